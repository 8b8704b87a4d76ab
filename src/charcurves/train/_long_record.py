"""Fits on long records: the preset's training on a subset of the samples, then Levenberg-Marquardt
on every sample from there.

A curve is a univariate function with a few dozen parameters; a record of 10^5 samples pins it
down far better than the optimiser's path needs. The first stage (Adam, then LM with the Bayesian
evidence: everything the preset asks for) runs on a stratified random subset of
:data:`SUBSET_SAMPLES` samples, one per equal stretch of the record, drawn from each record's own
seed; the second runs the same LM on all samples, its normal equations accumulated over chunks
of samples (see ``BatchedProblem.normal_equations``), starting from the first stage's weights and
decay. The answer is the optimum of the whole record's objective, as a fit on all samples from
the start would find; what changes is how much work reaches it: a few passes over the data
instead of some 230, and memory bounded by a chunk instead of the whole Jacobian.

Records of at most :data:`SUBSET_SAMPLES` samples train as before, in one stage.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from ._train import TrainingLog, merge_logs, train_in_chunks

__all__ = ["SUBSET_SAMPLES", "REFINE_MARGIN", "is_long", "subset_indices", "contenders", "train_long_record"]

#: samples of the first stage's subset (and the length from which a record counts as long)
SUBSET_SAMPLES = 4096
#: starts within this relative loss of their record's best after the first stage are refined
REFINE_MARGIN = 0.1
#: starts whose first-stage residuals differ by less than this (rms, relative) are one fit
SAME_FIT = 1e-3


def is_long(problem) -> bool:
    """Whether ``problem`` trains in two stages (only equation-error problems can take a subset)."""
    return hasattr(problem, "sample_subset") and problem.n_data > SUBSET_SAMPLES


def subset_indices(n: int, n_sub: int, seed: int) -> np.ndarray:
    """``n_sub`` sorted sample indices of ``0 .. n-1``, one uniformly at random in each of ``n_sub``
    equal stretches: the subset covers the whole record (every forcing period, every amplitude)
    and, unlike a fixed stride, cannot alias with a periodic input."""
    edges = np.linspace(0.0, float(n), n_sub + 1)
    u = np.random.default_rng(np.random.SeedSequence([int(seed), 0x10AD])).random(n_sub)
    idx = np.floor(edges[:-1] + u * np.diff(edges)).astype(np.int64)
    return np.clip(idx, 0, n - 1)


def _merge(first: TrainingLog, second: TrainingLog, n_sub: int, effective: list) -> TrainingLog:
    return TrainingLog(adam_steps=first.adam_steps, lm_iterations=first.lm_iterations,
                       history=first.history + [("refine", s, v) for _, s, v in second.history],
                       stopped_by=second.stopped_by or first.stopped_by,
                       interrupted=first.interrupted or second.interrupted,
                       effective_parameters=effective, subset_samples=n_sub,
                       refine_iterations=second.lm_iterations)


def contenders(residuals: torch.Tensor, loss: torch.Tensor, n_starts: int, combine_tol: float):
    """Which model rows to refine on all samples, and where each row's refined weights come from.

    Per record, the starts whose first-stage ``loss`` is within ``REFINE_MARGIN`` (or 5 combine
    tolerances, if more) of the record's best are contenders; starts further behind sit in another
    local minimum, refining cannot bring them within the combine tolerance of the best, so they keep
    their first-stage weights (and their whole-record loss keeps them out of the combination, as
    before). Contenders that are the same fit (residual vectors within ``SAME_FIT`` of each other,
    relative: several starts often reach one minimum) are refined once. Returns ``(rows, source)``:
    the rows to refine, and for every row the row whose refined weights it takes (itself for a
    refined row, -1 for a row that is not refined)."""
    K = loss.shape[0]
    L = torch.where(torch.isfinite(loss), loss, torch.full_like(loss, float("inf"))).view(-1, n_starts)
    best = L.min(dim=1, keepdim=True).values
    keep = (L <= best * (1.0 + max(REFINE_MARGIN, 5 * combine_tol))).flatten().tolist()
    source = [-1] * K
    rows: list[int] = []
    norm = residuals.pow(2).mean(dim=1).sqrt()
    for k in range(K):
        if not keep[k]:
            continue
        rec = k // n_starts
        for j in rows:
            if j // n_starts == rec and float((residuals[k] - residuals[j]).pow(2).mean().sqrt()) \
                    <= SAME_FIT * float(norm[j]):
                source[k] = j
                break
        else:
            rows.append(k)
            source[k] = k
    return torch.as_tensor(rows, dtype=torch.long, device=loss.device), source


def train_long_record(problem, theta0, preset, chunk: int, row_seeds: Sequence[int], *, warm=None,
                      profile=None, progress=None):
    """Two-stage training of ``problem`` (see the module's text): ``(theta, [(start, subproblem, log)])``
    like :func:`~._train.train_in_chunks`, the subproblems over all samples.

    ``row_seeds`` gives each model row its record's seed (rows of one record share a subset);
    ``warm`` and ``profile`` (functions ``(problem, theta) -> theta``: the least-squares start, the
    jump widths' profile) act on the first stage's problem, before and after its training. The
    second stage refines the :func:`contenders` only. Ctrl-C during the first stage ends the call
    with its best weights (no refinement)."""
    N, K = problem.n_data, problem.K
    idx = torch.as_tensor(np.stack([subset_indices(N, SUBSET_SAMPLES, s) for s in row_seeds]),
                          device=problem.y.device)
    small = problem.sample_subset(idx)
    if warm is not None:
        theta0 = warm(small, theta0)
    options = dict(lm_tol=preset.lm_tol, stop_loss=preset.stop_loss)
    theta, logs1 = train_in_chunks(small, theta0, chunk, progress=progress, adam_steps=preset.adam_steps,
                                   adam_lr=preset.adam_lr, lm_max_iter=preset.lm_max_iter, **options)
    interrupted = any(lg.interrupted for _, _, lg in logs1)
    if profile is not None and not interrupted:
        with torch.no_grad():
            theta = profile(small, theta)
    # the first stage's decay, for a mean over all samples: lambda = alpha / (beta N)
    decay = torch.cat([sub.decay_per_group(sub.K) for _, sub, _ in logs1])
    decay = decay * (small.n_used / problem.n_used).to(decay.dtype).view(-1, 1)
    effective: list = []
    for _, sub, lg in logs1:
        effective += lg.effective_parameters or [None] * sub.K
    second = TrainingLog()
    if not interrupted and preset.lm_max_iter > 0:
        with torch.no_grad():
            sel, source = contenders(small.residuals(theta)[:, :small.n_data], small.loss(theta),
                                     preset.n_starts, preset.combine_tol)
        part = problem.subset(sel)
        part.set_weight_decay(decay[sel] if problem.n_decay_groups > 1 else decay[sel, 0])
        label = None if progress is None else (  # the second stage's lines say what it is
            lambda phase, *rest: progress(f"refine on all {N} samples" if phase == "lm" else phase, *rest))
        refined, logs2 = train_in_chunks(part, theta[sel], chunk, progress=label, adam_steps=0,
                                         adam_lr=preset.adam_lr, lm_max_iter=preset.lm_max_iter, keep_decay=True,
                                         **options)
        theta = theta.clone()
        theta[sel] = refined
        decay[sel] = torch.cat([sub.decay_per_group(sub.K) for _, sub, _ in logs2]).to(decay.dtype)
        second = merge_logs([lg for _, _, lg in logs2])
        rows = sel.tolist()
        for s2, sub2, lg2 in logs2:  # a chunk whose LM took no step keeps the first stage's values
            for j, g in enumerate(lg2.effective_parameters):
                effective[rows[s2 + j]] = g
        for k, j in enumerate(source):  # a start that reached a refined one's minimum takes its weights
            if j >= 0 and j != k:
                theta[k], decay[k], effective[k] = theta[j], decay[j], effective[j]
    problem.set_weight_decay(decay if problem.n_decay_groups > 1 else decay[:, 0])
    out = []
    for s, sub, lg in logs1:
        full = problem.subset(slice(s, s + sub.K))
        out.append((s, full, _merge(lg, second, SUBSET_SAMPLES, effective[s:s + sub.K])))
    assert sum(f.K for _, f, _ in out) == K
    return theta, out

