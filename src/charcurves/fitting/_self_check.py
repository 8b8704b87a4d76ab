"""Every fit checks itself: the loss of each equation against the noise floor of its record.

A model that captured the system leaves residuals of the size of the measurement noise, so its
equation-error loss is near the noise floor (:func:`charcurves.data.noise_floor`, the estimate
selection's inner loop uses: Savitzky-Golay residuals of the forcing and of a measured x'', or a
given SNR). A loss far above the floor (ratio > :data:`SELF_CHECK_FACTOR`) means the fit missed
something; the fit then warns, naming the likely causes in order and what to try for each.

A loss near the floor can still hide a misfit of the curves' shape (a cubic standing in for
v|v|, an odd curve for an asymmetric spring): :func:`residual_check` runs the residual tests of
system identification (:mod:`._residual_tests`) on each equation's residual -- a binned test
against each curve's argument, the cross-correlation with the input and, where a correct model
leaves white residuals, whiteness -- and warns for each failed test, naming the curve and the cause.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..data import REL_FLOOR, equation_floors, noise_variance
from ._residual_tests import autocorrelation, bin_indices, binned_tests, input_correlation, whiteness

__all__ = ["RESIDUAL_LEVEL", "RESIDUAL_MIN_EFFECT", "residual_check", "residual_test_rows", "self_check", "SELF_CHECK_FACTOR", "self_check_warning"]

#: a loss more than this multiple of the noise floor gets a warning (the inner loop of model
#: selection accepts 1.5; this bound flags fits that clearly failed, not marginal ones)
SELF_CHECK_FACTOR = 10.0
#: a measured x or x' column whose Savitzky-Golay noise variance is below this fraction of its
#: variance (an SNR above 50 dB) is taken as clean by :func:`measured_state_noise`
CLEAN_COLUMN = 1e-5
#: the residual tests' level: the chance that a well-specified fit fails any of its tests
#: (Bonferroni: each of the n tests of a fit runs at RESIDUAL_LEVEL / n). 0.3 %: at 1 % 2 of 100
#: well-specified fits were flagged (benchmarks/bench_self_check.py), at 0.3 % none, with the
#: detections of the misspecified fits at 20 dB on F kept (docs/selection.md)
RESIDUAL_LEVEL = 0.003
#: a failed test must also have found structure of at least this share of the equation's noise
#: floor: a clean record's residual (a differentiator's bias, round-off) has structure the tests
#: see, far below the floor's noise-free part (1e-4 of var(g F)); a cubic for drag, 20 dB on F: 0.03-0.05
RESIDUAL_MIN_EFFECT = 0.01
#: quantile bins of a curve's argument in the binned test (fewer on short records: 50 samples a bin)
RESIDUAL_BINS = 10


def _equation_losses(model, record, mask) -> list[float]:
    """Mean squared equation residual per equation over the fitted samples (sticking phases left out)."""
    r = np.asarray(model.force_residual(record), dtype=float)
    r = r.reshape(r.shape[0], -1)
    if mask is not None and len(mask) == r.shape[0]:
        r = r[np.asarray(mask, bool)]
    return [float(np.mean(r[:, e] ** 2)) for e in range(r.shape[1])]


def _states_of(record) -> dict:
    states = getattr(record, "states", None)
    return dict(states) if states is not None else {"x": record.x}


def derivative_noise(model, raw, prepared, prepare, mask=None, seed: int = 0) -> tuple[list[float], float]:
    """The part of the floor that noise on the measured state puts into the equation through the
    estimated derivatives (and the curves), per equation; and the largest state-noise variance.

    The state's white-noise variance σ² is estimated (Savitzky-Golay residuals of each state); a
    copy of the raw record with a further N(0, σ²) on every state is prepared like the record
    (``prepare``: the same differentiator, settings and checks) and the variance of the change of
    the model's equation residual is the noise the estimate carries: the differentiators are (near)
    linear in the data, so the noise already in the record passes through the same way.
    """
    rng = np.random.default_rng(int(seed))
    states = _states_of(raw)
    sig2 = {k: noise_variance(v) for k, v in states.items()}
    noisy = {k: np.asarray(v, dtype=float) + rng.normal(scale=np.sqrt(max(sig2[k], 0.0)), size=np.shape(v))
             for k, v in states.items()}
    changes: dict[str, Any] = {"states": noisy} if getattr(raw, "states", None) is not None else {"x": noisy["x"]}
    if getattr(raw, "states", None) is None:
        changes.update(v=None, a=None)
    perturbed = prepare(raw.replace(**changes))
    r0 = np.asarray(model.force_residual(prepared), dtype=float)
    r1 = np.asarray(model.force_residual(perturbed), dtype=float)
    d = (r1 - r0).reshape(r0.shape[0], -1)
    if mask is not None and len(mask) == d.shape[0]:
        d = d[np.asarray(mask, bool)]
    return [float(np.var(d[:, e])) for e in range(d.shape[1])], float(max(sig2.values()))


def measured_state_noise(model, prepared, mask=None, seed: int = 0) -> tuple[list[float], float]:
    """The part of the floor that noise on *measured* x and x' columns puts into the equation through
    the curves (errors in variables: a curve's argument is noisy, so its value is), per equation;
    and the largest noise variance of those columns.

    Each state and velocity column's white-noise variance σ² is estimated (Savitzky-Golay
    residuals); a copy of the prepared record with a further N(0, σ²) on each of them gives the
    variance of the change of the model's equation residual, about Σ σ² f'(z)² over the curves
    (x'' is not perturbed: a measured x'' is in the floor already). A column whose estimate is below
    :data:`CLEAN_COLUMN` of its variance (50 dB) counts as clean and adds nothing: there the estimate
    is the signal's own roughness (a stick-slip velocity's kinks), not noise, and a steep curve (a
    friction jump) would turn it into a floor far too high.
    """
    rng = np.random.default_rng(int(seed))
    multi = getattr(prepared, "states", None) is not None
    fields = {"states": prepared.states, "velocities": prepared.velocities} if multi else \
        {"x": {"x": prepared.x}, "v": {"v": getattr(prepared, "v", None)}}
    sig2: dict[tuple, float] = {}
    changes: dict[str, Any] = {}
    for field, columns in fields.items():
        if not columns or all(v is None for v in columns.values()):
            continue
        noisy = {}
        for name, v in columns.items():
            v = np.asarray(v, dtype=float)
            s2 = noise_variance(v)
            s2 = s2 if s2 > CLEAN_COLUMN * float(np.var(v)) else 0.0
            sig2[(field, name)] = s2
            noisy[name] = v + rng.normal(scale=np.sqrt(s2), size=v.shape) if s2 > 0 else v
        changes[field] = noisy if multi else noisy[field]
    r0 = np.asarray(model.force_residual(prepared), dtype=float)
    r1 = np.asarray(model.force_residual(prepared.replace(**changes)), dtype=float)
    d = (r1 - r0).reshape(r0.shape[0], -1)
    if mask is not None and len(mask) == d.shape[0]:
        d = d[np.asarray(mask, bool)]
    return [float(np.var(d[:, e])) for e in range(d.shape[1])], float(max(sig2.values(), default=0.0))


def _derivative_scales(record, order: int) -> list[float]:
    """Variance of each equation's highest derivative (x'', or x' for first-order templates)."""
    if getattr(record, "forces", None) is None:
        d = getattr(record, "a", None) if order >= 2 else None
        d = d if d is not None else getattr(record, "v", None)
        return [0.0 if d is None else float(np.var(np.asarray(d, dtype=float)))]
    accs = record.accelerations or {}
    states = list(record.states)
    return [float(np.var(np.asarray(accs[s], dtype=float))) if s in accs else 0.0
            for s in (states[min(k, len(states) - 1)] for k in range(len(record.forces)))]


def self_check_warning(ratio: float, floor: float, source: str, equation: str = "", *,
                       output_error: bool = False) -> str:
    """The one-line warning of a fit whose loss is ``ratio`` times the noise floor."""
    what = "the output-error loss (free runs against the measured states)" if output_error else \
        "the equation-error loss" + (f" of equation {equation}" if equation else "")
    return (f"self-check: {what} is {ratio:.3g} times the noise floor ({floor:.3g}, {source}); "
            "a fit that captured the system is near 1. Likely causes, most likely first: "
            "(1) curve capacity: a curve too small for its law (e.g. periodic over many periods) -- try a "
            "larger network (Neural(hidden=(32, 32))) or a richer basis (--method poly-cc, --basis); "
            "(2) wrong family or missing term (e.g. a cross term f(x)*x' the family cannot hold) -- run "
            "`charcurves select` or write the term into --equation; "
            "(3) derivative estimation -- try another --derivatives (spline, savgol, spectral) or give "
            "measured v, a columns; "
            "(4) forcing scale -- check the forcing's units and gain (or learn it: --free-gain)")


def _state_floor(raw) -> tuple[float, str]:
    """Noise variance of the measured states (mean over them): Savitzky-Golay residuals, at least
    1e-4 of their variance (the 40 dB floor of a noise-free record)."""
    states = [np.asarray(v, dtype=float) for v in _states_of(raw).values()]
    s2 = float(np.mean([noise_variance(v) for v in states]))
    guard = REL_FLOOR * float(np.mean([np.var(v) for v in states]))
    return max(s2, guard), (f"Savitzky-Golay residual of the measured state{'s' if len(states) > 1 else ''}, "
                            "at least 1e-4 of its variance")


def _output_error_check(model, raw) -> dict | None:
    """The ratio of a fit by output error: its own loss (mean squared error of the segments' free runs
    against the measured states, after the refit) over the states' noise variance."""
    oe = model.info.get("output_error") or {}
    if raw is None or not str(oe.get("status", "")).startswith("ok") or oe.get("segmented_rmse_after") is None:
        return None
    floor, source = _state_floor(raw)
    loss = float(oe["segmented_rmse_after"]) ** 2
    return {"loss_over_floor": [loss / floor if floor > 0 else float("inf")], "loss_value": [loss],
            "noise_floor": [floor], "floor_source": source,
            "loss": "output error: mean squared error of the segments' free runs against the measured states"}


