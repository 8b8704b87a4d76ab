"""One training loop for every gradient-trained model: batched Adam, then batched Levenberg-Marquardt
with Bayesian regularisation (MacKay's evidence), in chunks of independent models.

The loop only sees a problem object (:class:`~._problem.LeastSquaresProblem`: residuals, their
Jacobian, the weight-decay rows), so equation error, output error and every curve
representation train through it.
"""

from __future__ import annotations

import contextlib
import dataclasses
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

import torch

from ._evidence import (EVIDENCE_SETTLED, SWEEP_TOL, EvidenceSweeps, decay_moves, initial_decay, set_evidence,
                        with_decay)

if TYPE_CHECKING:
    from ._presets import TrainingPreset
    from ._problem import LeastSquaresProblem

__all__ = ["TrainingLog", "train", "train_in_chunks", "train_with_preset", "chunk_log", "merge_logs",
           "torch_threads", "start_weights", "model_chunk", "BatchedAdam"]


@dataclasses.dataclass
class TrainingLog:
    adam_steps: int = 0
    lm_iterations: int = 0
    history: list = dataclasses.field(default_factory=list)  # (phase, step, mean loss)
    stopped_by: str = ""
    interrupted: bool = False
    effective_parameters: list = dataclasses.field(default_factory=list)
    #: output error's evidence sweeps (``evidence_sweeps``): how many models had them undone by the guard
    sweeps_undone: int = 0
    #: long records (``_long_record``): the first stage's subset size and the refinement's LM iterations
    subset_samples: int = 0
    refine_iterations: int = 0


class BatchedAdam:
    """Adam (Kingma & Ba 2015) on one ``(K, P)`` tensor: the update of ``torch.optim.Adam`` with its
    defaults (betas 0.9, 0.999, eps 1e-8, no weight decay), written out in its single-tensor form
    and bitwise equal to it on a CPU (tested). ``torch.optim`` imports ``torch._dynamo`` on first
    use, about 1 s of a 1000-sample fit's 3-4 s process; this loop needs none of its machinery."""

    def __init__(self, param: torch.Tensor, lr: float, betas=(0.9, 0.999), eps: float = 1e-8):
        self.param, self.lr, self.betas, self.eps = param, float(lr), betas, float(eps)
        self.exp_avg = torch.zeros_like(param, memory_format=torch.preserve_format)
        self.exp_avg_sq = torch.zeros_like(param, memory_format=torch.preserve_format)
        self.steps = 0

    @torch.no_grad()
    def step(self) -> None:
        grad = self.param.grad
        if grad is None:
            return
        beta1, beta2 = self.betas
        self.steps += 1
        self.exp_avg.lerp_(grad, 1 - beta1)
        self.exp_avg_sq.mul_(beta2).addcmul_(grad, grad, value=1 - beta2)
        step_size = self.lr / (1 - beta1**self.steps)
        denom = (self.exp_avg_sq.sqrt() / (1 - beta2**self.steps) ** 0.5).add_(self.eps)
        self.param.addcdiv_(self.exp_avg, denom, value=-step_size)

    def zero_grad(self, set_to_none: bool = True) -> None:
        self.param.grad = None


def jump_height_columns(problem) -> list[int]:
    """Columns of ``problem``'s parameters that hold a learned jump's height (neural curves with a
    jump, in equation-error and output-error problems). Training keeps them >= 0: dry friction
    takes energy out, a negative height would feed it in.

    Examples
    --------
    >>> from charcurves.train._train import jump_height_columns
    >>> class Problem:  # no curve with a jump
    ...     terms = []
    >>> jump_height_columns(Problem())
    []
    """
    terms = getattr(problem, "terms", None)
    if terms is not None:
        pairs = [(t.curve, o) for t, o in zip(terms, problem.offsets)]
    else:
        pairs = [(b.param, o) for b, o in zip(getattr(problem, "blocks", ()), getattr(problem, "block_offsets", ()))]
    out = []
    for curve, offset in pairs:
        sl = curve.slices() if getattr(curve, "jump", False) and hasattr(curve, "slices") else {}
        if "jump_height" in sl:
            out.append(offset + sl["jump_height"].start)
    return out


def project_jumps(theta, columns) -> None:
    """Clamp the jump heights (``columns`` of ``theta``) at 0 in place."""
    if columns:
        theta[:, columns] = theta[:, columns].clamp_min(0.0)


