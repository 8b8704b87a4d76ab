"""The lack-of-fit correction of a fit's posterior bands (issue 48: bands that cover on the curve zoo).

A band of a polynomial (or library) fit is the band of the best curve the representation can take.
Where the record's law has a shape the representation cannot take, the self-check's binned test
(:func:`charcurves.fitting.residual_check`) finds the residual to be a function of that curve's
argument, and the band is centred off the truth by the representation's bias. That bias is what the
residual holds: with ``f = f_hat + b`` the equation's residual is ``b(z) + noise`` (after the
columns the fit could still change are projected out; a sparse fit's pruned terms are not among
them), so a function of each curve's argument, linear between the medians of its quantile bins (hat
functions), regressed jointly over the curves of an equation (an additive model, each curve's hats
scaled by its coefficient in the equation), estimates ``b`` in the curve's units.

:func:`lack_of_fit_bias` gives those estimates at the level the fit leaves them: zero at 0 only for a
curve whose value at 0 the fit does not estimate (anchored by the gauge, ``f2(0) = 0``, or zero at 0 by
its representation, an odd prior; mean zero over the record where its range misses 0), while a curve
whose value at 0 is free keeps its level, and the one that carries an equation's constant takes the
residual's constant (issue 48: a spring's misfit at 0 that the gauge hands to the damper, a
position-damping curve's bias at 0, were dropped before); :func:`apply_lack_of_fit` wraps the model's
posterior in a :class:`charcurves.model.LackOfFitPosterior` for each curve whose binned test
rejects at :data:`LACK_OF_FIT_LEVEL` (the variance ``sd^2 + b^2``: a mean squared error band) and says
so in ``info["posterior"]``. A curve whose test passes keeps its band unchanged: the estimate's own
noise is far larger than the band of a well-specified curve (a Duffing fit's linear spring: about 4
times its width), so it is not added where nothing was found. The exception is a sparse regression's
fit (:func:`sparse_fit`, SINDy): its library is truncated and its support chosen by the data, and its
narrow bands miss biases below what the test detects (issue 48: an odd library's |v|^1.5 damper, 0.67 of
the grid); every curve whose test passes gets a coarser estimate with part of its own noise taken out
(:data:`SPARSE_LACK_OF_FIT`).
"""

from __future__ import annotations

import numpy as np

from ..model import LackOfFitPosterior
from scipy.stats import chi2

from ._residual_tests import ar_whitener, bin_indices
from ._self_check import equation_columns

__all__ = ["LACK_OF_FIT_BINS", "LACK_OF_FIT_LEVEL", "SPARSE_LACK_OF_FIT", "apply_lack_of_fit", "lack_of_fit_bias",
           "sparse_fit"]

#: quantile bins of each curve's argument for the bias estimate (fewer on short records: 50 samples a bin)
LACK_OF_FIT_BINS = 20
#: a curve's band gets the lack-of-fit term where its binned residual test's p-value is below this
#: (chosen on the zoo's tuning half: benchmarks/results/zoo-coverage/PROVENANCE.md)
LACK_OF_FIT_LEVEL = 1e-3
#: the term of a sparse regression's fit (SINDy, :func:`sparse_fit`) on the curves whose test passes: the estimate
#: in ``bins`` bins, its square less ``shrink`` times its variance (chosen on the zoo's tuning half, issue 48:
#: benchmarks/results/zoo-coverage/PROVENANCE.md); the curves whose test rejects get the usual term
SPARSE_LACK_OF_FIT = {"bins": 10, "shrink": 0.25}


