"""SINDy, SINDy-CC and SINDy-CC+sym on pysindy 2.x (the paper's methods vi-viii).

All three regress the state ``X = [x, x']`` with the derivatives given explicitly,
``x_dot = [x', x'']`` (no numerical differentiation), and the forcing as control input ``u = F``.
The curves are read off the ``x''`` equation:
``x'' = k u + sum_j a_j x'^j + sum_j b_j x^j``  =>  ``f1 = -sum a_j z^j``, ``f2 = -sum b_j z^j``, ``g = k``.

* ``"sindy"``: ``GeneralizedLibrary([PolynomialLibrary(degree=10, include_interaction=False,
  include_bias=False), IdentityLibrary()])`` and ``STLSQ(threshold=1e-4)``; the gain ``k`` is free.
* ``"sindy-cc"``: the same library and ``ConstrainedSR3`` (l0, nu = 1) with the equality constraint
  ``k = g`` (the template's fixed gain, 1 by default) on the u coefficient of the x'' equation.
  pysindy 1.7.5 (the paper's) took an l0 *threshold* (1e-5); pysindy 2.x takes the weight
  ``reg_weight_lam``, and the prox of l0 thresholds at ``sqrt(2 lam nu)``, so the threshold maps to
  ``lam = threshold^2 / (2 nu)`` (``ConstrainedSR3.calculate_l0_weight``): 1e-5 <-> 5e-11.
* ``"sindy-cc+sym"``: one library per curve: odd powers ``z, z^3, ..., z^9`` (symmetry "odd"),
  even powers ``z^2, ..., z^10`` ("even") or the full polynomial library ("none"), plus the identity
  on u; same ConstrainedSR3.

The first equation (``d x / dt = x'``) is fitted along with the second, as in the scripts; it is
trivially ``x' = 1 * x'`` whenever ``x'`` is a library feature (always, except with an "even" prior
on f1) and plays no part in the curves (the optimizers treat the two equations separately, and the
constraint touches only the x'' equation). Its fit is reported in ``info["x_equation"]``.
"""

from __future__ import annotations

import re
import time
import warnings
from typing import Any

import numpy as np

from .._errors import ConfigError
from ..curves._fitted import BasisFittedCurve
from ..data._trajectory import Trajectory
from ..templates._separable import SeparableTemplate, apply_gauge, sticking_mask
from ._model import FittedModel

__all__ = ["fit_sindy", "SINDY_METHODS", "l0_weight"]

#: Methods this fitter serves (+post-sr variants are distilled afterwards by the estimator).
SINDY_METHODS = ("sindy", "sindy-cc", "sindy-cc+sym", "sindy-cc+sym+post-sr")

_INSTALL = "pip install 'charcurves[sindy]'"
_OPTIONS = ("threshold", "degree", "max_iter", "alpha", "nu", "tol", "exclude_sticking", "stick_tol")
_NAMES = ("x", "v", "u")  # state x, state x' and the input, as pysindy sees them
_VAR_OF = {"f1": "v", "f2": "x"}


def l0_weight(threshold: float, nu: float = 1.0) -> float:
    """pysindy 1.x l0 threshold -> pysindy 2.x ``reg_weight_lam`` (prox threshold sqrt(2 lam nu))."""
    return threshold**2 / (2.0 * nu)


def _import_pysindy(constrained: bool):
    try:
        import pysindy as ps
    except ImportError:
        raise ConfigError(f"the SINDy methods need pysindy; install it with {_INSTALL}") from None
    if constrained:
        try:
            import cvxpy  # noqa: F401  (pysindy exports ConstrainedSR3 only when cvxpy imports)
        except ImportError:
            raise ConfigError(
                f"sindy-cc needs cvxpy for pysindy's ConstrainedSR3; install both with {_INSTALL}"
            ) from None
        if not hasattr(ps, "ConstrainedSR3"):
            raise ConfigError(f"this pysindy has no ConstrainedSR3; install pysindy>=2 and cvxpy with {_INSTALL}")
    return ps


