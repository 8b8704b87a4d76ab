"""Parametric: ordinary least squares on a user-given closed-form basis per curve (the paper's lower bound)."""

from __future__ import annotations

import time

import numpy as np

from .._errors import ConfigError
from ..curves._fitted import BasisFittedCurve, parse_basis_function
from ..data._trajectory import Trajectory
from ..templates._separable import SeparableTemplate, apply_gauge, sticking_mask
from ._model import FittedModel

__all__ = ["fit_basis", "DEFAULT_BASIS", "parse_basis_option"]

#: The paper's Parametric basis for Duffing: f1 = a1 x', f2 = a2 x + a3 x^3.
DEFAULT_BASIS = {"f1": ["z"], "f2": ["z", "z**3"]}


def parse_basis_option(text: str | dict | None, curve_names=("f1", "f2")) -> dict[str, list[str]]:
    """``"f1=z; f2=z, z**3"`` -> ``{"f1": ["z"], "f2": ["z", "z**3"]}`` (z is the curve's argument)."""
    if text is None:
        return {k: list(v) for k, v in DEFAULT_BASIS.items()}
    if isinstance(text, dict):
        out = {k: [str(b) for b in (v if isinstance(v, (list, tuple)) else [v])] for k, v in text.items()}
    else:
        out = {}
        for part in str(text).split(";"):
            if not part.strip():
                continue
            if "=" not in part:
                raise ConfigError(f"basis part {part.strip()!r} has no '='; write e.g. \"f1=z; f2=z, z**3\"")
            name, funcs = part.split("=", 1)
            out[name.strip()] = [f.strip() for f in funcs.split(",") if f.strip()]
    unknown = set(out) - set(curve_names)
    if unknown:
        raise ConfigError(f"basis given for unknown curve(s) {sorted(unknown)}; the curves are {', '.join(curve_names)}")
    missing = [c for c in curve_names if not out.get(c)]
    if missing:
        raise ConfigError(f"no basis functions for {missing}; write e.g. \"f1=z; f2=z, z**3\"")
    for funcs in out.values():
        for f in funcs:
            parse_basis_function(f)
    return out


def fit_basis(traj: Trajectory, template: SeparableTemplate, basis: dict[str, list[str]], *,
              method: str = "parametric", exclude_sticking: bool = True, stick_tol: float | None = None,
              constant: bool | None = None) -> FittedModel:
    """One joint least-squares fit of all basis coefficients (and the gain when it is free)."""
    import sympy as sp

    t0 = time.perf_counter()
    template.check_excitation(traj)
    args = template.arguments_of(traj)
    mask = ~sticking_mask(traj, rel_tol=stick_tol) if exclude_sticking else np.ones(traj.n_samples, bool)
    z = sp.Symbol("z")
    cols, owners = [], []
    for name in template.curve_names:
        for b in basis[name]:
            f = sp.lambdify(z, parse_basis_function(b), modules="numpy")
            cols.append(np.broadcast_to(f(args[name]), args[name].shape).astype(float))
            owners.append(name)
    pinned_all = all(
        all(parse_basis_function(b).subs(z, 0) == 0 for b in basis[name]) for name in template.curve_names
    )
    use_constant = pinned_all if constant is None else constant
    if use_constant:
        cols.append(np.ones(traj.n_samples))
        owners.append("__constant")
    target = template.gain * np.asarray(traj.F) - np.asarray(traj.a)
    force_side = template.free_gain and template.gain_on == "force"
    if template.free_gain:
        if force_side:  # F = h x'' + sum c b(z) + const, g = 1/h: the noisy forcing is the target
            cols.append(np.asarray(traj.a))
            target = np.asarray(traj.F)
        else:
            cols.append(-np.asarray(traj.F))
            target = -np.asarray(traj.a)
        owners.append("__gain")
    A = np.column_stack(cols)[mask]
    coef, *_ = np.linalg.lstsq(A, target[mask], rcond=None)
    owners = np.array(owners)
    if force_side:
        h = float(coef[owners == "__gain"][0])
        coef = coef / h  # curves and constant in the x'' + f1 + f2 + b = g F form
        coef[owners == "__gain"] = 1.0 / h
    gain = float(coef[owners == "__gain"][0]) if template.free_gain else template.gain
    b = float(coef[owners == "__constant"][0]) if use_constant else 0.0
    design = np.column_stack([c for c, o in zip(cols, owners) if o != "__gain"])[mask] if len(cols) > 1 else None
    resid = (design @ coef[owners != "__gain"] if design is not None else 0.0) + np.asarray(traj.a)[mask] \
        - gain * np.asarray(traj.F)[mask]
    loss = float(np.mean(resid**2))
    curves = {
        name: BasisFittedCurve(name, template.arguments[name], (float(args[name].min()), float(args[name].max())),
                               basis[name], coef[owners == name])
        for name in template.curve_names
    }
    raw0 = {n: float(c.raw(np.array([0.0]))[0]) for n, c in curves.items()}
    pinned = {n: c.pinned_at_zero for n, c in curves.items()}
    shifts, offset = apply_gauge(raw0, pinned, b, template.gauge, template.curve_names)
    for n, c in curves.items():
        c.shift = shifts[n]
    info = {"basis": basis, "n_samples": traj.n_samples, "n_fitted_samples": int(mask.sum()),
            "train_seconds": time.perf_counter() - t0, "condition_number": float(np.linalg.cond(A))}
    return FittedModel(template, method, curves, gain, offset, loss, info)