def self_check(model, record, mask=None, *, estimated: bool = False, snr_db: float | None = None,
               state_noise: tuple[list[float], float] | None = None, raw=None,
               state_noise_via: str = "the estimated derivatives") -> dict:
    """Add ``info["self_check"]`` to ``model`` and, when a ratio exceeds :data:`SELF_CHECK_FACTOR`,
    a line to ``info["warnings"]``; returns the check.

    Equation error: the loss is the equation-error loss (mean squared residual of each equation,
    sticking samples left out) of the model's final curves -- after post-SR -- on ``record``, the
    prepared record the fit used (the record's own derivative columns, or those the differentiator
    estimated), and the floor is :func:`charcurves.data.equation_floors`. With ``estimated``
    derivatives x'' is not taken as measured (its noise is not added to the floor); ``state_noise``
    (:func:`derivative_noise`: what the state's noise carries into the equation through the
    differentiator) is added instead. With measured derivatives, ``state_noise`` is
    :func:`measured_state_noise` (the noise of the measured x and x' columns through the curves),
    added where it is more than 1 % of a floor.

    Output error (``info["output_error"]`` finished): the model's loss (``model.loss``) may be the
    equation-error loss of the start, and the equation-error loss of the final curves on estimated
    derivatives holds the differentiator's smoothing bias, which no floor estimates (a correct
    Duffing model at 30 dB of state noise: 31 times the floor). The ratio is then output error's
    own: the mean squared error of the segments' free runs against the measured states (``raw``)
    over the states' noise variance; the equation-error figures are kept under ``equation_error``.
    """
    losses = _equation_losses(model, record, mask)
    # a measured x'' adds its noise to the floor only where the equation holds x'' (not first order)
    order = int(getattr(model.template, "order", 2))
    floors = equation_floors(record, gain=float(model.gain), snr_db=snr_db,
                             acceleration_given=not estimated and order >= 2)
    scales = _derivative_scales(record, order)
    if len(floors) != len(losses):  # one forcing column shared by several equations
        floors, scales = [floors[0]] * len(losses), [scales[0]] * len(losses)
    # the floor's noise-free part is 1e-4 (40 dB) of var(g F); a free response (F constant) has only
    # the derivative term to balance the curves, so there the same fraction of its variance stands in
    extra = list(state_noise[0]) if state_noise is not None else [0.0] * len(losses)
    if len(extra) != len(losses):
        extra = [float(np.mean(extra))] * len(losses)
    if not estimated and not any(e > 0.01 * nf.floor for e, nf in zip(extra, floors)):
        state_noise, extra = None, [0.0] * len(losses)  # measured columns without noise worth counting
    values = [nf.floor + e if nf.floor - nf.sigma2_acceleration > 0 else max(nf.floor + e, REL_FLOOR * s)
              for nf, e, s in zip(floors, extra, scales)]
    source = floors[0].source
    if state_noise is not None:
        source += (f"; plus the state's noise (variance {state_noise[1]:.3g}, Savitzky-Golay residual) through "
                   f"{state_noise_via}")
    ee: dict[str, Any] = {"loss_over_floor": [loss / f if f > 0 else float("inf") for loss, f in zip(losses, values)],
          "loss_value": losses, "noise_floor": values, "floor_source": source,
          "loss": "equation-error loss of the final curves on the prepared record (sticking samples left out)"}
    oe = _output_error_check(model, raw)
    used: dict[str, Any] = oe if oe is not None else ee
    ratios: list[float] = list(used["loss_over_floor"])
    check = {**used, "threshold": SELF_CHECK_FACTOR, "passed": bool(all(r <= SELF_CHECK_FACTOR for r in ratios)),
             # the floor holds noise of the state (through derivatives or curves, or output error's own):
             # selection's inner loop then takes these figures rather than the forcing's floor alone
             "state_noise_counted": bool(oe is not None or state_noise is not None)}
    if oe is not None:
        check["equation_error"] = ee
    check["residual_tests"] = residual_check(model, record, mask, white_expected=not estimated and oe is None,
                                             floors=values)
    model.info["self_check"] = check
    lines = check["residual_tests"].pop("warnings")
    if not model.info.get("interrupted"):
        if not check["passed"]:  # the loss far above the floor first, then the residual tests
            k = int(np.argmax(ratios))
            label = f"{k + 1} of {len(ratios)}" if len(ratios) > 1 else ""
            lines.insert(0, self_check_warning(ratios[k], used["noise_floor"][k], used["floor_source"], label,
                                               output_error=oe is not None))
        if lines:
            model.info["warnings"] = list(model.info.get("warnings", [])) + lines
    return check


