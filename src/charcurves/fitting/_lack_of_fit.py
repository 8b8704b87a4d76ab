"""The lack-of-fit correction of a fit's posterior bands (issue 48: bands that cover on the curve zoo).

A band of a polynomial (or library) fit is the band of the best curve the representation can take.
Where the record's law has a shape the representation cannot take, the self-check's binned test
(:func:`charcurves.fitting.residual_check`) finds the residual to be a function of that curve's
argument, and the band is centred off the truth by the representation's bias. That bias is what the
residual holds: with ``f = f_hat + b`` the equation's residual is ``b(z) + noise`` (after the
columns the fit could still change are projected out), so the residual's means in quantile bins of
each curve's argument, regressed jointly over the curves of an equation (an additive model, each
curve's bins scaled by its coefficient in the equation), estimate ``b`` in the curve's units.

:func:`lack_of_fit_bias` gives those estimates, gauge-fixed like the curve (zero at 0 where the
range holds 0, else mean zero over the record); :func:`apply_lack_of_fit` wraps the model's
posterior in a :class:`charcurves.model.LackOfFitPosterior` for each curve whose binned test
rejects at :data:`LACK_OF_FIT_LEVEL` (the variance ``sd^2 + b^2``: a mean squared error band) and says
so in ``info["posterior"]``. A curve whose test passes keeps its band unchanged: the bin means' own
noise is far larger than the band of a well-specified curve (a Duffing fit's linear damping: 2-6 times
its width), so it is not added where nothing was found.
"""

from __future__ import annotations

import numpy as np

from ..model import LackOfFitPosterior
from scipy.stats import chi2

from ._residual_tests import ar_whitener, bin_indices
from ._self_check import _equation_parts

__all__ = ["LACK_OF_FIT_BINS", "LACK_OF_FIT_LEVEL", "apply_lack_of_fit", "lack_of_fit_bias"]

#: quantile bins of each curve's argument for the bias estimate (fewer on short records: 50 samples a bin)
LACK_OF_FIT_BINS = 20
#: a curve's band gets the lack-of-fit term where its binned residual test's p-value is below this
#: (chosen on the zoo's tuning half: benchmarks/results/zoo-coverage/PROVENANCE.md)
LACK_OF_FIT_LEVEL = 1e-3


def lack_of_fit_bias(model, record, mask=None, *, bins: int = LACK_OF_FIT_BINS, curves=None,
                     shrink: bool = False) -> dict:
    """``{curve: (centres, bias, p_value)}``: the representation's bias (truth minus fit) of each curve
    (of ``curves``, default all that vary) estimated from the residual of ``model`` on ``record`` (the
    prepared record of the fit; ``mask`` leaves samples out), at the median of each quantile bin of
    the curve's argument, and the p-value of no bias (the bin means over their standard errors, squared
    and summed, against chi-square with one degree of freedom fewer than the bins).
    ``shrink``: each bin's squared mean less its variance (the residual's long-run variance over the
    bin's samples), floored at 0.

    Examples
    --------
    >>> import numpy as np
    >>> import charcurves as cc
    >>> from charcurves.fitting import lack_of_fit_bias
    >>> from charcurves.systems import get_system
    >>> system = get_system("duffing")
    >>> record = cc.corrupt(system.simulate(), 30, on="force", seed=0)
    >>> model = cc.fit(record, method="parametric", basis="f1=z; f2=z")  # f2 without its cubic
    >>> c, b, p = lack_of_fit_bias(model, record)["f2"]
    >>> true_bias = system.true_curves()["f2"](c) - model.curves["f2"](c)
    >>> bool(np.corrcoef(b, true_bias)[0, 1] > 0.95), p < 1e-10
    (True, True)
    """
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


def _long_run_variance(u: np.ndarray) -> float:
    """The long-run variance of ``u`` (the variance of its mean times its length) from its AR model
    (:func:`._residual_tests.ar_whitener`): the innovations' variance over the filter's gain at 0."""
    from scipy.signal import lfilter

    filt = ar_whitener(u)
    e = lfilter(filt, [1.0], u)[len(filt) - 1:]
    return float(np.var(e) / max(float(np.sum(filt)) ** 2, 1e-12))


def apply_lack_of_fit(model, record, mask=None, *, bins: int | None = None, level: float | None = None) -> list[str]:
    """Widen ``model``'s posterior by the estimated bias (:func:`lack_of_fit_bias`, the bin means as
    they are: the bias and its estimate's noise) of each curve whose bias test has a p-value below
    ``level`` (default :data:`LACK_OF_FIT_LEVEL`); the other curves keep their bands. ``bins`` default
    :data:`LACK_OF_FIT_BINS`. Returns the curves whose band widened; ``info["posterior"]`` says which
    posterior the bands come from and ``info["lack_of_fit_p"]`` each curve's p-value.

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.systems import get_system
    >>> record = cc.corrupt(get_system("duffing").simulate(), 30, on="force", seed=0)
    >>> model = cc.fit(record, method="parametric", basis="f1=z; f2=z")  # f2 without its cubic
    >>> type(model.posterior).__name__, sorted(model.posterior.bias)  # the fit ran apply_lack_of_fit
    ('LackOfFitPosterior', ['f2'])
    >>> print(model.info["posterior"].split(":")[0])
    laplace (least squares) + lack of fit (binned residual)
    """
    bins = LACK_OF_FIT_BINS if bins is None else int(bins)
    level = LACK_OF_FIT_LEVEL if level is None else float(level)
    post = getattr(model, "posterior", None)
    if post is None or not (hasattr(post, "curve_factor") and hasattr(post, "scalar_factor")):
        return []
    est = lack_of_fit_bias(model, record, mask, bins=bins)
    model.info["lack_of_fit_p"] = {c: p for c, (_, _, p) in est.items()}
    bias = {c: (z, b) for c, (z, b, p) in est.items() if p < level}
    label = str(getattr(post, "label", None) or getattr(post, "method", "laplace"))
    if not bias:
        model.info["posterior"] = f"{label}; no lack-of-fit term (no curve's bias test has p < {level:g})"
        return []
    model.posterior = LackOfFitPosterior(post, bias)
    model.info["posterior"] = (f"{model.posterior.label}: the bands of {', '.join(sorted(bias))} add the bias "
                               f"estimated from the residual's means in {bins} quantile bins of their arguments "
                               f"(their bias test has p < {level:g})")
    return sorted(bias)
