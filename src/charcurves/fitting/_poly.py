"""Poly-CC: every curve a degree-N polynomial of its rescaled argument, all fitted in one least squares.

The paper's Poly-CC (method v): ``f_i(z) ~ sum_j c_ij s^j`` with ``s`` the curve's argument mapped
onto a reference interval ("domain rescaling"). Here:

* the default map sends each curve's training range ``[lo, hi]`` onto ``[-1, 1]``
  (``s = (z - c) / h``, ``c = (lo + hi) / 2``, ``h = (hi - lo) / 2``) and the columns are the
  Chebyshev polynomials ``T_1(s) ... T_N(s)`` (the same span as ``s ... s^N``, better conditioned);
* ``options["rescaling"] = "scripts"`` reproduces the authors' scripts: ``A0 = (max|z| + min|z|)/2``,
  ``A1 = (max|z| - min|z|)/2`` from *absolute* values (which maps the range to about ``[-3, 1]``)
  with plain powers of ``s``;
* the two curves' constant columns are collinear, so one shared constant is fitted and the
  template's gauge (default ``f2(0) = 0``; the scripts' ``f1(0) = 0`` with ``gauge="f1"``) decides
  which curve carries it;
* a curve with an "odd"/"even" symmetry keeps only the odd/even powers of the *unmapped*
  argument (the map is then a pure scaling ``s = z / max|z|``, which preserves parity);
* the fitted polynomial is expanded into powers of ``z`` so that the curve's sympy expression is
  an ordinary polynomial; when the expansion does not reproduce the mapped polynomial to
  ``options["expand_tol"]`` (relative, default 1e-9) on the training range (far-from-zero ranges,
  where cancellation ruins the monomial form) the mapped form ``((z - c)/h)**k`` is stored instead.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from numpy.polynomial import chebyshev as _cheb
from numpy.polynomial import polynomial as _poly

from .._errors import ConfigError
from ..curves._fitted import BasisFittedCurve
from ..data._trajectory import Trajectory
from ..templates._separable import SeparableTemplate, apply_gauge, sticking_mask
from ._model import FittedModel

__all__ = ["fit_poly", "RESCALINGS", "POLY_BASES"]

#: Domain maps: "minmax" (training range -> [-1, 1]), "scripts" (the authors' |z|-based quirk),
#: "none" (s = z).
RESCALINGS = ("minmax", "scripts", "none")
#: Column functions of the mapped variable.
POLY_BASES = ("chebyshev", "power")

_OPTIONS = ("degree", "rescaling", "basis", "expand_tol", "exclude_sticking", "stick_tol", "constant")


def _check_options(options: dict[str, Any]) -> dict[str, Any]:
    unknown = sorted(set(options) - set(_OPTIONS))
    if unknown:
        raise ConfigError(f"unknown poly-cc option(s) {unknown}; valid: {', '.join(_OPTIONS)}")
    degree = options.get("degree", 10)
    if isinstance(degree, bool) or not isinstance(degree, (int, np.integer)) or not 1 <= int(degree) <= 30:
        raise ConfigError(f"poly-cc degree must be an integer from 1 to 30, got {degree!r}")
    rescaling = options.get("rescaling", "minmax")
    if rescaling not in RESCALINGS:
        raise ConfigError(f"unknown poly-cc rescaling {rescaling!r}; choose one of {', '.join(RESCALINGS)}")
    basis = options.get("basis", "power" if rescaling == "scripts" else "chebyshev")
    if basis not in POLY_BASES:
        raise ConfigError(f"unknown poly-cc basis {basis!r}; choose one of {', '.join(POLY_BASES)}")
    tol = float(options.get("expand_tol", 1e-9))
    if not tol > 0:
        raise ConfigError(f"expand_tol must be positive, got {tol}")
    return {"degree": int(degree), "rescaling": rescaling, "basis": basis, "expand_tol": tol,
            "exclude_sticking": bool(options.get("exclude_sticking", True)),
            "stick_tol": options.get("stick_tol"), "constant": bool(options.get("constant", True))}


def _powers(degree: int, sym: str) -> list[int]:
    """Powers of the mapped variable used as columns (the constant is shared and not listed)."""
    if sym == "odd":
        return list(range(1, degree + 1, 2))
    if sym == "even":
        return list(range(2, degree + 1, 2))
    return list(range(1, degree + 1))


def _mapping(z: np.ndarray, sym: str, rescaling: str) -> tuple[float, float]:
    """Centre c and half-width h of ``s = (z - c) / h``."""
    if rescaling == "none":
        return 0.0, 1.0
    if sym in ("odd", "even"):  # parity in z survives only a pure scaling
        return 0.0, float(np.max(np.abs(z)))
    if rescaling == "scripts":
        az = np.abs(z)
        c, h = (az.max() + az.min()) / 2.0, (az.max() - az.min()) / 2.0
    else:
        c, h = (z.max() + z.min()) / 2.0, (z.max() - z.min()) / 2.0
    if not h > 0:
        h = max(abs(float(c)), 1.0)  # degenerate (constant) argument: check_excitation refuses it anyway
    return float(c), float(h)


def _column(s: np.ndarray, k: int, basis: str) -> np.ndarray:
    if basis == "chebyshev":
        e = np.zeros(k + 1)
        e[k] = 1.0
        return _cheb.chebval(s, e)
    return s**k


def _series_in_s(coef_by_power: dict[int, float], degree: int, basis: str) -> np.ndarray:
    """Power-series coefficients (index = power of s) of sum_k c_k B_k(s); the shared constant is not included."""
    c = np.zeros(degree + 1)
    for k, v in coef_by_power.items():
        c[k] = v
    return _cheb.cheb2poly(c) if basis == "chebyshev" else c


def _expand(series_s: np.ndarray, c: float, h: float) -> np.ndarray:
    """Coefficients in powers of z of sum_k a_k ((z - c)/h)^k."""
    out = np.zeros(1)
    lin = np.array([-c / h, 1.0 / h])  # s as a polynomial in z
    for a in series_s[::-1]:  # Horner in polynomial arithmetic
        out = _poly.polyadd(_poly.polymul(out, lin), [a])
    full = np.zeros(len(series_s))
    full[: min(len(out), len(full))] = out[: len(full)]
    return full


def _fmt(v: float) -> str:
    return repr(float(v))


def _build_curve(name: str, argument: str, domain: tuple[float, float], series_s: np.ndarray, c: float, h: float,
                 sym: str, expand_tol: float) -> tuple[BasisFittedCurve, str, float]:
    """A BasisFittedCurve for sum_k a_k s^k: expanded in powers of z when that is accurate, else mapped."""
    degree = len(series_s) - 1
    keep = [k for k in range(degree + 1)
            if not (sym == "odd" and k % 2 == 0) and not (sym == "even" and k % 2 == 1)]
    grid = np.linspace(domain[0], domain[1], 1000)
    mapped_vals = _poly.polyval((grid - c) / h, series_s)
    scale = max(float(np.max(np.abs(mapped_vals))), 1e-300)

    pz = _expand(series_s, c, h)
    # parity of the unmapped variable is exact when c = 0: drop the (zero) opposite powers
    basis = ["1" if k == 0 else ("z" if k == 1 else f"z**{k}") for k in keep]
    coefs = [pz[k] for k in keep]
    curve = BasisFittedCurve(name, argument, domain, basis, coefs)
    err = float(np.max(np.abs(curve.raw(grid) - mapped_vals))) / scale
    if err <= expand_tol:
        return curve, "power", err
    if c == 0.0:
        s_txt = f"(z/{_fmt(h)})"
    else:
        s_txt = f"((z - {_fmt(c)})/{_fmt(h)})" if c > 0 else f"((z + {_fmt(-c)})/{_fmt(h)})"
    basis = ["1" if k == 0 else (s_txt if k == 1 else f"{s_txt}**{k}") for k in keep]
    curve = BasisFittedCurve(name, argument, domain, basis, [series_s[k] for k in keep])
    err = float(np.max(np.abs(curve.raw(grid) - mapped_vals))) / scale
    return curve, "mapped", err


def fit_poly(traj: Trajectory, template: SeparableTemplate, *, symmetry: dict[str, str] | None = None,
             options: dict | None = None, sr_options: dict | None = None, random_state: int = 0,
             method: str = "poly-cc") -> FittedModel:
    """Poly-CC: one joint least-squares fit of a degree-N polynomial per curve (and the gain when free).

    Parameters
    ----------
    traj : Trajectory with derivatives (v, a)
    template : SeparableTemplate
        Its ``gauge`` picks the curve anchored at 0 (the scripts' convention is ``gauge="f1"``);
        with ``free_gain`` a ``-F`` column learns the gain.
    symmetry : dict, optional
        ``{"f1": "none"|"odd"|"even", ...}``; a parity keeps only those powers of the unmapped argument.
    options : dict, optional
        ``degree`` (10), ``rescaling`` ("minmax" | "scripts" | "none"), ``basis`` ("chebyshev";
        "power" for the scripts' rescaling), ``expand_tol`` (1e-9), ``exclude_sticking`` (True),
        ``stick_tol`` (None: exact zeros of x'), ``constant`` (True: fit the shared constant).
    sr_options, random_state : ignored (the fit is deterministic).

    Returns
    -------
    FittedModel with BasisFittedCurve curves (exact sympy polynomials).
    """
    t0 = time.perf_counter()
    opts = _check_options(dict(options or {}))
    names = template.curve_names
    sym = {n: "none" for n in names}
    sym.update(symmetry or {})
    for n, s in sym.items():
        if s not in ("none", "odd", "even"):
            raise ConfigError(f"unknown symmetry {s!r} for {n}; choose none, odd or even")
    template.check_excitation(traj)
    args = template.arguments_of(traj)
    mask = (~sticking_mask(traj, rel_tol=opts["stick_tol"]) if opts["exclude_sticking"]
            else np.ones(traj.n_samples, bool))
    degree, basis_kind = opts["degree"], opts["basis"]

    cols, owners, powers_of, maps = [], [], {}, {}
    for name in names:
        z = args[name]
        c, h = _mapping(z, sym[name], opts["rescaling"])
        maps[name] = (c, h)
        s = (z - c) / h
        powers_of[name] = _powers(degree, sym[name])
        for k in powers_of[name]:
            cols.append(_column(s, k, basis_kind))
            owners.append((name, k))
    if opts["constant"]:
        cols.append(np.ones(traj.n_samples))
        owners.append(("__constant", 0))
    target = template.gain * np.asarray(traj.F) - np.asarray(traj.a)
    force_side = template.free_gain and template.gain_on == "force"
    if template.free_gain:
        # the noisy side is the target (see SeparableTemplate.gain_on): F = h x'' + ... with g = 1/h
        cols.append(np.asarray(traj.a) if force_side else -np.asarray(traj.F))
        owners.append(("__gain", 0))
        target = np.asarray(traj.F) if force_side else -np.asarray(traj.a)
    A = np.column_stack(cols)[mask]
    y = target[mask]
    # equilibrate the columns (the scripts' map gives powers up to 3^10) before the solve
    norms = np.linalg.norm(A, axis=0)
    norms[norms == 0] = 1.0
    coef_scaled, *_ = np.linalg.lstsq(A / norms, y, rcond=None)
    coef = coef_scaled / norms
    if force_side:
        h = float(coef[[o == "__gain" for o, _ in owners].index(True)])
        coef = coef / h  # back to x'' + f1 + f2 + b = g F
        coef[[o == "__gain" for o, _ in owners].index(True)] = 1.0 / h
        resid = (A @ (coef * np.array([0.0 if o == "__gain" else 1.0 for o, _ in owners]))
                 + np.asarray(traj.a)[mask] - np.asarray(traj.F)[mask] / h)
    else:
        resid = A @ coef - y
    loss = float(np.mean(resid**2))

    gain = template.gain
    bias = 0.0
    by_curve: dict[str, dict[int, float]] = {n: {} for n in names}
    for (owner, k), v in zip(owners, coef):
        if owner == "__gain":
            gain = float(v)
        elif owner == "__constant":
            bias = float(v)
        else:
            by_curve[owner][k] = float(v)

    curves, forms, exp_err, series = {}, {}, {}, {}
    for name in names:
        z = args[name]
        domain = (float(z.min()), float(z.max()))
        series[name] = _series_in_s(by_curve[name], degree, basis_kind)
        c, h = maps[name]
        curves[name], forms[name], exp_err[name] = _build_curve(
            name, template.arguments[name], domain, series[name], c, h, sym[name], opts["expand_tol"])

    raw0 = {n: float(cv.raw(np.array([0.0]))[0]) for n, cv in curves.items()}
    pinned = {n: cv.pinned_at_zero for n, cv in curves.items()}
    shifts, offset = apply_gauge(raw0, pinned, bias, template.gauge, names)
    for n, cv in curves.items():
        cv.shift = shifts[n]

    info = {
        "degree": degree,
        "rescaling": opts["rescaling"],
        "basis": basis_kind,
        "symmetry": dict(sym),
        "mapping": {n: {"center": maps[n][0], "half_width": maps[n][1]} for n in names},
        "coefficients_in_s": {n: series[n].tolist() for n in names},
        "expression_form": forms,
        "expansion_error": exp_err,
        "constant": bias,
        "n_columns": int(A.shape[1]),
        "n_samples": traj.n_samples,
        "n_fitted_samples": int(mask.sum()),
        "condition_number": float(np.linalg.cond(A / norms)),
        "train_seconds": time.perf_counter() - t0,
    }
    return FittedModel(template, method, curves, gain, offset, loss, info)