def _features(curve, z: np.ndarray) -> np.ndarray | None:
    """The columns a curve linear in its parameters is a combination of, at ``z`` (None for neural and
    symbolic curves): each basis function (coefficient vector e_k) evaluated through the curve itself."""
    from ..curves import BasisFittedCurve, LinearFittedCurve

    if isinstance(curve, BasisFittedCurve):
        return np.column_stack([BasisFittedCurve(curve.name, curve.argument, curve.domain, [b], [1.0])(z)
                                for b in curve.basis])
    if isinstance(curve, LinearFittedCurve):
        k = curve.coefficients.size
        return np.column_stack([LinearFittedCurve(curve.name, curve.argument, curve.domain, curve.representation,
                                                  np.eye(k)[j], center=curve.center, half_width=curve.half_width)(z)
                                for j in range(k)])
    return None


def _equation_parts(model, record, mask):
    """Per equation: its residual, its input and the arguments of the curves that enter it (masked).

    The residual is taken orthogonal to what the representations could still change
    (:func:`equation_columns`). An equation-error fit by least squares leaves such a residual
    already; a fit by output error leaves in it the (small, but on thousands of samples visible)
    change of coefficients that output error makes, which is no misfit of the curves' shape."""
    r = np.asarray(model.force_residual(record), dtype=float)
    r = r.reshape(r.shape[0], -1)
    keep = np.asarray(mask, bool) if mask is not None and len(mask) == r.shape[0] else np.ones(r.shape[0], bool)
    D = model.template.design(record)
    parts = []
    for e in range(D["E"]):
        cols, F, curves = equation_columns(model, D, keep, e)
        X = np.column_stack(cols)
        re = r[keep, e] - X @ np.linalg.lstsq(X, r[keep, e], rcond=None)[0]
        parts.append((re, F, curves))
    return parts


