"""The lack-of-fit bias estimate as it was before issue 48's level fix (commit bd29a5b), kept only so that
``bench_zoo_coverage.py --previous`` scores the old and the new band on the same fits (a same-run
baseline). It held every curve's bias at 0 at z = 0 (mean zero where the range misses 0) and dropped
the residual's constant, also where the curve's value at 0 is free (the curve that carries a shared
constant, a position-damping curve)."""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2

from charcurves.fitting._lack_of_fit import _long_run_variance
from charcurves.fitting._residual_tests import bin_indices
from charcurves.fitting._self_check import _equation_parts

__all__ = ["previous_lack_of_fit_bias", "record_previous"]


def previous_lack_of_fit_bias(model, record, mask=None, *, bins: int = 20, curves=None,
                     shrink: bool = False) -> dict:
    """The estimate of :func:`charcurves.fitting.lack_of_fit_bias` before the fix."""
    parts = _equation_parts(model, record, mask)
    D = model.template.design(record)
    n = D["n"]
    keep = np.asarray(mask, bool) if mask is not None and len(mask) == n else np.ones(n, bool)
    out: dict = {}
    for e, (r, _F, args) in enumerate(parts):
        rows = slice(e * n, (e + 1) * n)
        names = [c for c, z in args.items() if np.ptp(z) > 0 and c not in out and (curves is None or c in curves)]
        if not names or r.size < 4 * 3:
            continue
        K = int(max(3, min(int(bins), r.size // 50)))
        cols, layout = [np.ones(r.size)], {}
        for c in names:
            z = args[c]
            idx, counts = bin_indices(z, K)
            B = np.zeros((r.size, counts.size))
            B[np.arange(r.size), idx] = 1.0
            mult = np.asarray(D["mult"][c], dtype=float)[rows][keep]
            layout[c] = (len(cols), counts.size, idx)
            cols.extend((B * mult[:, None]).T)
        X = np.column_stack(cols)
        beta = -np.linalg.lstsq(X, r, rcond=None)[0]  # the residual is model - data; minimum norm: levels fixed below
        lrv = _long_run_variance(r + X @ beta)
        for c in names:
            start, k, idx = layout[c]
            b = beta[start:start + k]
            z = args[c]
            mult = np.asarray(D["mult"][c], dtype=float)[rows][keep]
            centres = np.array([np.median(z[idx == j]) for j in range(k)])
            se2 = lrv / np.maximum(np.bincount(idx, weights=mult**2, minlength=k), 1e-300)
            if centres[0] <= 0.0 <= centres[-1]:  # the curve's gauge: its value at 0 is fixed
                b, se2 = b - np.interp(0.0, centres, b), se2 + np.interp(0.0, centres, se2)
            else:
                b = b - np.sum(np.bincount(idx, minlength=k) * b) / z.size
            # a Wald statistic of the bin means against no misfit, with the residual's long-run variance (the
            # self-check's GLS binned test whitens a smooth misfit away: its p is ~0.06 for a linear Duffing spring)
            stat = float(np.sum(b**2 / se2))
            p_value = float(chi2.sf(stat, max(k - 1, 1)))
            if shrink:  # the squared bias less the bin mean's own noise (method of moments)
                b = np.sign(b) * np.sqrt(np.maximum(b**2 - se2, 0.0))
            out[c] = (centres, b, p_value)
    return out


def record_previous() -> None:
    """Make every fit also keep the previous lack-of-fit estimate (on the same prepared record and mask) in
    ``info["_lack_of_fit_previous"]``; the pipeline imports ``apply_lack_of_fit`` at each check."""
    import charcurves.fitting._lack_of_fit as lof

    new = lof.apply_lack_of_fit

    def both(model, record, mask=None, **kw):
        out = new(model, record, mask, **kw)
        if getattr(model, "posterior", None) is not None:
            model.info["_lack_of_fit_previous"] = previous_lack_of_fit_bias(model, record, mask, bins=lof.LACK_OF_FIT_BINS)
        return out

    lof.apply_lack_of_fit = both
