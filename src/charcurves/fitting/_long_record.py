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

from ._train import TrainingLog, train_in_chunks

__all__ = ["SUBSET_SAMPLES", "is_long", "subset_indices", "train_long_record"]

#: samples of the first stage's subset (and the length from which a record counts as long)
SUBSET_SAMPLES = 4096


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


def _merge(first: TrainingLog, second: TrainingLog, n_sub: int) -> TrainingLog:
    return TrainingLog(adam_steps=first.adam_steps, lm_iterations=first.lm_iterations,
                       history=first.history + [("refine", s, v) for _, s, v in second.history],
                       stopped_by=second.stopped_by or first.stopped_by,
                       interrupted=first.interrupted or second.interrupted,
                       effective_parameters=second.effective_parameters or first.effective_parameters,
                       subset_samples=n_sub, refine_iterations=second.lm_iterations)


def train_long_record(problem, theta0, preset, chunk: int, row_seeds: Sequence[int], *, warm=None,
                      profile=None, progress=None):
    """Two-stage training of ``problem`` (see the module's text): ``(theta, [(start, subproblem, log)])``
    like :func:`~._train.train_in_chunks`, the subproblems over all samples.

    ``row_seeds`` gives each model row its record's seed (rows of one record share a subset);
    ``warm`` and ``profile`` (functions ``(problem, theta) -> theta``: the least-squares start, the
    jump widths' profile) act on the first stage's problem, before and after its training.
    Ctrl-C during the first stage ends the call with its best weights (no refinement)."""
    N = problem.n_data
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
    if problem.bayesian and preset.lm_max_iter > 0:
        # the first stage's decay, for a mean over all samples: lambda = alpha / (beta N)
        decay = torch.cat([sub.decay_per_group(sub.K) for _, sub, _ in logs1])
        ratio = (small.n_used / problem.n_used).to(decay.dtype).view(-1, 1)
        decay = decay * ratio
        problem.set_weight_decay(decay if problem.n_decay_groups > 1 else decay[:, 0])
    if interrupted or preset.lm_max_iter == 0:
        return theta, [(s, problem.subset(slice(s, s + sub.K)), _merge(lg, TrainingLog(), SUBSET_SAMPLES))
                       for s, sub, lg in logs1]
    theta, logs2 = train_in_chunks(problem, theta, chunk, progress=progress, adam_steps=0, adam_lr=preset.adam_lr,
                                   lm_max_iter=preset.lm_max_iter, keep_decay=True, **options)
    return theta, [(s, sub, _merge(lg1, lg2, SUBSET_SAMPLES))
                   for (s, _, lg1), (_, sub, lg2) in zip(logs1, logs2)]