def equation_columns(model, D: dict, keep: np.ndarray, e: int, *, used_only: bool = False):
    """``(columns, input, arguments)`` of equation ``e`` of the design ``D`` (masked by ``keep``): a
    constant, with a free gain the input, and the columns of the curves linear in their parameters
    (times their coefficients in the equation), what the representations could still change;
    ``used_only``: only the terms a sparse fit kept (nonzero coefficients)."""
    n = D["n"]
    rows = slice(e * n, (e + 1) * n)
    mults = {c: np.asarray(D["mult"][c], dtype=float)[rows] for c in D["args"]}
    curves = {c: np.asarray(z, dtype=float)[keep] for c, z in D["args"].items() if np.any(mults[c] != 0)}
    F = np.asarray(D["F"], dtype=float)[rows][keep]
    cols = [np.ones(int(keep.sum()))] + ([F] if getattr(model.template, "free_gain", False) else [])
    for c, z in curves.items():
        phi = _features(model.curves[c], z)
        if phi is None:
            continue
        if used_only:
            used = np.asarray(getattr(model.curves[c], "coefficients", np.ones(phi.shape[1])), dtype=float) != 0
            phi = phi[:, used] if used.size == phi.shape[1] else phi
        cols.extend((phi * mults[c][keep][:, None]).T)
    return cols, F, curves


