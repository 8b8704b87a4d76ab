"""Symmetry detection: test the parity of unconstrained curves and propose priors.

For each curve of an unconstrained fit (NN-CC) and an ensemble around it (wild residual
bootstrap, see :mod:`._bands`), the odd and even defects on the symmetric part of the range,

    odd:  o(z) = f(z) + f(-z) [- 2 f(0) where the equation's free constant can absorb a shift]
    even: e(z) = f(z) - f(-z),

are compared with their uncertainty, ``t(z) = defect(z) / sqrt(sd(z)^2 + (tol * scale)^2)``:
``sd`` is the ensemble's spread of the defect and ``tol * scale`` an approximation floor (1 %
of the curve's RMS size about f(0) where the constant can shift) so that noise-free data do not turn a network's tiny asymmetry into a
rejection. A parity is *consistent* when the RMS of ``t`` over the grid is at most
``threshold``. A curve gets a prior only when exactly one parity is consistent: a curve that
fits both (nearly constant) or neither gets none, and so does one whose argument covers only
one side of 0 (nothing to compare).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .._errors import CharCurvesError, ConfigError
from ._ensemble import fit_ensemble
from ._methods import METHODS

__all__ = ["parity_tests", "detect_parity", "fit_many_auto", "PARITY_THRESHOLD", "AUTO_MEMBERS",
           "DEFAULT_DETECTOR"]

#: RMS of the normalised defect up to which a parity counts as consistent with the data
PARITY_THRESHOLD = 3.0
#: relative approximation floor of the defects (fraction of the curve's RMS size)
APPROX_TOL = 0.01
#: the symmetric part must cover at least this fraction of the larger side to test parity
MIN_SYMMETRIC_FRACTION = 0.25
#: ensemble size of ``symmetry="auto"``
AUTO_MEMBERS = 8
#: the detector of the default fit (no method, no symmetry asked): poly-cc curves by equation error,
#: linear least squares, about 0.1 s per record against 1.6-3 s of the fit itself
DEFAULT_DETECTOR = "poly-cc"

#: curves whose constant the equation's free constant can absorb, per family (odd up to a shift)
_SHIFTABLE = {"separable": ("f1", "f2"), "position-damping": ("f2",), "first-order": ("f1",),
              "two-dof": ("f1", "f2", "f3", "f4")}


def parity_tests(ensemble, *, threshold: float = PARITY_THRESHOLD, n_grid: int = 60,
                 shiftable: Sequence[str] | None = None) -> dict[str, dict]:
    """Odd/even statistics and the proposed prior of every curve of an ensemble.

    Parameters
    ----------
    ensemble : Ensemble
        From :func:`charcurves.selection.fit_ensemble` with an unconstrained method.
    threshold : float
        RMS normalised defect up to which a parity is consistent.
    n_grid : int
        Grid points on (0, m], m the symmetric half-width of the argument's range.
    shiftable : sequence of str, optional
        Curves tested for oddness up to a constant (default: by family).

    Returns
    -------
    dict
        ``{name: {"proposal", "odd_stat", "even_stat", "range", "symmetric_halfwidth", "reason"}}``

    Examples
    --------
    >>> from charcurves.data import corrupt
    >>> from charcurves.fitting import CharacteristicCurves, fit_ensemble, parity_tests
    >>> from charcurves.systems import get_system
    >>> record = corrupt(get_system("duffing").simulate(t_end=20.0, n_points=500), 20, seed=0)
    >>> tests = parity_tests(fit_ensemble(CharacteristicCurves.from_method(method="poly-cc"), record, 8))
    >>> {name: t["proposal"] for name, t in tests.items()}
    {'f1': 'odd', 'f2': 'odd'}
    """
    point = ensemble.point
    family = getattr(point.template, "family", "")
    if shiftable is None:
        shiftable = _SHIFTABLE.get(family, ())
    out = {}
    for name, curve in point.curves.items():
        lo, hi = (float(v) for v in curve.domain)
        entry: dict = {"range": [lo, hi], "odd_stat": None, "even_stat": None, "symmetric_halfwidth": 0.0}
        if lo >= 0.0 or hi <= 0.0:
            entry.update(proposal="none", reason=f"one-sided range [{lo:.4g}, {hi:.4g}] of {curve.argument}: "
                                                  "parity cannot be tested, none imposed")
            out[name] = entry
            continue
        m = min(-lo, hi)
        entry["symmetric_halfwidth"] = m
        if m < MIN_SYMMETRIC_FRACTION * max(-lo, hi):
            entry.update(proposal="none", reason=(
                f"nearly one-sided range [{lo:.4g}, {hi:.4g}] of {curve.argument}: the symmetric part "
                f"[-{m:.3g}, {m:.3g}] is under {MIN_SYMMETRIC_FRACTION:.0%} of the range, none imposed"))
            out[name] = entry
            continue
        z = np.linspace(m / n_grid, m, n_grid)
        zero = np.zeros(1)

        def defects(f):
            fz, fm = np.asarray(f(z), dtype=float), np.asarray(f(-z), dtype=float)
            shift = 2.0 * float(np.asarray(f(zero), dtype=float)[0]) if name in shiftable else 0.0
            return fz + fm - shift, fz - fm, fz

        odd0, even0, f0 = defects(curve)
        member = [defects(mc.curves[name]) for mc in ensemble.members]
        sd_odd = np.std([d[0] for d in member], axis=0, ddof=1)
        sd_even = np.std([d[1] for d in member], axis=0, ddof=1)
        fm0 = np.asarray(curve(-z), dtype=float)
        # the size of the curve's variation: a constant the equation absorbs (one that another curve's
        # anchor outside its data puts here, as f2(0) = 0 of a record resting at x = 10 does) is not a size
        c0 = float(np.asarray(curve(zero), dtype=float)[0]) if name in shiftable else 0.0
        scale = float(np.sqrt(np.mean((np.concatenate([f0, fm0]) - c0) ** 2)))
        floor = APPROX_TOL * max(scale, 1e-300)
        odd_stat = float(np.sqrt(np.mean(odd0**2 / (sd_odd**2 + floor**2))))
        even_stat = float(np.sqrt(np.mean(even0**2 / (sd_even**2 + floor**2))))
        odd_ok, even_ok = odd_stat <= threshold, even_stat <= threshold
        if odd_ok and not even_ok:
            proposal, reason = "odd", "odd defect within its uncertainty, even defect not"
        elif even_ok and not odd_ok:
            proposal, reason = "even", "even defect within its uncertainty, odd defect not"
        elif odd_ok and even_ok:
            proposal, reason = "none", "both parities fit (the curve is nearly constant here): none imposed"
        else:
            proposal, reason = "none", "the data contradict both parities"
        entry.update(proposal=proposal, reason=reason, odd_stat=odd_stat, even_stat=even_stat,
                     threshold=float(threshold))
        out[name] = entry
    return out


def detect_parity(record, estimator, *, n_members: int = AUTO_MEMBERS, threshold: float = PARITY_THRESHOLD,
                  random_state: int = 0, method: str = "nn-cc", objective=None,
                  block: int | None = None) -> dict[str, dict]:
    """:func:`~charcurves.fitting.detect_symmetry` with the settings of ``estimator`` (its class builds
    the tested fits, so this module needs no estimator class of its own); ``block``: the bootstrap's
    (:func:`~charcurves.fitting.bootstrap_records`, default the residual's correlation length)."""
    params = estimator.flat_params()
    params.update(method=method, symmetry=None, random_state=int(random_state), progress=None, basis=None,
                  post_sr=None)
    if METHODS[method]["representation"] != "neural":  # a jump or a network shape belongs to neural curves
        params.update(jump="auto", hidden=None, activation=None)
    if objective is not None:
        params.update(objective=objective)
    try:
        ensemble = fit_ensemble(type(estimator).from_method(**params), record, n_members, kind="bootstrap",
                                block=block)
    except ConfigError as exc:
        # the residual bootstrap needs each equation's own forcing column; otherwise seeds only
        if "kind='seeds'" not in str(exc):
            raise
        ensemble = fit_ensemble(type(estimator).from_method(**params), record, n_members, kind="seeds")
    return parity_tests(ensemble, threshold=threshold)


def _method_for(method: str, any_parity: bool) -> str:
    """The method that carries the detected priors (or none) closest to the one asked for."""
    spec = METHODS[method]
    if spec.get("allows_symmetry"):
        return method
    if spec["symmetry"] and not any_parity:
        plain = method.replace("+sym", "")
        if plain not in METHODS:
            raise ConfigError(f"no symmetry was detected and {method!r} needs one; use --method "
                              f"{method.replace('+sym', '').replace('+post-sr', '')} with --sym auto")
        return plain
    if not spec["symmetry"] and any_parity:
        base, _, rest = method.partition("+")
        with_sym = f"{base}+sym" + (f"+{rest}" if rest else "")
        return with_sym if with_sym in METHODS else method
    return method


def fit_many_auto(estimator, trajectories, seeds=None, *, default: bool = False):
    """``CharacteristicCurves.fit_many`` with ``symmetry="auto"``: detect, then fit with the priors.

    A curve gets a parity only when every record proposes it. The decision and its statistics
    are stored in each model's ``info["symmetry_auto"]`` (and so in result.json). ``default``: the
    estimator asked for no method and no prior (``CharacteristicCurves()``, a plain ``charcurves
    fit``): the parity is tested by :data:`DEFAULT_DETECTOR` by equation error (about 0.1 s), and
    a record it cannot test (an error of the detector) gets no prior, with the reason.

    Examples
    --------
    >>> from charcurves.data import corrupt
    >>> from charcurves.fitting import CharacteristicCurves, fit_many_auto
    >>> from charcurves.systems import get_system
    >>> record = corrupt(get_system("duffing").simulate(t_end=20.0, n_points=500), 20, seed=0)
    >>> [model] = fit_many_auto(CharacteristicCurves.from_method(method="poly-cc", symmetry="auto"), [record])
    >>> model.info["symmetry_auto"]["applied"], model.method
    ({'f1': 'odd', 'f2': 'odd'}, 'poly-cc')
    """
    if estimator.method_name() not in METHODS:
        raise ConfigError(f"symmetry='auto' works with the paper's method presets (method=...); for a composed "
                          f"template set each curve's symmetry, got method {estimator.method_name()!r}")
    spec = METHODS[estimator.method_name()]
    takes_prior = spec["symmetry"] or spec.get("allows_symmetry") or \
        f"{estimator.method_name().partition('+')[0]}+sym" in METHODS
    if not takes_prior:
        raise ConfigError(f"--sym auto needs a method that takes a symmetry prior (nn-cc, nn-cc+sym, poly-cc, "
                          f"sindy-cc...), not {estimator.method_name()!r}")
    # poly-cc fits test poly-cc curves (fast); every other method tests unconstrained NN-CC curves
    detector = "poly-cc" if spec["representation"] == "poly" or default else "nn-cc"
    try:
        tests = [detect_parity(tr, estimator, random_state=int(estimator.random_state), method=detector,
                                 objective="equation-error" if default else None)
                 for tr in trajectories]
    except CharCurvesError as exc:
        if not default:
            raise
        # the fit itself names what is wrong with the record, in its own method's words
        tests = [{name: {"proposal": "none", "reason": f"not tested: {str(exc).splitlines()[0][:200]}"}
                  for name in estimator.resolve()[1].curve_names}]
    names = list(tests[0])
    applied = {}
    for name in names:
        proposals = {t[name]["proposal"] for t in tests}
        applied[name] = proposals.pop() if len(proposals) == 1 else "none"
    method = _method_for(estimator.method_name(), any(v != "none" for v in applied.values()))
    params = estimator.flat_params()
    params.update(method=method, symmetry=dict(applied))
    models = type(estimator).from_method(**params).fit_many(trajectories, seeds=seeds)
    report = {
        "mode": "default (no method, no prior asked: tested)" if default else "auto",
        "applied": applied,
        "method": method,
        "requested_method": estimator.method_name(),
        "detection": {"method": detector, "members": AUTO_MEMBERS,
                      "kind": "bootstrap (training seeds where an equation has no forcing column of its own)",
                      "threshold": PARITY_THRESHOLD, "approximation_tolerance": APPROX_TOL},
        "tests": tests[0] if len(tests) == 1 else tests,
    }
    for m in models:
        m.info["symmetry_auto"] = report
    return models


def resolved_estimator(estimator, model):
    """The estimator that ``symmetry="auto"`` ended up fitting with (itself when not auto).

    Examples
    --------
    >>> from charcurves.data import corrupt
    >>> from charcurves.fitting import CharacteristicCurves, resolved_estimator
    >>> from charcurves.systems import get_system
    >>> estimator = CharacteristicCurves.from_method("poly-cc", symmetry="auto")
    >>> model = estimator.fit(corrupt(get_system("duffing").simulate(t_end=20.0, n_points=500), 20, seed=0)).model_
    >>> resolved_estimator(estimator, model)
    CharacteristicCurves.from_method('poly-cc', symmetry={'f1': 'odd', 'f2': 'odd'})
    """
    report = model.info.get("symmetry_auto") if isinstance(model.info, dict) else None
    auto = isinstance(estimator.symmetry, str) and estimator.symmetry.strip().lower() == "auto"
    if not (auto or estimator.tests_priors()) or not report:
        return estimator
    params = estimator.flat_params()
    params.update(method=report["method"], symmetry=dict(report["applied"]))
    return type(estimator).from_method(**params)