def _check_options(options: dict[str, Any], constrained: bool) -> dict[str, Any]:
    unknown = sorted(set(options) - set(_OPTIONS))
    if unknown:
        raise ConfigError(f"unknown SINDy option(s) {unknown}; valid: {', '.join(_OPTIONS)}")
    out = {
        "threshold": options.get("threshold", 1e-5 if constrained else 1e-4),
        "degree": options.get("degree", 10),
        "max_iter": options.get("max_iter", 10000),
        "alpha": options.get("alpha", 0.05),
        "nu": options.get("nu", 1.0),
        "tol": options.get("tol", 1e-5),
        "exclude_sticking": bool(options.get("exclude_sticking", True)),
        "stick_tol": options.get("stick_tol"),
    }
    for key in ("threshold", "alpha", "nu", "tol"):
        v = out[key]
        if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) or not np.isfinite(v) \
                or v < 0 or (key in ("nu", "tol") and v == 0):
            raise ConfigError(f"SINDy option {key} must be a {'positive' if key in ('nu', 'tol') else 'non-negative'}"
                              f" number, got {v!r}")
        out[key] = float(v)
    for key, lo, hi in (("degree", 1, 20), ("max_iter", 1, 10**7)):
        v = out[key]
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not lo <= int(v) <= hi:
            raise ConfigError(f"SINDy option {key} must be an integer from {lo} to {hi}, got {v!r}")
        out[key] = int(v)
    return out


def _power_function(k: int):
    # one positional argument only: CustomLibrary reads a function's arity from its signature
    def f(z):
        return z**k

    return f


def _power_name(k: int):
    def name(s):
        return s if k == 1 else f"{s}^{k}"

    return name


def _parity_library(ps, powers: list[int]):
    return ps.CustomLibrary(library_functions=[_power_function(k) for k in powers],
                            function_names=[_power_name(k) for k in powers])


def _library(ps, symmetry: dict[str, str], degree: int, use_sym: bool):
    """The feature library and a description of it."""
    if not use_sym or all(s == "none" for s in symmetry.values()):
        poly = ps.PolynomialLibrary(degree=degree, include_interaction=False, include_bias=False)
        lib = ps.GeneralizedLibrary([poly, ps.IdentityLibrary()], inputs_per_library=[[0, 1], [2]])
        return lib, f"polynomial degree {degree} in x, x' (no interactions, no bias) + identity(u)"
    libs, desc = [], []
    for name, idx in (("f2", 0), ("f1", 1)):
        s = symmetry.get(name, "none")
        if s == "odd":
            p = list(range(1, degree + 1, 2))
        elif s == "even":
            p = list(range(2, degree + 1, 2))
        else:
            p = None
        if p is None:
            libs.append(ps.PolynomialLibrary(degree=degree, include_interaction=False, include_bias=False))
            desc.append(f"{_NAMES[idx]}: powers 1..{degree}")
        else:
            if not p:
                raise ConfigError(f"an {s} library of degree {degree} is empty; raise options['degree']")
            libs.append(_parity_library(ps, p))
            desc.append(f"{_NAMES[idx]}: {s} powers {p}")
    lib = ps.GeneralizedLibrary([*libs, ps.IdentityLibrary()], inputs_per_library=[[0], [1], [2]])
    return lib, "; ".join(desc) + "; identity(u)"


_FEATURE = re.compile(r"^(x|v)(?:\^(\d+))?$")


def _parse_features(names: list[str]) -> list[tuple[str, int]]:
    out = []
    for n in names:
        n = n.strip()
        if n == "u":
            out.append(("u", 1))
            continue
        m = _FEATURE.match(n)
        if not m:
            raise RuntimeError(f"unexpected SINDy feature {n!r}; the library should hold powers of x, x' and u")
        out.append((m.group(1), int(m.group(2) or 1)))
    return out


