"""Least-squares starts, the batched training call, and the treatment of learned jumps (dry friction)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
import torch

from ._long_record import is_long, train_long_record
from ._train import jump_height_columns, merge_logs, model_chunk, torch_threads, train_with_preset

if TYPE_CHECKING:
    from ._presets import TrainingPreset

__all__ = ["train_batched", "warm_start", "profile_jump_widths", "sharpen_unresolved_jumps", "gain_estimate"]


def _slices(curve) -> dict:
    return curve.slices() if hasattr(curve, "slices") else {}


def gain_estimate(design: dict, mask: np.ndarray, fallback: float) -> float:
    """Least-squares g from F = h x'' + smooth odd/even powers of the arguments (times their
    coefficients) + constant, on the fitted samples: the start of a free gain."""
    E = design["E"]
    rows = np.tile(mask, E)
    cols = [design["y"], np.ones_like(design["y"])]
    for name, u in design["args"].items():
        z = np.tile(u / max(float(np.max(np.abs(u))), 1e-300), E)
        m = design["mult"][name]
        cols += [m * z, m * z**2, m * z**3]
        if np.ptp(m) > 0:
            cols.append(m)
    cols += list(design["scalars"].values())
    A = np.column_stack(cols)[rows]
    norms = np.linalg.norm(A, axis=0)
    norms[norms == 0] = 1.0
    coef, *_ = np.linalg.lstsq(A / norms, design["F"][rows], rcond=None)
    h = coef[0] / norms[0]
    return float(1.0 / h) if np.isfinite(h) and h != 0 else float(fallback)


def train_batched(problem, theta0, preset: TrainingPreset, *, threads, device, chunk_models, progress,
                  profile_jumps: bool = False, row_seeds=None):
    """Warm start, train with ``preset`` (Ctrl-C ends the whole call, see :func:`train_in_chunks`)
    and, for jump-aware curves, profile the jump widths: ``(theta, logs, merged log, loss per row)``.
    Long records (given ``row_seeds``, each model row's seed) train in two stages: see ``_long_record``."""

    long = row_seeds is not None and is_long(problem)
    if preset.warm_start and not long:
        theta0 = warm_start(problem, theta0)
    with torch_threads(threads):
        if long:
            theta, logs = train_long_record(problem, theta0, preset, model_chunk(preset, device, chunk_models),
                                            row_seeds, warm=warm_start if preset.warm_start else None,
                                            profile=profile_jump_widths if profile_jumps else None,
                                            progress=progress)
        else:
            theta, logs = train_with_preset(problem, theta0, preset, device=device, chunk_models=chunk_models,
                                            progress=progress)
        if profile_jumps and not long:  # a long record's widths are profiled between its two stages
            theta = profile_jump_widths(problem, theta)
        with torch.no_grad():
            total_loss = torch.cat([sub.loss(theta[s:s + sub.K]) for s, sub, _ in logs]).double().cpu().numpy()
    return theta, logs, merge_logs([lg for _, _, lg in logs]), total_loss


def profile_jump_widths(problem, theta, n_grid: int = 33):
    """Profile each jump's width over a grid (the parts that enter linearly refitted by least
    squares at each width) and keep the best, the sharpest among near-ties.

    The loss is flat in the width wherever the few samples near the jump sit on the tanh's
    linear part or its saturated tails, so gradient steps leave it wherever they started; a
    profile finds the width the data support (a true step for Coulomb friction with slipping
    samples at tiny |x'|, 1/500 for the tanh(500 x') law)."""

    terms = [(i, t) for i, t in enumerate(problem.terms) if "jump_log_eps" in _slices(t.curve)]
    if not terms:
        return theta
    data_loss = problem.data_loss
    with torch.no_grad():
        best = theta.clone()
        best_loss = data_loss(warm_start(problem, best))
        keep = best_loss <= data_loss(best)
        best = torch.where(keep.unsqueeze(1), warm_start(problem, best), best)
        best_loss = torch.minimum(best_loss, data_loss(theta))
        for i, term in terms:
            j = problem.offsets[i] + term.curve.slices()["jump_log_eps"].start
            # from wide to sharp, so that a sharper width must be strictly (relatively) better only
            # against a wider one; near-ties then go to the sharper width
            for raw in torch.linspace(-0.5, -16.5, n_grid, dtype=theta.dtype):
                trial = best.clone()
                trial[:, j] = raw
                trial = warm_start(problem, trial)
                loss = data_loss(trial)
                better = torch.isfinite(loss) & (loss <= best_loss * (1 + 1e-9))
                best = torch.where(better.unsqueeze(1), trial, best)
                best_loss = torch.where(better, loss, best_loss)
    return best


def sharpen_unresolved_jumps(problem, theta, saturation: float = 10.0):
    """Set the width of each jump with |u| >= saturation * eps at every fitted sample to its lower
    bound (eps = 1e-7 of the range), in place. The fit changes by at most mu * (1 - tanh(10)),
    about 4e-9 mu, at the samples. Returns a per-model flag, or None without jump curves."""

    from ..curves import jump_log_eps

    flags = None
    used = problem.weights.detach().cpu() > 0
    for i, term in enumerate(problem.terms):
        sl = _slices(term.curve)
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


def warm_start(problem, theta0):
    """Least squares for the parts that enter linearly (linear terms, jump heights, gain, constant,
    and the output layer of exact even curves, which have no linear term: see curves/_neural.py)."""

    with torch.no_grad():
        N = problem.y.shape[1]
        cols, idx, guarded = [], [], []
        for i, term in enumerate(problem.terms):
            o = problem.offsets[i]
            m = term.multiplier
            for j, col, guard in term.curve.linear_parts(problem.block(theta0, i), term.u, term.u_both):
                if guard:
                    guarded.append(len(cols))
                cols.append(col if m is None else col * m)
                idx.append(o + j)
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
        # gelsd, not the default gelsy: torch hands gelsy an uninitialised column-pivot array (jpvt),
        # which LAPACK reads on entry, so its answer followed leftover heap contents (issue 25)
        driver = "gelsd" if A.device.type == "cpu" else "gels"
        sol = torch.linalg.lstsq(A, target.unsqueeze(-1), driver=driver).solution.squeeze(-1)
        # a jump's height is >= 0 (friction takes energy out): where least squares wants it negative,
        # the constrained optimum holds it at 0 (the active set of this convex problem); refit the
        # other parts without its column
        jumps = [k for k, j in enumerate(idx) if j in set(jump_height_columns(problem))]
        negative = sol[:, jumps] < 0 if jumps else None
        if negative is not None and bool(negative.any()):
            rows = negative.any(dim=1)
            neg = negative[rows].to(A.dtype)  # (R, n_jumps): 1 where the height is held at 0
            A2 = A[rows].clone()
            pin = A2.new_zeros(A2.shape[0], len(jumps), A2.shape[2])  # a row c_k = 0 for each held height
            for c, k in enumerate(jumps):
                A2[:, :, k] = A2[:, :, k] * (1.0 - neg[:, c:c + 1])
                pin[:, c, k] = neg[:, c]
            A2 = torch.cat([A2, pin], dim=1)
            t2 = torch.cat([target[rows], target.new_zeros(A2.shape[0], len(jumps))], dim=1)
            sol2 = torch.linalg.lstsq(A2, t2.unsqueeze(-1), driver=driver).solution.squeeze(-1)
            sol[rows] = sol2
            sol[:, jumps] = sol[:, jumps].clamp_min(0.0)
        theta[:, idx] = sol.to(theta.dtype)
        return theta