def lack_of_fit_bias(model, record, mask=None, *, bins: int = LACK_OF_FIT_BINS, curves=None,
                     shrink: float = 0.0) -> dict:
    """``{curve: (centres, bias, p_value)}``: the representation's bias (truth minus fit) of each curve
    (of ``curves``, default all that vary) estimated from the residual of ``model`` on ``record`` (the
    prepared record of the fit; ``mask`` leaves samples out), at the median of each quantile bin of
    the curve's argument (linear between them), and the p-value of no bias (a Wald test of those values
    with their covariance under the level conditions, against chi-square with its rank: one fewer than
    the bins for a curve held at 0).
    ``shrink`` (0 to 1; ``True`` is 1): each value's square less ``shrink`` times its variance (from the
    residual's long-run variance), floored at 0 (1: the method of moments' estimate of the squared bias).

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
    D = model.template.design(record)
    n = D["n"]
    keep = np.asarray(mask, bool) if mask is not None and len(mask) == n else np.ones(n, bool)
    fixed = _fixed_at_zero(model)
    offsets = _offset_equations(model)
    parts = _parts(model, record, D, keep)
    out: dict = {}
    for e, (r, args, Q) in enumerate(parts):
        rows = slice(e * n, (e + 1) * n)
        names = [c for c, z in args.items() if np.ptp(z) > 0 and c not in out and (curves is None or c in curves)]
        if not names or r.size < 4 * 3:
            continue
        K = int(max(3, min(int(bins), r.size // 50)))
        cols, layout = [np.ones(r.size)], {}
        for c in names:
            z = args[c]
            idx, counts = bin_indices(z, K)
            mult = np.asarray(D["mult"][c], dtype=float)[rows][keep]
            centres = np.array([np.median(z[idx == j]) for j in range(counts.size)])
            # the bias linear between the bins' medians, as the widened band takes it (LackOfFitPosterior): hat
            # functions, whose fit of a smooth bias is off by far less within a bin than bin means (so that a
            # large misfit of one curve does not leak into the other curves' bins through their correlation)
            B = _hats(z, centres)
            layout[c] = (len(cols), counts.size, B.mean(axis=0), centres)
            cols.extend((B * mult[:, None]).T)
        X = np.column_stack(cols)
        C = _level_conditions(X.shape[1], layout, fixed, free_constant=e not in offsets)
        A = _constrained_solver(X, C)  # beta = -A r: least squares under the curves' level conditions
        beta = -(A @ r)  # the residual is model - data
        lrv = _long_run_variance(r + X @ beta)
        for c in names:
            start, k, _, centres = layout[c]
            b, Ac = beta[start:start + k], A[start:start + k]
            se2 = np.maximum(lrv * np.sum(Ac**2, axis=1), 1e-300)
            stat, dof = _wald(b, Ac)
            p_value = float(chi2.sf(stat / max(lrv, 1e-300), max(dof, 1)))
            if shrink:  # the squared bias less (a share of) the estimate's own noise (method of moments)
                b = np.sign(b) * np.sqrt(np.maximum(b**2 - float(shrink) * se2, 0.0))
            out[c] = (centres, b, p_value)
    return out


def _parts(model, record, D: dict, keep: np.ndarray) -> list:
    """Per equation: the residual (masked) orthogonal to what the fit could still change, the arguments of
    its curves and an orthonormal basis ``Q`` of those columns: a constant, a free gain's input and the
    columns of the curves linear in their parameters (times their coefficients in the equation) that the
    fit used. A sparse fit's pruned terms are not among them: their share of the bias (the support taken
    as known) stays in the residual, as a misfit of the curve (the self-check projects them out too,
    :func:`._self_check._equation_parts`; an output-error refinement's change of the used coefficients
    is projected out here as there)."""
    r_all = np.asarray(model.force_residual(record), dtype=float)
    r_all = r_all.reshape(r_all.shape[0], -1)
    out = []
    for e in range(D["E"]):
        cols, _, args = equation_columns(model, D, keep, e, used_only=True)
        u, s, _ = np.linalg.svd(np.column_stack(cols), full_matrices=False)
        Q = u[:, s > 1e-10 * max(float(s.max(initial=0.0)), 1e-300)]
        r = r_all[keep, e]
        out.append((r - Q @ (Q.T @ r), args, Q))
    return out


def _wald(b: np.ndarray, Ac: np.ndarray) -> tuple[float, int]:
    """``b' S^+ b`` with ``S = Ac Ac'`` (the bin means' covariance over the noise variance) and its rank: a
    Wald statistic of the bin means against no misfit, with the residual's long-run variance as the noise
    variance (the self-check's GLS binned test whitens a smooth misfit away: its p is ~0.06 for a linear
    Duffing spring). The full covariance, as the level conditions tie the bins together (a curve held at
    0 at 0 through its two middle bins, a free curve's level shared by every bin) and the fit's own columns
    take up noise along them (a polynomial's shapes: so many fewer degrees of freedom)."""
    u, s, _ = np.linalg.svd(Ac, full_matrices=False)
    keep = s > 1e-6 * max(float(s.max(initial=0.0)), 1e-300)
    w = (u[:, keep].T @ b) / s[keep]
    return float(w @ w), int(keep.sum())


def _pinned(model) -> dict:
    """Curve -> whether its representation is 0 at 0 (the gauge analysis's input)."""
    return {name: bool(getattr(curve, "pinned_at_zero", False)) for name, curve in model.curves.items()}


def _fixed_at_zero(model) -> set:
    """The curves whose value at 0 the fit does not estimate, so that their bias there is 0: those the
    gauge anchors (``f2(0) = 0``: the truth is taken in the same gauge) and those whose representation
    is 0 at 0 (an odd prior, a basis without a constant: the truth is assumed to be 0 there too)."""
    pinned = _pinned(model)
    try:
        conditions = set(model.template.gauge_conditions(pinned))
    except Exception:  # a template without gauge bookkeeping: every curve is held at 0, as before
        return set(model.curves)
    return {name for name in model.curves if pinned[name] or f"{name}(0) = 0" in conditions}


def _offset_equations(model) -> set:
    """The equations with a free constant of their own (no curve carries it): their residual's constant is
    the constant's error, not a curve's bias."""
    try:
        return set(model.template.anchored_offsets(_pinned(model)))
    except Exception:
        return set()


def _level_conditions(p: int, layout: dict, fixed: set, *, free_constant: bool) -> np.ndarray:
    """Rows ``C`` with ``C beta = 0``: each curve of ``fixed`` has bias 0 at 0 (interpolated between the
    bin centres; mean zero over its bins, weighted by their samples, where its range does not hold 0);
    and, where a free curve carries the equation's constant (``free_constant``, some curve not in
    ``fixed``), the intercept is 0, so that a constant misfit is that curve's bias and not dropped."""
    rows = []
    for c, (start, k, weights, centres) in layout.items():
        row = np.zeros(p)
        if c in fixed:
            if centres[0] <= 0.0 <= centres[-1]:
                row[start:start + k] = _hats(np.zeros(1), centres)[0]
            else:
                row[start:start + k] = weights  # the bias's mean over the record
            rows.append(row)
    if free_constant and any(c not in fixed for c in layout):
        row = np.zeros(p)
        row[0] = 1.0
        rows.append(row)
    return np.array(rows).reshape(-1, p)


def _hats(z: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """``(len(z), len(centres))``: the weights of linear interpolation between the centres (constant past
    the outer ones), so that ``_hats(z, c) @ b == np.interp(z, c, b)``."""
    j = np.clip(np.searchsorted(centres, z) - 1, 0, max(len(centres) - 2, 0))
    H = np.zeros((z.size, len(centres)))
    if len(centres) == 1:
        H[:, 0] = 1.0
        return H
    t = np.clip((z - centres[j]) / np.maximum(centres[j + 1] - centres[j], 1e-300), 0.0, 1.0)
    H[np.arange(z.size), j] = 1.0 - t
    H[np.arange(z.size), j + 1] = t
    return H


def _constrained_solver(X: np.ndarray, C: np.ndarray) -> np.ndarray:
    """``A`` with ``A y`` the minimum-norm least-squares solution of ``X beta ~ y`` under ``C beta = 0``."""
    if C.shape[0] == 0:
        return np.linalg.pinv(X, rcond=1e-8)
    _, s, vt = np.linalg.svd(C)
    rank = int(np.sum(s > 1e-10 * max(1.0, float(s.max()))))
    Z = vt[rank:].T  # the conditions' null space
    return Z @ np.linalg.pinv(X @ Z, rcond=1e-8)


def _long_run_variance(u: np.ndarray) -> float:
    """The long-run variance of ``u`` (the variance of its mean times its length) from its AR model
    (:func:`._residual_tests.ar_whitener`): the innovations' variance over the filter's gain at 0."""
    from scipy.signal import lfilter

    filt = ar_whitener(u)
    e = lfilter(filt, [1.0], u)[len(filt) - 1:]
    return float(np.var(e) / max(float(np.sum(filt)) ** 2, 1e-12))


def sparse_fit(model) -> bool:
    """Whether ``model`` is a sparse regression's fit (SINDy's methods: ``info["active_terms"]``, not distilled
    by post-SR), whose library is a truncated one and whose support the data chose: its bias is rarely 0, and its bands are
    conditioned on the support, so they are narrower than the residual can check (issue 48: sindy-cc+sym's
    band held 0.52 of the zoo's report-half grid, with the gated term 0.87, its bias mostly below the test).

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.fitting import sparse_fit
    >>> from charcurves.systems import get_system
    >>> record = cc.corrupt(get_system("duffing").simulate(), 20, on="force", seed=0)
    >>> sparse_fit(cc.fit(record, method="sindy-cc+sym")), sparse_fit(cc.fit(record, method="poly-cc"))
    (True, False)
    """
    info = getattr(model, "info", {})
    return "active_terms" in info and "post_sr" not in info  # a distilled model's curves are closed forms


def apply_lack_of_fit(model, record, mask=None, *, bins: int | None = None, level: float | None = None,
                      sparse: dict | None = None) -> list[str]:
    """Widen ``model``'s posterior by the estimated bias (:func:`lack_of_fit_bias`, the estimates as
    they are: the bias and its estimate's noise) of each curve whose bias test has a p-value below
    ``level`` (default :data:`LACK_OF_FIT_LEVEL`); an output-error fit (``info["objective"]``) keeps its
    plain posterior. ``bins`` default :data:`LACK_OF_FIT_BINS`. A sparse regression's fit
    (:func:`sparse_fit`) also widens the band of every other curve, by the estimate in ``sparse["bins"]``
    bins with ``sparse["shrink"]`` times its variance taken out (default :data:`SPARSE_LACK_OF_FIT`;
    ``sparse={}``: none); the other fits' curves whose test passes keep their bands. Returns the curves
    whose band widened; ``info["posterior"]`` says which posterior the bands come from and
    ``info["lack_of_fit_p"]`` each curve's p-value.

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
    rule = (SPARSE_LACK_OF_FIT if sparse is None else sparse) if sparse_fit(model) else {}
    post = getattr(model, "posterior", None)
    if post is None:
        return []
    label = str(getattr(post, "label", None) or getattr(post, "method", "laplace"))
    if model.info.get("objective") == "output-error":
        # the test reads the equation residual, whose estimated derivatives an output-error fit does not fit:
        # their errors pass for misfit (Duffing, 40 dB on x: bands 5-20 times wider, the plain ones already
        # covering; benchmarks/results/zoo-coverage/duffing-level-fix-oe.txt)
        model.info["posterior"] = f"{label}; no lack-of-fit term (an output-error fit)"
        return []
    if not (hasattr(post, "curve_factor") and hasattr(post, "scalar_factor")):
        return []
    est = lack_of_fit_bias(model, record, mask, bins=bins)
    model.info["lack_of_fit_p"] = {c: p for c, (_, _, p) in est.items()}
    bias = {c: (z, b) for c, (z, b, p) in est.items() if p < level}
    rest = [c for c in est if c not in bias]
    if rule and rest:  # a sparse fit: the curves whose test passes get the coarse term, part of its noise out
        coarse = lack_of_fit_bias(model, record, mask, bins=int(rule["bins"]), shrink=float(rule["shrink"]))
        bias.update({c: (z, b) for c, (z, b, _) in coarse.items() if c in rest and np.any(b != 0)})
    if not bias:
        model.info["posterior"] = f"{label}; no lack-of-fit term (no curve's bias test has p < {level:g})"
        return []
    model.posterior = LackOfFitPosterior(post, bias)
    tested = sorted(c for c in bias if c not in rest)
    why = [f"{', '.join(tested)}: the bias test has p < {level:g}, {bins} quantile bins"] if tested else []
    if rule and any(c in rest for c in bias):
        why.append(f"{', '.join(sorted(c for c in bias if c in rest))}: a sparse regression's fit, whose support the "
                   f"data chose, {int(rule['bins'])} bins, the squared estimate less {float(rule['shrink']):g} times "
                   "its variance")
    model.info["posterior"] = (f"{model.posterior.label}: the bands of {', '.join(sorted(bias))} add the bias "
                               f"estimated from the residual, linear between the medians of quantile bins of their "
                               f"arguments ({'; '.join(why)})")
    return sorted(bias)
