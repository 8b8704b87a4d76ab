"""NN-CC: neural curves on a template, trained in one batched pass for one or many records."""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Callable, Sequence

import numpy as np

from .._errors import ConfigError, DataError, FitError
from ..curves._fitted import NeuralFittedCurve
from ..curves._neural import NeuralCurve
from ..data._trajectory import Trajectory
from ..templates._separable import SeparableTemplate, apply_gauge, sticking_mask
from ._model import FittedModel
from ._presets import TrainingPreset

__all__ = ["fit_neural", "torch_threads"]


@contextlib.contextmanager
def torch_threads(n: int | None):
    """Run with ``n`` torch threads and restore the previous count afterwards."""
    import torch

    if n is None:
        yield
        return
    old = torch.get_num_threads()
    torch.set_num_threads(max(1, int(n)))
    try:
        yield
    finally:
        torch.set_num_threads(old)


def fit_neural(
    trajectories: Sequence[Trajectory],
    template: SeparableTemplate,
    curves: dict[str, NeuralCurve],
    preset: TrainingPreset,
    seeds: Sequence[int],
    *,
    method: str = "nn-cc",
    exclude_sticking: bool = True,
    stick_tol: float | None = None,
    weight_decay: float = 0.0,
    device: str = "cpu",
    threads: int | None = None,
    progress: Callable | None = None,
    chunk_models: int | None = None,
) -> list[FittedModel]:
    """Fit K records (equal lengths) as one batched computation; returns K fitted models.

    Each model's initialisation comes from its own seed, so K models trained together equal
    the same models trained one by one.
    """
    import torch

    if len(trajectories) != len(seeds):
        raise ConfigError("give one seed per trajectory")
    n = {tr.n_samples for tr in trajectories}
    if len(n) != 1:
        raise DataError("records fitted in one batch must have the same number of samples; fit them separately")
    dtype = torch.float64 if preset.dtype == "float64" else torch.float32
    names = template.curve_names
    R = preset.n_starts
    t_start = time.perf_counter()

    # ---------------------------------------------------------------- data, masks and scales
    args, ys, Fs, masks, scales_in, scale_out, n_stuck, g_est = [], [], [], [], [], [], [], []
    force_side = template.free_gain and template.gain_on == "force"
    for tr in trajectories:
        template.check_excitation(tr)
        a = template.arguments_of(tr)
        mask = np.ones(tr.n_samples, dtype=bool)
        if exclude_sticking:
            stuck = sticking_mask(tr, rel_tol=stick_tol)
            mask &= ~stuck
            n_stuck.append(int(stuck.sum()))
        else:
            n_stuck.append(0)
        if mask.sum() < 10:
            raise DataError("fewer than 10 samples remain after removing sticking phases; give a longer record")
        args.append(a)
        ys.append(np.asarray(tr.a))
        Fs.append(np.asarray(tr.F))
        masks.append(mask)
        s_in = {k: (float(np.max(np.abs(a[k]))) if preset.scale_inputs else 1.0) for k in names}
        scales_in.append(s_in)
        g0 = template.gain
        if force_side:
            # F = h x'' + f~ + b~: the target is the forcing. x'' is divided by a least-squares
            # estimate of g so that the learned coefficient h' = g_est / g is of order one
            # whatever the units (volts and 1e5 1/s^2 on real records).
            g_est.append(_gain_estimate(a, ys[-1], Fs[-1], mask, template.gain))
            s_out = float(np.std(Fs[-1][mask])) if preset.scale_output else 1.0
        else:
            g_est.append(1.0)
            s_out = float(np.std((ys[-1] - g0 * Fs[-1])[mask])) if preset.scale_output else 1.0
        scale_out.append(s_out if s_out > 0 else 1.0)

    K = len(trajectories)
    KR = K * R
    rep = lambda arr_list: np.repeat(np.stack(arr_list), R, axis=0)  # noqa: E731
    T = lambda arr: torch.as_tensor(arr, dtype=dtype, device=device)  # noqa: E731
    so = np.repeat(np.array(scale_out), R)[:, None]
    y = T(rep(ys) / so / np.repeat(np.array(g_est), R)[:, None])
    F = T(rep(Fs) / so)
    w_np = rep([m / np.sqrt(m.sum()) for m in masks])
    w = T(w_np)

    from ._gradient import BatchedProblem, CurveTerm

    terms = []
    for name in names:
        spec = curves[name]
        z = rep([a[name] for a in args]) / np.repeat([s[name] for s in scales_in], R)[:, None]
        sym_pts = None
        if spec.symmetry != "none" and spec.symmetry_mode == "penalty":
            zs = [np.linspace(a[name].min(), a[name].max(), preset.n_sym) / s[name] for a, s in zip(args, scales_in)]
            sym_pts = T(np.repeat(np.stack(zs), R, axis=0))
        terms.append(CurveTerm(spec, T(z), None, sym_pts))
    bias = all(curves[nm].pinned_at_zero for nm in names)
    problem = BatchedProblem(terms, y, F, w, free_gain=template.free_gain, gain=template.gain,
                             gain_on=template.gain_on, bias=bias,
                             lambda_sym=preset.lambda_sym, weight_decay=weight_decay, bayesian=preset.bayesian,
                             decay_groups=preset.decay_groups)

    # ---------------------------------------------------------------- initialisation (per model seed)
    def draw(gen):
        parts = [curves[nm].init(1, gen, dtype) for nm in names]
        if template.free_gain:
            start = 1.0 if template.gain_on == "force" else float(template.gain)
            parts.append(torch.full((1, 1), start, dtype=dtype))
        if bias:
            parts.append(torch.zeros(1, 1, dtype=dtype))
        return parts

    theta, logs, log, total_loss = train_batched(
        problem, start_weights(seeds, R, draw).to(device), preset, threads=threads, device=device,
        chunk_models=chunk_models, progress=progress, profile_jumps=True)
    decay = torch.cat([sub.decay_per_group(sub.K).to(theta.dtype) for _, sub, _ in logs])  # (KR, G)
    elapsed = time.perf_counter() - t_start
    theta = theta.double().cpu()
    # the problem's terms follow ``names``: (1, "layer 1 weights") -> "f2 layer 1 weights"
    decay_group_names = [" ".join(filter(None, ("all networks" if i is None else names[i], part)))
                         for i, part in problem.decay_group_parts]
    # a jump whose tanh is saturated at every fitted sample has a width the data cannot see:
    # take the sharpest law they allow (Coulomb's sign) rather than an arbitrary width
    unresolved_jump = _sharpen_unresolved_jumps(problem, theta)

    # ---------------------------------------------------------------- assemble fitted models
    models = []
    for k in range(K):
        losses = total_loss[k * R:(k + 1) * R]
        if not np.isfinite(losses).any():
            raise FitError(f"every training start of record {k} diverged to a non-finite loss; check the record "
                           "for outliers or try --preset default / another seed")
        losses = np.where(np.isfinite(losses), losses, np.inf)  # a diverged start never joins
        best = int(np.argmin(losses))
        if preset.combine == "mean":
            members = np.flatnonzero(losses <= losses[best] * (1.0 + preset.combine_tol))
        else:
            members = np.array([best])
        rows = theta[k * R + members]
        s_out = scale_out[k]
        fitted = {}
        for i, name in enumerate(names):
            z = args[k][name]
            fitted[name] = NeuralFittedCurve(
                name, template.arguments[name], (float(z.min()), float(z.max())), curves[name],
                problem.block(rows, i).numpy(), scales_in[k][name], s_out,
            )
        b = float(problem.bias_of(rows).mean()) * s_out
        g = float(problem.gain_of(rows).mean())
        if template.free_gain and template.gain_on == "force":
            # F = h x'' + f~ + b~  <=>  x'' + g f~ + g b~ = g F with g = 1/h
            g = g_est[k] / g
            b *= g
            for name in names:
                fitted[name].out_scale *= g
                fitted[name]._np_fn = None
        raw0 = {nm: float(fitted[nm].raw(np.array([0.0]))[0]) for nm in names}
        pinned = {nm: fitted[nm].pinned_at_zero for nm in names}
        shifts, offset = apply_gauge(raw0, pinned, b, template.gauge, names)
        for nm in names:
            fitted[nm].shift = shifts[nm]
        info = {
            "preset": preset.name,
            "preset_settings": preset.to_dict(),
            "seed": int(seeds[k]),
            "n_starts": R,
            "best_start": best,
            "ensemble_members": int(members.size),
            "adam_steps": log.adam_steps,
            "lm_iterations": log.lm_iterations,
            "stopped_by": log.stopped_by,
            "interrupted": log.interrupted,
            "n_samples": int(masks[k].size),
            "n_fitted_samples": int(masks[k].sum()),
            "n_sticking_samples": n_stuck[k],
            "total_loss": float(total_loss[k * R + best] * s_out**2),
            "train_seconds": elapsed / K,
            "batch_size": K,
            "weight_decay": [float(d) for d in decay[k * R + best]],
            "weight_decay_groups": decay_group_names,
            "effective_parameters": (log.effective_parameters[k * R + best] if log.effective_parameters else None),
        }
        if log.interrupted:  # say what this record's own chunk did: finished, interrupted or never trained
            own = chunk_log(logs, k * R)
            info.update(adam_steps=own.adam_steps, lm_iterations=own.lm_iterations, stopped_by=own.stopped_by)
        if unresolved_jump is not None:
            info["jump_width_unresolved"] = bool(unresolved_jump[k * R + members].all())
        model = FittedModel(template, method, fitted, g, offset, 0.0, info)
        resid = model.force_residual(trajectories[k])[masks[k]]
        model.loss = float(np.mean(resid**2))  # the combined model's own data loss
        models.append(model)
    return models