def _basis_curve(name: str, argument: str, domain, terms: dict[int, float]) -> BasisFittedCurve:
    active = sorted(k for k, c in terms.items() if c != 0.0)
    if not active:
        return BasisFittedCurve(name, argument, domain, ["z"], [0.0])
    basis = ["z" if k == 1 else f"z**{k}" for k in active]
    return BasisFittedCurve(name, argument, domain, basis, [terms[k] for k in active])


def fit_sindy(traj: Trajectory, template: SeparableTemplate, *, symmetry: dict[str, str] | None = None,
              options: dict | None = None, sr_options: dict | None = None, random_state: int = 0,
              method: str = "sindy") -> FittedModel:
    """SINDy / SINDy-CC / SINDy-CC+sym with pysindy's libraries and optimizers.

    Parameters
    ----------
    traj : Trajectory with derivatives (v, a)
    template : SeparableTemplate
        "sindy" needs ``free_gain=True`` (k is identified); the CC variants need a fixed gain
        (the constraint sets the u coefficient to ``template.gain``).
    symmetry : dict, optional
        Per-curve parity for "sindy-cc+sym" ("odd": z, z^3, ..., "even": z^2, z^4, ...,
        "none": all powers); ignored by the methods without +sym (the estimator refuses it there).
    options : dict, optional
        ``threshold`` (1e-4 STLSQ for sindy, 1e-5 l0 threshold for the CC variants, mapped to
        ``reg_weight_lam = threshold^2 / (2 nu)``), ``degree`` (10), ``max_iter`` (10000),
        ``alpha`` (STLSQ ridge, 0.05), ``nu`` (SR3 relaxation, 1), ``tol`` (SR3, 1e-5),
        ``exclude_sticking`` (True), ``stick_tol`` (None: exact zeros of x').
    method : str
        One of :data:`SINDY_METHODS`.
    """
    t0 = time.perf_counter()
    if method not in SINDY_METHODS:
        raise ConfigError(f"fit_sindy serves {', '.join(SINDY_METHODS)}, not {method!r}")
    constrained = method != "sindy"
    use_sym = "+sym" in method
    if constrained and template.free_gain:
        raise ConfigError(f"{method} fixes the gain; use sindy for a free gain")
    if not constrained and not template.free_gain:
        raise ConfigError("sindy identifies the gain k (free_gain); use sindy-cc for a fixed gain")
    opts = _check_options(dict(options or {}), constrained)
    ps = _import_pysindy(constrained)
    sym = {n: "none" for n in template.curve_names}
    sym.update(symmetry or {})
    for n, s in sym.items():
        if s not in ("none", "odd", "even"):
            raise ConfigError(f"unknown symmetry {s!r} for {n}; choose none, odd or even")

    template.check_excitation(traj)
    args = template.arguments_of(traj)
    mask = (~sticking_mask(traj, rel_tol=opts["stick_tol"]) if opts["exclude_sticking"]
            else np.ones(traj.n_samples, bool))
    x, v, a, F = (np.asarray(c, dtype=float)[mask] for c in (traj.x, traj.v, traj.a, traj.F))
    t = np.asarray(traj.t, dtype=float)[mask]
    X = np.column_stack([x, v])
    X_dot = np.column_stack([v, a])
    U = F[:, None]

    library, lib_desc = _library(ps, sym if use_sym else {}, opts["degree"], use_sym)
    # the library's size is known only after fitting; build the optimizer around a probe transform
    library.fit(np.column_stack([X, U]))
    n_features = int(library.n_output_features_)
    feats = _parse_features(library.get_feature_names(list(_NAMES)))
    u_idx = [i for i, f in enumerate(feats) if f[0] == "u"]
    if len(u_idx) != 1:
        raise RuntimeError(f"the SINDy library has {len(u_idx)} input features; expected one")
    u_idx = u_idx[0]

    if constrained:
        lam = l0_weight(opts["threshold"], opts["nu"])
        C = np.zeros((1, n_features * 2))
        C[0, u_idx * 2 + 1] = 1.0  # "feature" order: feature-major, target-minor; target 1 = the x'' equation
        optimizer = ps.ConstrainedSR3(reg_weight_lam=lam, regularizer="l0", relax_coeff_nu=opts["nu"],
                                      tol=opts["tol"], max_iter=opts["max_iter"], constraint_lhs=C,
                                      constraint_rhs=np.array([template.gain]), constraint_order="feature",
                                      equality_constraints=True)
        opt_desc = {"optimizer": "ConstrainedSR3", "regularizer": "l0", "threshold": opts["threshold"],
                    "reg_weight_lam": lam, "nu": opts["nu"], "tol": opts["tol"], "max_iter": opts["max_iter"]}
    else:
        optimizer = ps.STLSQ(threshold=opts["threshold"], alpha=opts["alpha"], max_iter=opts["max_iter"])
        opt_desc = {"optimizer": "STLSQ", "threshold": opts["threshold"], "alpha": opts["alpha"],
                    "max_iter": opts["max_iter"]}

    model = ps.SINDy(optimizer=optimizer, feature_library=library)
    t_solve = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model.fit(X, t=t, x_dot=X_dot, u=U, feature_names=list(_NAMES))
    solve_seconds = time.perf_counter() - t_solve
    converged = not any("converge" in str(w.message).lower() for w in caught)
    other_warnings = sorted({str(w.message) for w in caught if "converge" not in str(w.message).lower()})

    names = model.get_feature_names()
    feats = _parse_features(names)
    coef = np.asarray(model.coefficients(), dtype=float)
    if coef.shape != (2, len(feats)):
        raise RuntimeError(f"unexpected SINDy coefficient shape {coef.shape}")
    xdd = coef[1]
    terms: dict[str, dict[int, float]] = {"f1": {}, "f2": {}}
    k_u = 0.0
    for (var, power), c in zip(feats, xdd):
        if var == "u":
            k_u = float(c)
        else:
            curve = "f1" if var == "v" else "f2"
            terms[curve][power] = terms[curve].get(power, 0.0) - float(c)
    gain = template.gain if constrained else k_u

    curves = {}
    for name in template.curve_names:
        z = args[name]
        curves[name] = _basis_curve(name, template.arguments[name], (float(z.min()), float(z.max())), terms[name])
    raw0 = {n: float(c.raw(np.array([0.0]))[0]) for n, c in curves.items()}
    pinned = {n: c.pinned_at_zero for n, c in curves.items()}
    shifts, offset = apply_gauge(raw0, pinned, 0.0, template.gauge, template.curve_names)
    for n, c in curves.items():
        c.shift = shifts[n]

    a_hat = gain * F - curves["f1"](v) - curves["f2"](x) - offset
    loss = float(np.mean((a - a_hat) ** 2))
    x_eq = " + ".join(f"{c:.6g} {n}" for n, c in zip(names, coef[0]) if c != 0.0) or "0"
    x_eq_resid = float(np.sqrt(np.mean((model.predict(X, u=U)[:, 0] - v) ** 2)) / max(np.sqrt(np.mean(v**2)), 1e-300))
    history = getattr(optimizer, "history_", None)
    info = {
        **opt_desc,
        "library": lib_desc,
        "library_size": n_features,
        "feature_names": list(names),
        "n_active_terms": int(np.count_nonzero(np.delete(xdd, u_idx))),
        "active_terms": [n for i, (n, c) in enumerate(zip(names, xdd)) if c != 0.0 and i != u_idx],
        "u_coefficient": k_u,
        "gain_free": not constrained,
        "converged": converged,
        "iterations": None if history is None else max(len(history) - 1, 0),
        "x_equation": x_eq,
        "x_equation_relative_rmse": x_eq_resid,
        "warnings": other_warnings,
        "solver_seconds": solve_seconds,
        "pysindy_version": getattr(ps, "__version__", "unknown"),
        "symmetry": dict(sym) if use_sym else {n: "none" for n in template.curve_names},
        "n_samples": traj.n_samples,
        "n_fitted_samples": int(mask.sum()),
        "train_seconds": time.perf_counter() - t0,
    }
    return FittedModel(template, method, curves, gain, offset, loss, info)