def _adam(problem, theta, steps, lr, stop_loss, log, progress, holder, check_every=100):
    jumps = jump_height_columns(problem)
    theta = theta.clone()
    with torch.no_grad():
        project_jumps(theta, jumps)
    theta.requires_grad_(True)
    opt = BatchedAdam(theta, lr=lr)
    done = torch.zeros(theta.shape[0], dtype=torch.bool, device=theta.device)
    # a model whose loss turns non-finite goes back to its last finite weights and stops there
    diverged = torch.zeros_like(done)
    last_good = theta.detach().clone()
    # Ctrl-C keeps, per model, the best weights seen at a checkpoint (not the latest ones)
    best, best_loss = last_good.clone(), torch.full_like(done, float("inf"), dtype=theta.dtype)
    for step in range(steps):
        opt.zero_grad(set_to_none=True)
        per_model = problem.loss(theta)
        per_model.sum().backward()
        if step % check_every == 0 or step == steps - 1:
            with torch.no_grad():
                bad = ~torch.isfinite(per_model.detach())
                if bool(bad.any()):
                    diverged |= bad
                    theta[bad] = last_good[bad]
                last_good = theta.detach().clone()
                done = (per_model.detach() < stop_loss) | diverged
                better = torch.isfinite(per_model.detach()) & (per_model.detach() < best_loss)
                best = torch.where(better.unsqueeze(1), last_good, best)
                best_loss = torch.where(better, per_model.detach(), best_loss)
            log.history.append(("adam", step, float(per_model.detach()[~diverged].mean())))
            holder["theta"] = best
            if progress is not None:
                progress("adam", step, steps, float(per_model.detach().mean()))
            if bool(done.all()):
                log.stopped_by = "stop_loss"
                break
        if done.any():
            # models already below the stop loss keep their weights (as separate runs would):
            # Adam's momentum would still move them, so restore them after the step
            frozen = theta.detach()[done].clone()
            opt.step()
            with torch.no_grad():
                theta[done] = frozen
        else:
            opt.step()
        with torch.no_grad():  # projected gradient: a jump's height stays >= 0
            project_jumps(theta, jumps)
        log.adam_steps = step + 1
    holder["theta"] = theta.detach()
    return theta.detach()