def _gain_estimate(args, a, F, mask, fallback):
    """Least-squares g from F = h x'' + smooth odd/even powers of the arguments + constant."""
    cols = [a, np.ones_like(a)]
    for z in args.values():
        u = z / max(float(np.max(np.abs(z))), 1e-300)
        cols += [u, u**2, u**3]
    A = np.column_stack(cols)[mask]
    coef, *_ = np.linalg.lstsq(A / np.linalg.norm(A, axis=0), F[mask], rcond=None)
    h = coef[0] / np.linalg.norm(A[:, 0])
    return float(1.0 / h) if np.isfinite(h) and h != 0 else float(fallback)


def start_weights(seeds, n_starts: int, draw) -> torch.Tensor:
    """Initial weights ``(len(seeds) * n_starts, P)``: ``draw(generator)`` gives one row's parts,
    each (seed, start) row from its own generator so a seed gives the same start in any batch."""
    import torch

    return torch.cat([torch.cat(draw(torch.Generator().manual_seed(int(seed) * 7919 + r)), dim=1)
                      for seed in seeds for r in range(n_starts)], dim=0)


def train_batched(problem, theta0, preset: TrainingPreset, *, threads, device, chunk_models, progress,
                  profile_jumps: bool = False):
    """Warm start, train with ``preset`` (Ctrl-C ends the whole call, see :func:`train_in_chunks`)
    and, for jump-aware curves, profile the jump widths: ``(theta, logs, merged log, loss per row)``."""
    import torch

    if preset.warm_start:
        theta0 = _warm_start(problem, theta0)
    with torch_threads(threads):
        theta, logs = train_with_preset(problem, theta0, preset, device=device, chunk_models=chunk_models,
                                        progress=progress)
        if profile_jumps:
            theta = _profile_jump_widths(problem, theta)
        with torch.no_grad():
            total_loss = torch.cat([sub.loss(theta[s:s + sub.K]) for s, sub, _ in logs]).double().cpu().numpy()
    return theta, logs, _merge_logs([lg for _, _, lg in logs]), total_loss


