"""Ensemble statistics of noise sweeps: ensemble RMSE, A fits, performance %, MIW.

The paper summarises each method by how its curve errors grow with the noise fraction
η = 10^(−SNR/20). Per SNR level the errors of the noise realisations are combined into an
ensemble RMSE, either as the paper's root of the mean of squares (Eq. 19, ``how="rms"``) or as
the authors' scripts do, the arithmetic mean of per-run RMSEs (``how="mean"``, which reproduces
the published tables). Across levels a line of slope 1 in log-log space,
``RMSE ≈ A η``, gives the amplitude ``A`` (Tables 2 and 3); methods with an error floor are fitted
with ``RMSE ≈ sqrt(bias² + (A η)²)``. Performance % compares ``A`` with the Parametric reference.

MIW (Table 1) measures the spread of a curve's residuals at the training points, binned in the
curve's argument and pooled over datasets.

Examples
--------
>>> import numpy as np
>>> eta = np.array([0.01, 0.1, 1.0])
>>> round(fit_slope_one(eta, 0.05 * eta), 6)
0.05
>>> ensemble_rmse([3.0, 4.0], how="rms"), ensemble_rmse([3.0, 4.0], how="mean")
(3.5355339059327378, 3.5)
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from .._errors import ConfigError, DataError

__all__ = [
    "ENSEMBLE_KINDS",
    "PERFORMANCE_TERMS",
    "MIWResult",
    "ensemble_rmse",
    "ensemble_by_level",
    "fit_slope_one",
    "fit_bias",
    "performance_percent",
    "miw",
    "curve_residuals",
]

#: ``"rms"``: the paper's sqrt(mean(RMSE²)); ``"mean"``: the scripts' mean of per-run RMSEs.
ENSEMBLE_KINDS = ("rms", "mean")
#: The A terms each system's performance % averages (paper Sec. 4, Figs. 9 and 13).
PERFORMANCE_TERMS = {"duffing": ("f1", "f2"), "stick-slip": ("f1", "f2", "x")}


def _vector(name: str, values: Any) -> np.ndarray:
    try:
        arr = np.asarray(values, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise DataError(f"{name} must be numbers ({exc})") from None
    return arr


def _check_kind(how: str) -> str:
    if how not in ENSEMBLE_KINDS:
        raise ConfigError(
            f"how must be 'rms' (the paper's root of mean squares) or 'mean' (the scripts' mean of "
            f"per-run RMSEs), got {how!r}"
        )
    return how


def ensemble_rmse(values: Sequence[float] | np.ndarray, how: str = "rms") -> float:
    """Combine per-realisation RMSEs of one noise level into one ensemble value.

    Parameters
    ----------
    values : array_like
        Per-run RMSEs (non-finite entries, e.g. failed runs, are ignored).
    how : {"rms", "mean"}
        ``"rms"``: ``sqrt(mean(values²))`` (paper Eq. 19); ``"mean"``: ``mean(values)`` (the
        authors' plot scripts, which reproduce Tables 2 and 3).

    Returns
    -------
    float
        NaN when no finite value is given.

    Examples
    --------
    >>> from charcurves.metrics import ensemble_rmse
    >>> ensemble_rmse([1.0, 7.0], how="rms"), ensemble_rmse([1.0, 7.0], how="mean")
    (5.0, 4.0)
    """
    _check_kind(how)
    v = _vector("values", values)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return float("nan")
    return float(np.sqrt(np.mean(v * v))) if how == "rms" else float(np.mean(v))


def ensemble_by_level(levels: Sequence[float] | np.ndarray, values: Sequence[float] | np.ndarray, how: str = "rms"):
    """Group per-run values by noise level (SNR in dB or η) and combine each group.

    Parameters
    ----------
    levels : array_like
        The level of each run (e.g. SNR in dB; ``inf`` allowed).
    values : array_like
        The per-run RMSEs.
    how : {"rms", "mean"}
        See :func:`ensemble_rmse`.

    Returns
    -------
    (levels, ensemble, counts) : three arrays
        The distinct levels in descending order, the ensemble value of each and the number of
        finite values it combined.

    Examples
    --------
    >>> from charcurves.metrics import ensemble_by_level
    >>> lv, ens, n = ensemble_by_level([20, 20, 0, 0], [1.0, 3.0, 2.0, 2.0], how="mean")
    >>> lv.tolist(), ens.tolist(), n.tolist()
    ([20.0, 0.0], [2.0, 2.0], [2, 2])
    """
    _check_kind(how)
    lv = _vector("levels", levels)
    v = _vector("values", values)
    if lv.shape != v.shape:
        raise DataError(f"levels and values must have the same length, got {lv.size} and {v.size}")
    if np.isnan(lv).any():
        raise DataError("levels contain NaN; give every run its SNR (inf for noise-free runs)")
    uniq = np.unique(lv)[::-1]
    ens = np.array([ensemble_rmse(v[lv == u], how) for u in uniq])
    counts = np.array([int(np.isfinite(v[lv == u]).sum()) for u in uniq])
    return uniq, ens, counts


def _fit_mask(eta: np.ndarray, rmse: np.ndarray, eta_min, eta_max, mask) -> np.ndarray:
    keep = np.isfinite(eta) & np.isfinite(rmse) & (eta > 0) & (rmse > 0)
    if mask is not None:
        m = np.asarray(mask, dtype=bool).reshape(-1)
        if m.shape != eta.shape:
            raise DataError(f"mask must have one entry per level ({eta.size}), got {m.size}")
        keep &= m
    if eta_min is not None:
        keep &= eta >= float(eta_min)
    if eta_max is not None:
        keep &= eta <= float(eta_max)
    return keep


def fit_slope_one(eta: Sequence[float] | np.ndarray, rmse: Sequence[float] | np.ndarray, *,
                  eta_min: float | None = None, eta_max: float | None = None,
                  mask: Sequence[bool] | None = None) -> float:
    """Amplitude ``A`` of ``RMSE = A η`` fitted with the slope fixed to 1 in log-log space.

    ``log A = mean_k(log RMSE_k − log η_k)`` (natural logs, unweighted) over the levels kept:
    η = 0 (noise-free), non-positive or non-finite values are always left out; ``eta_min``,
    ``eta_max`` and ``mask`` narrow the range further (the scripts fit SR at η ≤ 8 for Duffing,
    η ≤ 5 for stick-slip, and the stick-slip RMSE[x] of the NN variants at η ≤ 0.3).

    Parameters
    ----------
    eta : array_like
        Nominal noise fractions of the levels, ``10**(-SNR/20)``.
    rmse : array_like
        Ensemble RMSE of each level.
    eta_min, eta_max : float, optional
        Inclusive bounds of the fitted range.
    mask : array_like of bool, optional
        Extra selection of levels.

    Returns
    -------
    float
        ``A``; NaN when no level is left.

    Examples
    --------
    >>> from charcurves.metrics import fit_slope_one
    >>> round(fit_slope_one([0.1, 1.0], [0.02, 0.08]), 6)   # exp(mean(log 0.2, log 0.08))
    0.126491
    """
    e = _vector("eta", eta)
    r = _vector("rmse", rmse)
    if e.shape != r.shape:
        raise DataError(f"eta and rmse must have the same length, got {e.size} and {r.size}")
    keep = _fit_mask(e, r, eta_min, eta_max, mask)
    if not keep.any():
        return float("nan")
    return float(np.exp(np.mean(np.log(r[keep]) - np.log(e[keep]))))


def fit_bias(eta: Sequence[float] | np.ndarray, rmse: Sequence[float] | np.ndarray, *,
             eta_min: float | None = None, eta_max: float | None = None,
             mask: Sequence[bool] | None = None) -> tuple[float, float]:
    """Fit ``RMSE = sqrt(bias² + (A η)²)`` for methods with an error floor.

    As the stick-slip scripts do for Poly-CC and SINDy-CC: ``scipy.optimize.curve_fit`` in
    linear space on the ensemble values, starting from ``[min RMSE, 1]``, both parameters
    bounded below by 0. Levels are selected as in :func:`fit_slope_one`.

    Returns
    -------
    (bias, A) : tuple of float
        NaN, NaN when fewer than two levels are left.

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.metrics import fit_bias
    >>> eta = np.logspace(-2, 1, 31)
    >>> b, A = fit_bias(eta, np.sqrt(0.2**2 + (0.3 * eta) ** 2))
    >>> round(b, 6), round(A, 6)
    (0.2, 0.3)
    """
    from scipy.optimize import curve_fit

    e = _vector("eta", eta)
    r = _vector("rmse", rmse)
    if e.shape != r.shape:
        raise DataError(f"eta and rmse must have the same length, got {e.size} and {r.size}")
    keep = _fit_mask(e, r, eta_min, eta_max, mask)
    if keep.sum() < 2:
        return float("nan"), float("nan")
    ek, rk = e[keep], r[keep]

    def model(x, b, a):
        return np.sqrt(b * b + (a * x) ** 2)

    import warnings

    from scipy.optimize import OptimizeWarning

    with warnings.catch_warnings():  # the covariance is not used (two levels leave none to estimate)
        warnings.simplefilter("ignore", OptimizeWarning)
        popt, _ = curve_fit(model, ek, rk, p0=[float(rk.min()), 1.0], bounds=([0.0, 0.0], [np.inf, np.inf]))
    return float(popt[0]), float(popt[1])


def performance_percent(a_method: Mapping[str, float], a_reference: Mapping[str, float],
                        terms: Sequence[str] | str | None = None) -> float:
    """Performance % of a method relative to the Parametric reference: ``mean_i(A_ref,i / A_i)·100``.

    Duffing averages the f1 and f2 terms, stick-slip adds the RMSE[x] term ("x")
    (:data:`PERFORMANCE_TERMS`); SINDy-CC and Poly-CC of stick-slip have only the f terms.

    Parameters
    ----------
    a_method, a_reference : mapping
        ``{"f1": A, "f2": A, "x": A}`` of the method and of Parametric.
    terms : sequence of str, or a system name, optional
        The terms to average; by default those with a finite, positive A in both mappings.

    Examples
    --------
    >>> from charcurves.metrics import performance_percent
    >>> performance_percent({"f1": 0.1, "f2": 0.04}, {"f1": 0.01, "f2": 0.02})
    30.0
    """
    if isinstance(terms, str):
        if terms not in PERFORMANCE_TERMS:
            raise ConfigError(f"unknown system {terms!r} for the performance terms; choose "
                              f"{', '.join(PERFORMANCE_TERMS)} or give the terms, e.g. ('f1', 'f2')")
        terms = [t for t in PERFORMANCE_TERMS[terms] if _usable(a_method.get(t)) and _usable(a_reference.get(t))]
    elif terms is None:
        terms = [t for t in a_method if _usable(a_method.get(t)) and _usable(a_reference.get(t))]
    terms = list(terms)
    if not terms:
        return float("nan")
    ratios = []
    for t in terms:
        if t not in a_method or t not in a_reference:
            raise ConfigError(f"term {t!r} is missing from the method's or the reference's A values")
        ratios.append(float(a_reference[t]) / float(a_method[t]))
    return float(100.0 * np.mean(ratios))


def _usable(a: Any) -> bool:
    try:
        return a is not None and math.isfinite(float(a)) and float(a) > 0
    except (TypeError, ValueError):
        return False


@dataclasses.dataclass(frozen=True)
class MIWResult:
    """Mean interval widths of binned residuals (paper Table 1).

    Attributes
    ----------
    miw_range : float
        Mean over bins of (max − min) of the pooled residuals.
    miw_99 : float
        Mean over bins (with at least two residuals) of the half-width ``t_{0.995, n−1}·SEM`` of
        the 99 % confidence interval of the bin's mean (the scripts' definition).
    n_bins : int
    bin_centers, ranges, half_widths, counts : numpy arrays per bin

    Examples
    --------
    >>> from charcurves.metrics import MIWResult, miw
    >>> result = miw([0.0, 0.001, 0.03, 0.031], [0.0, 0.2, 1.0, 1.4])
    >>> isinstance(result, MIWResult), result.n_bins, result.counts.tolist()
    (True, 2, [2, 2])
    """

    miw_range: float
    miw_99: float
    n_bins: int
    bin_centers: np.ndarray
    ranges: np.ndarray
    half_widths: np.ndarray
    counts: np.ndarray


def miw(z, residuals, *, bin_width: float = 0.03, confidence: float = 0.99) -> MIWResult:
    """MIW_range and MIW_99 of residuals binned in the curve's argument (reference protocol §7.6).

    Residuals ``r(z) = f̂(z) − f_true(z)`` at the training points of every dataset of an
    ensemble are pooled; bins are ``round(z / bin_width)`` (width 0.03 as in the scripts).

    Parameters
    ----------
    z, residuals : array_like, or sequences of arrays (one per dataset, pooled)
    bin_width : float
    confidence : float
        Two-sided level of the interval (0.99: t quantile 0.995).

    Returns
    -------
    MIWResult

    Examples
    --------
    >>> from charcurves.metrics import miw
    >>> r = miw([0.0, 0.001, 0.03, 0.031], [0.0, 0.2, 1.0, 1.4])
    >>> round(r.miw_range, 6)
    0.3
    """
    from scipy.stats import t as student_t

    zz = _pooled("z", z)
    rr = _pooled("residuals", residuals)
    if zz.shape != rr.shape:
        raise DataError(f"z and residuals must have the same number of points, got {zz.size} and {rr.size}")
    if not (bin_width > 0 and math.isfinite(bin_width)):
        raise ConfigError(f"bin_width must be a positive number, got {bin_width!r}")
    if not 0 < confidence < 1:
        raise ConfigError(f"confidence must be in (0, 1), got {confidence!r}")
    ok = np.isfinite(zz) & np.isfinite(rr)
    zz, rr = zz[ok], rr[ok]
    if zz.size == 0:
        raise DataError("no finite residuals to bin")
    idx = np.round(zz / bin_width).astype(np.int64)
    bins, inverse = np.unique(idx, return_inverse=True)
    n = np.bincount(inverse)
    order = np.argsort(inverse, kind="stable")
    splits = np.split(rr[order], np.cumsum(n)[:-1])
    ranges = np.array([s.max() - s.min() for s in splits])
    q = 0.5 + confidence / 2.0
    half = np.full(bins.size, np.nan)
    for i, s in enumerate(splits):
        if s.size >= 2:
            sem = np.std(s, ddof=1) / math.sqrt(s.size)
            half[i] = float(student_t.ppf(q, s.size - 1)) * sem
    miw99 = float(np.nanmean(half)) if np.isfinite(half).any() else float("nan")
    return MIWResult(float(np.mean(ranges)), miw99, int(bins.size), bins * bin_width, ranges, half, n)


def _pooled(name: str, values) -> np.ndarray:
    if isinstance(values, (list, tuple)) and values and all(np.ndim(v) >= 1 for v in values):
        return np.concatenate([_vector(name, v) for v in values])
    return _vector(name, values)


def curve_residuals(model, traj, truth: Mapping[str, Callable] | Callable, curve: str = "f2"):
    """Residuals ``f̂(z) − f_true(z)`` of one curve at a record's samples (the MIW input).

    Parameters
    ----------
    model : FittedModel
    traj : Trajectory
        The training record (with derivatives).
    truth : mapping of curve name to callable, or a callable
        E.g. ``system.true_curves()``.
    curve : str
        The curve ("f2": the stiffness, as in Table 1).

    Returns
    -------
    (z, r) : two arrays
        The curve's argument at the samples and the residuals there.

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.metrics import curve_residuals
    >>> from charcurves.systems import get_system
    >>> system = get_system("duffing")
    >>> record = cc.corrupt(system.simulate(), 20, seed=0)
    >>> z, r = curve_residuals(cc.fit(record, method="poly-cc"), record, system.true_curves(), curve="f2")
    >>> z.shape, round(float(abs(r).max()), 3)
    ((1000,), 0.032)
    """
    f_true = truth[curve] if isinstance(truth, Mapping) else truth
    z = np.asarray(model.template.arguments_of(traj)[curve], dtype=float)
    r = np.asarray(model.curves[curve](z), dtype=float) - np.asarray(f_true(z), dtype=float)
    return z, r