def _levenberg_marquardt(problem, theta, max_iter, tol, stop_loss, log, progress, holder, window=0,
                         deadline=None, nielsen=False, keep_decay=False, evidence_sweeps=0):
    """Batched LM on the normal equations (JtJ and Jtr accumulated by the problem, over chunks of
    samples on long records). ``keep_decay`` continues from the problem's current weight decay
    (the refinement of a long record, see ``_long_record``) instead of the evidence's start; for
    ``window``, ``deadline``, ``nielsen`` and ``evidence_sweeps`` see :func:`train`."""
    K, P = theta.shape
    jumps = jump_height_columns(problem)
    if jumps:
        theta = theta.clone()
        project_jumps(theta, jumps)
    if problem.bayesian and not keep_decay:
        shape = (K,) if problem.n_decay_groups == 1 else (K, problem.n_decay_groups)
        problem.set_weight_decay(initial_decay(problem, theta, shape))
    normal = problem.normal_equations(theta)
    JtJ, g, cost = with_decay(problem, theta, normal)
    mu = torch.full((K,), 1e-3, dtype=theta.dtype, device=theta.device)
    active = cost > stop_loss
    stalls = torch.zeros(K, dtype=torch.long, device=theta.device)
    # window > 0: a model stops when its relative decrease summed over its last `window` iterations
    # is below tol; a rejected step counts (as no decrease) only when its trial changed the loss by
    # less than tol (rounding-level: nothing left to gain), not when it overshot
    recent = torch.full((K, max(window, 1)), float("inf"), dtype=theta.dtype, device=theta.device)
    eye = torch.eye(P, dtype=theta.dtype, device=theta.device)
    nu = torch.full((K,), 2.0, dtype=theta.dtype, device=theta.device)
    sweeps = EvidenceSweeps(theta, evidence_sweeps) if evidence_sweeps and problem.bayesian else None
    for it in range(max_iter):
        if not bool(active.any()):
            break
        if deadline is not None and time.monotonic() > deadline:
            log.stopped_by = "time_budget"
            break
        diag = torch.diagonal(JtJ, dim1=1, dim2=2)
        # Marquardt scaling with a floor so directions the data do not see stay damped
        scale = diag + 1e-9 * diag.max(dim=1, keepdim=True).values + 1e-12
        A = JtJ + (mu.unsqueeze(-1) * scale).unsqueeze(-1) * eye
        g_step = g
        if jumps:
            # a jump height at its bound 0 whose gradient points below it stays there (active set):
            # the step solves for the other parameters only, so the linear model stays consistent
            held = torch.zeros_like(g, dtype=torch.bool)
            held[:, jumps] = (theta[:, jumps] <= 0) & (g[:, jumps] > 0)
            if bool(held.any()):
                keep = (~held).to(A.dtype)
                A = A * keep.unsqueeze(-1) * keep.unsqueeze(-2) + torch.diag_embed(held.to(A.dtype))
                g_step = g * keep
        L, info = torch.linalg.cholesky_ex(A)
        step = -torch.cholesky_solve(g_step.unsqueeze(-1), L).squeeze(-1)
        ok_solve = info == 0
        step = torch.where(ok_solve.unsqueeze(-1) & active.unsqueeze(-1), step, torch.zeros_like(step))
        trial = theta + step
        project_jumps(trial, jumps)  # a jump's height stays >= 0 (the step is projected)
        cost_new = problem.loss(trial)
        accept = active & ok_solve & torch.isfinite(cost_new) & (cost_new < cost)
        cost_before = cost
        rel = torch.where(accept, (cost - cost_new) / cost.clamp_min(1e-300), torch.zeros_like(cost))
        # the decrease the linear model predicts: -(2 g.s + s'JtJ s) = -g.s + mu s'Ds for the LM step
        predicted = -(g_step * step).sum(1) + mu * (scale * step * step).sum(1)
        # converged (MINPACK's ftol test) where neither the trial nor the linear model gains more
        # than tol: a refused step (otherwise the damping would grow to its cap over some 30 refused
        # steps that all leave theta as it is) or, with a window (output error), an accepted one
        # whose evidence update left the decays in place (checked below)
        rounding = (cost_new - cost).abs() <= tol * cost
        settled = ok_solve & (predicted <= tol * cost) & rounding & (active if window else ~accept)
        if window:
            flat = accept | (active & ok_solve & rounding)
            recent = torch.where(flat.unsqueeze(-1), torch.cat([recent[:, 1:], rel.unsqueeze(-1)], dim=1), recent)
        theta = torch.where(accept.unsqueeze(-1), trial, theta)
        cost = torch.where(accept, cost_new, cost)
        if bool(accept.any()):
            # the Jacobian only changes where a step was taken: recompute it once, at the new point
            normal = problem.normal_equations(theta)
            JtJ, g, cost = with_decay(problem, theta, normal)
        holder["theta"] = theta
        if nielsen:
            # Nielsen's update from the gain ratio rho (actual / predicted decrease of the linear
            # model): a good step relaxes the damping by up to 3, a poor one hardly; a rejection
            # raises it by 2, 4, 8, ... (Madsen, Nielsen & Tingleff 2004, eq. 3.16)
            rho = (cost_before - cost_new) / predicted.clamp_min(1e-300)
            fac = torch.clamp(1 - (2 * rho - 1) ** 3, min=1 / 3)
            mu = torch.where(accept, (mu * fac).clamp_min(1e-12), (mu * nu).clamp_max(1e12))
            nu = torch.where(accept, torch.full_like(nu, 2.0), (nu * 2).clamp_max(1e6))
        else:
            mu = torch.where(accept, (mu / 3).clamp_min(1e-12), (mu * 4).clamp_max(1e12))
        stalls = torch.where((accept & (rel < tol)) | settled, stalls + 1, torch.where(accept, 0, stalls))
        if problem.bayesian and bool(accept.any()):
            lam_before = problem.weight_decay if window else None  # set_weight_decay replaces, never mutates
            # re-estimate the decay of the models that moved; the objective changes with it, so
            # the decay's share of the normal equations is refreshed under the new value
            moved = accept & active
            if sweeps is None:
                set_evidence(problem, theta, JtJ, normal[3], moved)
                JtJ, g, cost = with_decay(problem, theta, normal)
            else:  # output error: undo sweeps that misled, then one update and the sweeps of settled models
                theta, normal, undone = sweeps.guard(problem, theta, normal, moved)
                holder["theta"] = theta
                if bool(undone.any()):
                    JtJ, g, cost = with_decay(problem, theta, normal)
                set_evidence(problem, theta, JtJ, normal[3], moved & ~undone)
                JtJ, g, cost = sweeps.settle(problem, theta, normal, moved & (rel < EVIDENCE_SETTLED))
            log.effective_parameters = problem.gamma.sum(1).tolist()
            if window:  # a decay that moved by more than the sweeps resolve opens new ground: go on
                lam_now = torch.as_tensor(problem.weight_decay, dtype=theta.dtype, device=theta.device)
                settled = settled & (~accept | ~(decay_moves(lam_now, lam_before, K) > SWEEP_TOL))
        # with a window (output error), a settled step ends the model at once: the further trials
        # that used to fill the window cost one free run each and left theta where it was
        finished = ((recent.sum(dim=1) < tol) | settled) if window else (stalls >= 3)
        finished = finished | (mu >= 1e12) | (cost < stop_loss)
        active = active & ~finished
        log.lm_iterations = it + 1
        if it % 10 == 0:
            log.history.append(("lm", it, float(cost.mean())))
            if progress is not None:
                progress("lm", it, max_iter, float(cost.mean()))
    log.stopped_by = log.stopped_by or ("stall" if not bool(active.any()) else "max_iter")
    if sweeps is not None:
        log.sweeps_undone = int(sweeps.off.sum())
    return theta