def train_with_preset(problem, theta0, preset: TrainingPreset, *, device, chunk_models: int | None, progress=None):
    """Train every model start of ``problem`` with ``preset``'s optimiser settings, in chunks.

    Models are independent, so they train in chunks: the Jacobians of a chunk stay small enough
    for the cache and memory stays bounded, with results identical to one batch (48 models on a
    CPU; a GPU wants the whole batch at once). Chunks hold whole groups of ``n_starts``.
    """
    import torch

    if chunk_models is None:
        chunk_models = 48 if torch.device(device).type == "cpu" else 4096
    R = preset.n_starts
    chunk = max(R, (chunk_models // R) * R)
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

    from ._gradient import TrainingLog, train

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


def _merge_logs(logs):
    from ._gradient import TrainingLog

    out = TrainingLog()
    out.adam_steps = max(lg.adam_steps for lg in logs)
    out.lm_iterations = max(lg.lm_iterations for lg in logs)
    out.stopped_by = ",".join(sorted({lg.stopped_by for lg in logs}))
    out.interrupted = any(lg.interrupted for lg in logs)
    out.effective_parameters = [g for lg in logs for g in lg.effective_parameters]
    out.history = [h for lg in logs for h in lg.history]
    return out


def _profile_jump_widths(problem, theta, n_grid: int = 33):
    """Profile each jump's width over a grid (the parts that enter linearly refitted by least
    squares at each width) and keep the best, the sharpest among near-ties.

    The loss is flat in the width wherever the few samples near the jump sit on the tanh's
    linear part or its saturated tails, so gradient steps leave it wherever they started; a
    profile finds the width the data support (a true step for Coulomb friction with slipping
    samples at tiny |x'|, 1/500 for the tanh(500 x') law)."""
    import torch

    terms = [(i, t) for i, t in enumerate(problem.terms) if "jump_log_eps" in t.curve.slices()]
    if not terms:
        return theta
    N = problem.y.shape[1]
    data_loss = lambda th: problem.residuals(th)[:, :N].pow(2).sum(dim=1)  # noqa: E731
    with torch.no_grad():
        best = theta.clone()
        best_loss = data_loss(_warm_start(problem, best))
        keep = best_loss <= data_loss(best)
        best = torch.where(keep.unsqueeze(1), _warm_start(problem, best), best)
        best_loss = torch.minimum(best_loss, data_loss(theta))
        for i, term in terms:
            j = problem.offsets[i] + term.curve.slices()["jump_log_eps"].start
            # from wide to sharp, so that a sharper width must be strictly (relatively) better only
            # against a wider one; near-ties then go to the sharper width
            for raw in torch.linspace(-0.5, -16.5, n_grid, dtype=theta.dtype):
                trial = best.clone()
                trial[:, j] = raw
                trial = _warm_start(problem, trial)
                loss = data_loss(trial)
                better = torch.isfinite(loss) & (loss <= best_loss * (1 + 1e-9))
                best = torch.where(better.unsqueeze(1), trial, best)
                best_loss = torch.where(better, loss, best_loss)
    return best


def _sharpen_unresolved_jumps(problem, theta, saturation: float = 10.0):
    """Set the width of each jump with |u| >= saturation * eps at every fitted sample to its lower
    bound (eps = 1e-7 of the range), in place. The fit changes by at most mu * (1 - tanh(10)),
    about 4e-9 mu, at the samples. Returns a per-model flag, or None without jump curves."""
    import torch

    from ..curves._neural import jump_log_eps

    flags = None
    used = problem.weights.detach().cpu() > 0
    for i, term in enumerate(problem.terms):
        sl = term.curve.slices()
        if "jump_log_eps" not in sl:
            continue
        j = problem.offsets[i] + sl["jump_log_eps"].start
        u = term.u.detach().cpu().double().abs()
        d_min = torch.where(used, u, torch.full_like(u, math.inf)).min(dim=1).values
        eps = torch.exp(jump_log_eps(theta[:, j]))
        unresolved = d_min >= saturation * eps
        theta[unresolved, j] = -60.0  # maps onto the lower bound of the width
        flags = unresolved.numpy() if flags is None else (flags & unresolved.numpy())
    return flags


#: Tikhonov guard of the even curves' output-layer warm start, relative to each column's norm
#: (random hidden features can be nearly collinear; unguarded, the start can have weights so
#: large that the evidence update meets a singular Hessian)
_EVEN_WARM_RIDGE = 1e-3


def _warm_start(problem, theta0):
    """Least squares for the parts that enter linearly (linear terms, jump heights, gain, constant,
    and the output layer of exact even curves, which have no linear term: see curves/_neural.py)."""
    import torch

    from ..curves._neural import jump_log_eps

    with torch.no_grad():
        N = problem.y.shape[1]
        cols, idx, guarded = [], [], []
        for i, term in enumerate(problem.terms):
            sl = term.curve.slices()
            o = problem.offsets[i]
            m = term.multiplier
            if term.curve.exact_symmetry == "even":
                feats, where = term.curve.output_layer(problem.block(theta0, i), term.u, term.u_both)
                for j in range(feats.shape[2]):
                    guarded.append(len(cols))
                    cols.append(feats[:, :, j] if m is None else feats[:, :, j] * m)
                    idx.append(o + where.start + j)
            if "linear" in sl:
                cols.append(term.u if m is None else term.u * m)
                idx.append(o + sl["linear"].start)
            if "jump_height" in sl:
                eps = torch.exp(jump_log_eps(theta0[:, o + sl["jump_log_eps"].start])).unsqueeze(1)
                c = torch.tanh(term.u / eps)
                cols.append(c if m is None else c * m)
                idx.append(o + sl["jump_height"].start)
        if problem.free_gain:
            cols.append(problem.y if problem.gain_on == "force" else -problem.F)
            idx.append(problem.gain_index)
        if problem.bias:
            cols.append(torch.ones_like(problem.y))
            idx.append(problem.bias_index)
        if not cols:
            return theta0
        theta = theta0.clone()
        for j in idx:  # the fit below replaces these parts, so start them from 0
            theta[:, j] = 0.0
        base = problem.residuals(theta)[:, :N]  # weighted residual of the rest
        A = torch.stack(cols, dim=2) * problem.weights.unsqueeze(-1)
        target = -base
        if guarded:
            rows = A.new_zeros(A.shape[0], len(guarded), A.shape[2])
            for r, c in enumerate(guarded):
                rows[:, r, c] = _EVEN_WARM_RIDGE * A[:, :, c].norm(dim=1)
            A = torch.cat([A, rows], dim=1)
            target = torch.cat([target, target.new_zeros(target.shape[0], len(guarded))], dim=1)
        sol = torch.linalg.lstsq(A, target.unsqueeze(-1)).solution.squeeze(-1)
        theta[:, idx] = sol.to(theta.dtype)
        return theta