def _prior(model, curve: str) -> str | None:
    sym = ((model.info.get("settings") or {}).get("symmetry") or {}).get(curve)
    return str(sym) if sym and str(sym) not in ("none", "None") else None


def _residual_warning(model, test: dict, level: float) -> str:
    """One line for a failed residual test: the curve (or input), the test, the likely cause and the fix."""
    where = f" of equation {test['equation']}" if test.get("equations", 1) > 1 else ""
    p = f"p = {test['p_value']:.2g} < {level:.2g}"
    if test["test"] == "binned":
        curve, arg = test["curve"], test["argument"]
        prior = _prior(model, curve)
        fix = (f"its prior ({prior}) is wrong for this record -- try --sym none or --sym auto; or " if prior else "")
        return (f"self-check: the residual{where} is a function of {arg}, the argument of {curve} (binned test: "
                f"the residual's means in {test['bins']} quantile bins of {arg} differ, {p}); {curve} (or a curve "
                f"whose argument moves with {arg} along the record) misses a shape of its law: {fix}the curve's shape is one its representation cannot take -- try a more "
                "flexible one (--method nn-cc, a larger --basis or poly-cc degree)")
    if test["test"] == "input":
        return (f"self-check: the residual{where} is correlated with the input F (cross-correlation at lag "
                f"{test['at_lag']}, {p}): a term of the input's dynamics is missing or the gain is wrong -- "
                "run `charcurves select`, write the term into --equation, or learn the gain (--free-gain)")
    return (f"self-check: the residual{where} is not white (Ljung-Box over {test['dof']} lags, {p}), though the "
            "record's derivatives are measured: dynamics the equation does not hold (a missing term or state) or "
            "coloured noise on the measured columns -- run `charcurves select` or write the term into --equation")