def train(
    problem: LeastSquaresProblem,
    theta0: torch.Tensor,
    *,
    adam_steps: int,
    adam_lr: float,
    lm_max_iter: int,
    lm_tol: float,
    stop_loss: float,
    progress: Callable | None = None,
    lm_window: int = 0,
    lm_deadline: float | None = None,
    lm_nielsen: bool = False,
    keep_decay: bool = False,
    evidence_sweeps: int = 0,
) -> tuple[torch.Tensor, TrainingLog]:
    """Train ``theta0`` (``(K, P)``) on ``problem``; Ctrl-C keeps the best weights so far.

    Levenberg-Marquardt stops a model after 3 iterations in a row that lower its loss by less than
    ``lm_tol`` (relative): accepted steps, or steps refused by rounding alone (the linear model
    predicts less and the trial's loss differs by less). With ``lm_window`` > 0 (output error) it
    stops a model once its relative decrease summed over its last ``lm_window`` iterations is below
    ``lm_tol`` (rejected steps whose trial changed the loss by less than that count as no decrease:
    at convergence the trials differ by rounding), or at once at a step whose trial and linear
    model both gain less than ``lm_tol`` (MINPACK's ftol test): a refused step, or an accepted one
    after which no decay of a Bayesian problem moved by more than ``SWEEP_TOL`` (in log). ``lm_nielsen`` sets the damping by Nielsen's
    gain-ratio rule instead of the fixed factors 1/3 and 4. ``lm_deadline`` (a ``time.monotonic()``
    value) ends training at the first iteration after that time. ``keep_decay``: LM continues from
    the problem's weight decay (the refinement of a long record) instead of the evidence's start.
    ``evidence_sweeps`` > 0 (Bayesian problems): once a model's accepted step lowers its loss by less
    than ``EVIDENCE_SETTLED`` (relative), its evidence is iterated up to that many times on the
    linearised problem after each step instead of once (:class:`._evidence.EvidenceSweeps`).
    """
    log = TrainingLog()
    holder = {"theta": theta0}
    try:
        if adam_steps > 0:
            _adam(problem, holder["theta"], adam_steps, adam_lr, stop_loss, log, progress, holder)
        if lm_max_iter > 0:
            with torch.no_grad():
                _levenberg_marquardt(
                    problem, holder["theta"], lm_max_iter, lm_tol, stop_loss, log, progress, holder, lm_window,
                    lm_deadline, lm_nielsen, keep_decay, evidence_sweeps)
    except KeyboardInterrupt:
        log.interrupted = True
        log.stopped_by = "interrupted"
    return holder["theta"].detach(), log


@contextlib.contextmanager
def torch_threads(n: int | None):
    """Run with ``n`` torch threads, and as many BLAS threads for numpy (the posterior's linear
    algebra: a threaded BLAS sums in another order, so OMP_NUM_THREADS would change the last bits),
    and restore the previous counts afterwards."""
    import torch
    from threadpoolctl import threadpool_limits

    if n is None:
        yield
        return
    old = torch.get_num_threads()
    torch.set_num_threads(max(1, int(n)))
    try:
        with threadpool_limits(limits=max(1, int(n)), user_api="blas"):
            yield
    finally:
        torch.set_num_threads(old)


def start_weights(seeds, n_starts: int, draw) -> torch.Tensor:
    """Initial weights ``(len(seeds) * n_starts, P)``: ``draw(generator)`` gives one row's parts,
    each (seed, start) row from its own generator so a seed gives the same start in any batch."""
    import torch

    return torch.cat([torch.cat(draw(torch.Generator().manual_seed(int(seed) * 7919 + r)), dim=1)
                      for seed in seeds for r in range(n_starts)], dim=0)


def model_chunk(preset: TrainingPreset, device, chunk_models: int | None) -> int:
    """Models trained together: ``chunk_models`` (48 on a CPU, 4096 on a GPU by default), rounded
    down to whole groups of ``n_starts``."""
    if chunk_models is None:
        chunk_models = 48 if torch.device(device).type == "cpu" else 4096
    R = preset.n_starts
    return max(R, (chunk_models // R) * R)


def train_with_preset(problem, theta0, preset: TrainingPreset, *, device, chunk_models: int | None, progress=None):
    """Train every model start of ``problem`` with ``preset``'s optimiser settings, in chunks.

    Models are independent, so they train in chunks: the Jacobians of a chunk stay small enough
    for the cache and memory stays bounded, with results identical to one batch (48 models on a
    CPU; a GPU wants the whole batch at once). Chunks hold whole groups of ``n_starts``.
    """
    chunk = model_chunk(preset, device, chunk_models)
    return train_in_chunks(problem, theta0, chunk, progress=progress, adam_steps=preset.adam_steps,
                           adam_lr=preset.adam_lr, lm_max_iter=preset.lm_max_iter, lm_tol=preset.lm_tol,
                           stop_loss=preset.stop_loss)


def train_in_chunks(problem, theta0, chunk: int, *, progress=None, **train_options):
    """Train the models of ``problem`` ``chunk`` rows at a time: ``(theta, [(start, subproblem, log)])``.

    Ctrl-C ends the whole call: the chunk in training keeps its best weights so far, the chunks
    after it are not trained (their models keep their initial weights; their log says
    ``stopped_by="not trained: interrupted"``), and every chunk's log is marked interrupted, so
    no caller starts further work (post-SR, refinement) on any model of an interrupted call.
    """
    import torch

    
    parts, logs = [], []
    interrupted = False
    for start in range(0, problem.K, chunk):
        sub = problem.subset(slice(start, start + chunk))
        lg = None
        if not interrupted:
            try:
                th, lg = train(sub, theta0[start:start + chunk], progress=progress, **train_options)
            except KeyboardInterrupt:  # outside train's own handler: the chunk keeps its initial weights
                lg = None
            interrupted = lg is None or lg.interrupted
        if lg is None:
            th, lg = theta0[start:start + chunk].detach(), TrainingLog(stopped_by="not trained: interrupted")
        parts.append(th)
        logs.append((start, sub, lg))
    if interrupted:
        for _, sub, lg in logs:
            lg.interrupted = True
            if len(lg.effective_parameters) != sub.K:  # stopped before LM: keep rows aligned with models
                lg.effective_parameters = [None] * sub.K
    return torch.cat(parts, dim=0), logs


def chunk_log(logs, row: int):
    """The log of the chunk that trained model row ``row`` (see :func:`train_in_chunks`)."""
    return next(lg for start, sub, lg in logs if start <= row < start + sub.K)


def merge_logs(logs):
    out = TrainingLog()
    out.adam_steps = max(lg.adam_steps for lg in logs)
    out.lm_iterations = max(lg.lm_iterations for lg in logs)
    out.stopped_by = ",".join(sorted({lg.stopped_by for lg in logs}))
    out.interrupted = any(lg.interrupted for lg in logs)
    out.effective_parameters = [g for lg in logs for g in lg.effective_parameters]
    out.history = [h for lg in logs for h in lg.history]
    out.subset_samples = max(lg.subset_samples for lg in logs)
    out.refine_iterations = max(lg.refine_iterations for lg in logs)
    return out