def residual_check(model, record, mask=None, *, white_expected: bool, level: float = RESIDUAL_LEVEL,
                   floors: list[float] | None = None) -> dict:
    """The residual tests of each equation of ``model`` on ``record`` (the prepared record of the fit,
    sticking samples left out by ``mask``): the binned test against each curve's argument and, with
    ``white_expected`` (equation error on the record's own derivative columns, where a correct model
    leaves the white noise of the measured columns), whiteness and the cross-correlation with the
    input (when it varies). The residual is the equation residual of the final curves. On estimated
    derivatives (a fit by output error, or equation error on a differentiator's estimates) it is
    correlated over neighbouring samples, which the binned test allows for (its AR model), and it
    holds the differentiator's bias, a filtered function of the trajectory: that is not white and
    correlates with the input at the filter's lags (the correct Duffing model, 30 dB on x: p = 1e-4
    to 1e-3), so whiteness and the cross-correlation are not applied there. ``level``: the chance that a well-specified fit
    fails any of its tests.

    Returns ``{"level", "per_test_level", "tests", "whiteness", "passed", "warnings"}``: each test
    with its p-value, ``effect_over_floor`` (the variance of the structure it found -- the bin means'
    spread, the input's share, the predictable share -- over the equation's noise floor ``floors``)
    and ``passed``: p at least ``level`` over the number of tests, or an effect below
    :data:`RESIDUAL_MIN_EFFECT`.

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.fitting import residual_check
    >>> from charcurves.systems import get_system
    >>> record = cc.corrupt(get_system("duffing").simulate(), 20, on="force", seed=1)
    >>> model = cc.fit(record, method="parametric", basis="f1=z; f2=z")  # f2 without its cubic
    >>> check = residual_check(model, record, white_expected=True, floors=model.info["self_check"]["noise_floor"])
    >>> check["passed"], [t["test"] for t in check["tests"] if not t["passed"]]
    (False, ['whiteness'])
    """
    parts = _equation_parts(model, record, mask)
    noisy_F = getattr(record, "F", None)
    tests: list[dict] = []
    E = len(parts)
    for e, (r, F, curves) in enumerate(parts):
        base = {"equation": e + 1, "equations": E}
        if r.size < 4 * RESIDUAL_BINS:
            continue
        var = float(np.var(r))
        if white_expected:
            w = whiteness(r)
            rho = autocorrelation(r, w["dof"])[1:]
            tests.append({**base, "test": "whiteness", **w, "effect": var * float(np.sum(rho ** 2))})
        if white_expected and np.ptp(F) > 1e-12 * max(1.0, float(np.max(np.abs(F)))):
            s2 = noise_variance(F) if noisy_F is not None else 0.0
            s2 = s2 if s2 > CLEAN_COLUMN * float(np.var(F)) else 0.0
            c = input_correlation(r, F, input_noise=s2, gain=float(model.gain))
            tests.append({**base, "test": "input", **c, "effect": var * c["max_abs_z"] ** 2 / r.size})
        bins = int(max(3, min(RESIDUAL_BINS, r.size // 50)))
        varying = {c: z for c, z in curves.items() if np.ptp(z) > 0}
        for c, res in (binned_tests(r, varying, bins=bins) if varying else {}).items():
            res["z_scores"] = [round(v, 3) for v in res["z_scores"]]
            idx, counts = bin_indices(varying[c], bins)
            means = np.bincount(idx, weights=r) / counts
            between = float(np.sum(counts * (means - np.mean(r)) ** 2) / r.size)
            tests.append({**base, "test": "binned", "curve": c, "argument": model.template.arguments[c], **res,
                          "effect": between})
    each = level / max(len(tests), 1)
    for t in tests:
        size = t.pop("effect")
        floor = floors[min(t["equation"], len(floors)) - 1] if floors else 0.0
        t["effect_over_floor"] = size / floor if floor > 0 else float("inf")
        # significant, and large enough to matter: a clean record's residual (a differentiator's bias,
        # round-off) has structure the tests see, but far below the floor's noise-free part
        t["passed"] = bool(t["p_value"] >= each or t["effect_over_floor"] < RESIDUAL_MIN_EFFECT)
    warnings = [_residual_warning(model, t, each) for t in tests if not t["passed"]]
    for t in tests:
        t.pop("equations")
    return {"level": level, "per_test_level": each, "tests": tests,
            "whiteness": "applied" if white_expected else
            "not applied (nor the cross-correlation with the input): the residual of estimated derivatives is "
            "correlated by nature and holds the differentiator's bias",
            "passed": bool(all(t["passed"] for t in tests)), "warnings": warnings}


def residual_test_rows(model) -> list[tuple[str, str, str, str]]:
    """The residual tests of a fitted model as rows ``(test, what, statistic, verdict)`` for the
    summary and the report (empty when the model has none, e.g. fitted by an older charcurves).

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.fitting import residual_test_rows
    >>> from charcurves.systems import get_system
    >>> record = cc.corrupt(get_system("duffing").simulate(), 20, on="force", seed=1)
    >>> residual_test_rows(cc.fit(record, method="parametric", basis="f1=z; f2=z, z**3"))[2]
    ('binned', "residual against x' (argument of f1), 10 bins", 'F = 1.54 with 9 degrees of freedom', 'p = 0.13, passed')
    """
    rt = (model.info.get("self_check") or {}).get("residual_tests")
    if not rt:
        return []
    rows = []
    for t in rt["tests"]:
        eq = f"equation {t['equation']}: " if any(u["equation"] > 1 for u in rt["tests"]) else ""
        if t["test"] == "binned":
            what = f"{eq}residual against {t['argument']} (argument of {t['curve']}), {t['bins']} bins"
            stat = f"F = {t['statistic'] / max(t['dof'], 1):.3g} with {t['dof']} degrees of freedom"
        elif t["test"] == "input":
            what = f"{eq}cross-correlation with F, lags 1..{t['lags'] // 2} both ways"
            stat = f"max |z| = {t['max_abs_z']:.3g} at lag {t['at_lag']}"
        else:
            what = f"{eq}whiteness over lags 1..{t['dof']}"
            stat = f"Ljung-Box Q = {t['statistic']:.3g}"
        verdict = f"p = {t['p_value']:.2g}, " + ("passed" if t["passed"] else f"FAILED (< {rt['per_test_level']:.2g})")
        rows.append((t["test"], what, stat, verdict))
    return rows
