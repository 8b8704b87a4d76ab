"""SR (bivariate, paper method x) and SR-CC (structured, method xi) as template fitters.

Both fit the force target ``y = g F - x''`` of the separable template
``x'' + f1(x') + f2(x) + b = g F`` on the non-sticking samples.

* **SR** searches ``y ≈ f(x, x')`` freely and then checks whether ``f`` decomposes as
  ``f1(x') + f2(x)`` (expand; terms in x' only -> f1, in x only -> f2, a pure number -> the free
  constant b, anything else -> "mixed").
* **SR-CC** enforces the decomposition by construction with the paper's block-coordinate loop
  (univariate SR of f2 on the residual target, then of f1, repeated). Operon's sklearn
  interface has no way to constrain a tree to a sum of univariate subtrees, so one structured
  search is not available; the alternating scheme also keeps each search univariate (small and
  fast).

The constant: a pure number in the SR expression is not a crossed term of x and x' -- the
template has a free constant b (f1 and f2 can trade it, the gauge fixes it) -- so here it makes
the result neither less nor more decomposable; it is reported as ``info["constant"]``. The
authors' scripts count it as "crossed": ``info["decomposable_scripts"]`` gives that verdict.

Free gain (``template.free_gain``): the search runs on ``g0 F - x''`` with ``g0`` from a
least-squares fit of a generic separable basis (powers of x and x' up to 5, a step in x', a
constant); afterwards all outer coefficients and g are refitted jointly by least squares, so g
is estimated together with the curves.
"""

from __future__ import annotations

import time

import numpy as np

from .._errors import ConfigError
from ..curves._fitted import SymbolicFittedCurve
from ..data._trajectory import Trajectory
from ..templates._separable import SeparableTemplate, apply_gauge, sticking_mask
from ._engine import POLY_OPERATORS, TANH_OPERATORS, _eval, _split_terms, make_engine, operators_option

__all__ = ["fit_sr", "fit_sr_cc", "decompose"]

_OPTION_KEYS_SR = ("stick_tol",)
_OPTION_KEYS_SRCC = ("stick_tol", "outer_iterations", "inner_generations", "tol")
#: Outer iterations of SR-CC (the paper: 8; stability "typically after 4").
OUTER_ITERATIONS = 8


def _check_options(options: dict, valid: tuple[str, ...], method: str) -> dict:
    unknown = sorted(set(options) - set(valid))
    if unknown:
        raise ConfigError(f"unknown option(s) {unknown} for {method}; valid: {', '.join(valid)}")
    return options


def _fit_mask(traj: Trajectory, options: dict) -> np.ndarray:
    """Samples to fit: sticking samples (x' = 0 over a run) are left out.

    ``options["stick_tol"]`` is the |x'| threshold relative to max|x'|; by default exact zeros
    (given derivatives) are looked for first and, when there are none, 1 % (the estimator's
    setting for estimated derivatives).
    """
    tol = options.get("stick_tol", "auto")
    if tol == "auto":
        stuck = sticking_mask(traj, rel_tol=None)
        if not stuck.any():
            stuck = sticking_mask(traj, rel_tol=0.01)
    else:
        stuck = sticking_mask(traj, rel_tol=None if tol is None else float(tol))
    return ~stuck


def _initial_gain(traj: Trajectory, template: SeparableTemplate, mask: np.ndarray) -> float:
    """g0 for free-gain runs: least squares of -x'' on a generic separable basis and -F."""
    if not template.free_gain:
        return float(template.gain)
    x, v, F, a = (np.asarray(c, dtype=float)[mask] for c in (traj.x, traj.v, traj.F, traj.a))
    sx, sv = max(np.max(np.abs(x)), 1e-300), max(np.max(np.abs(v)), 1e-300)
    cols = [np.ones_like(x)] + [(x / sx) ** p for p in range(1, 6)] + [(v / sv) ** p for p in range(1, 6)]
    cols += [np.tanh(v / (0.01 * sv)), -F]
    coef, *_ = np.linalg.lstsq(np.column_stack(cols), -a, rcond=None)
    g = float(coef[-1])
    if not np.isfinite(g) or g == 0.0:
        raise ConfigError("the input gain cannot be estimated from this record (the forcing does not move "
                          "the system); fix the gain instead (free_gain=False)")
    return g


def decompose(expr, var_of_curve: dict[str, object]):
    """Split ``f(x, x')`` into univariate parts.

    Parameters
    ----------
    expr : sympy.Expr
    var_of_curve : dict
        Curve name -> its sympy variable, e.g. ``{"f1": v, "f2": x}``.

    Returns
    -------
    parts : dict[str, sympy.Expr]
        Per curve, the sum of the terms in its variable only (0 when none).
    constant : float
        The pure-number part.
    mixed : list of sympy.Expr
        Terms depending on more than one variable (after expansion).
    """
    import sympy as sp

    expanded = sp.expand(expr, power_exp=False, power_base=False, log=False)
    parts = {name: sp.Integer(0) for name in var_of_curve}
    constant = 0.0
    mixed = []
    owner = {v: name for name, v in var_of_curve.items()}
    for term in sp.Add.make_args(expanded):
        syms = term.free_symbols & set(owner)
        if not syms:
            constant += float(term)
        elif len(syms) == 1:
            name = owner[next(iter(syms))]
            parts[name] = parts[name] + term
        else:
            mixed.append(term)
    return parts, constant, mixed


def _refit(traj, template, mask, parts_z: dict, gain: float):
    """Joint least squares of all outer coefficients (and g when free) on the fitted samples.

    ``parts_z`` holds each curve's expression in ``z`` (their constants are dropped: one joint
    constant is fitted). Returns the refitted parts, constant and gain. Inner constants (inside
    tanh) stay as they are.
    """
    import sympy as sp

    z = sp.Symbol("z")
    args = template.arguments_of(traj)
    cols, owners, bases = [], [], []
    for name, expr in parts_z.items():
        for c, b in _split_terms(sp.expand(expr)):
            if b == 1 or c == 0:
                continue
            vals = _eval(b, [z], np.asarray(args[name], dtype=float)[mask][:, None])
            if vals is None:
                continue
            cols.append(vals)
            owners.append(name)
            bases.append(b)
    cols.append(np.ones(int(mask.sum())))
    owners.append("__constant")
    bases.append(sp.Integer(1))
    F = np.asarray(traj.F, dtype=float)[mask]
    a = np.asarray(traj.a, dtype=float)[mask]
    if template.free_gain:
        cols.append(-F)
        owners.append("__gain")
        bases.append(None)
        target = -a
    else:
        target = gain * F - a
    coef, *_ = np.linalg.lstsq(np.column_stack(cols), target, rcond=None)
    out = {name: sp.Integer(0) for name in parts_z}
    new_const, new_gain = 0.0, gain
    for c, who, b in zip(coef, owners, bases):
        if who == "__constant":
            new_const = float(c)
        elif who == "__gain":
            new_gain = float(c)
        else:
            out[who] = out[who] + sp.Float(float(c), 15) * b
    if template.free_gain and (not np.isfinite(new_gain) or new_gain == 0.0):
        new_gain = gain
    return out, new_const, new_gain


def _build_model(traj, template, mask, parts_z, constant, gain, method, info, sr_meta, *, g0, t0):
    """FittedModel with SymbolicFittedCurve curves, the gauge applied and the loss computed.

    Also records what SR and SR-CC both report: sample counts, the initial gain and the time.
    """
    import sympy as sp

    info = {**info, "n_samples": traj.n_samples, "n_fitted_samples": int(mask.sum()),
            "n_sticking_samples": int((~mask).sum()), "gain_initial": float(g0)}

    from ..fitting._model import FittedModel

    args = template.arguments_of(traj)
    curves = {}
    for name in template.curve_names:
        expr = parts_z.get(name, sp.Integer(0))
        if not expr.free_symbols:
            constant += float(expr)
            expr = sp.Integer(0)
        z = np.asarray(args[name], dtype=float)
        curves[name] = SymbolicFittedCurve(name, template.arguments[name], (float(z.min()), float(z.max())), expr,
                                           0.0, sr_meta.get(name, {}))
    raw0 = {n: float(c.raw(np.array([0.0]))[0]) for n, c in curves.items()}
    pinned = {n: c.pinned_at_zero for n, c in curves.items()}
    shifts, offset = apply_gauge(raw0, pinned, float(constant), template.gauge, tuple(template.curve_names))
    for n, c in curves.items():
        c.shift = shifts[n]
    model = FittedModel(template, method, curves, gain, offset, 0.0, info)
    r = model.force_residual(traj)[mask]
    model.loss = float(np.mean(r**2))
    model.info["train_seconds"] = time.perf_counter() - t0
    return model


def _display(expr, names: dict) -> str:
    """Expression text with the data columns written as in the equation (v -> x')."""
    import sympy as sp

    return str(expr.xreplace({sp.Symbol(k): sp.Symbol(v) for k, v in names.items()}))


def fit_sr(traj: Trajectory, template: SeparableTemplate, *, symmetry=None, options=None, sr_options=None,
           random_state: int = 0, method: str = "sr"):
    """Bivariate SR of ``g F - x'' = f(x, x')`` followed by the decomposition check.

    Parameters
    ----------
    traj : Trajectory
        With derivatives (the estimator prepares them).
    template : SeparableTemplate
    symmetry : dict, optional
        Must be "none" for every curve (SR has no symmetry prior).
    options : dict, optional
        ``stick_tol`` (see :func:`_fit_mask`).
    sr_options : dict, optional
        Engine settings (:func:`charcurves.symbolic.make_engine`). ``operators="auto"``: + - *,
        plus tanh when the record has sticking phases (dry friction), as in the paper.
    random_state : int
    method : str

    Returns
    -------
    FittedModel
        Curves f1, f2 as SymbolicFittedCurve. ``info``: ``expression`` (the SR result, x' for
        the velocity), ``decomposable``, ``mixed_terms``, ``constant``, ``decomposable_scripts``
        and ``sr`` (front, timing, criterion). When mixed terms exist the curves are the
        separable terms of the expression with their coefficients refitted without the mixed
        terms (the best separable part), and ``decomposable`` is False.
    """
    import sympy as sp

    t0 = time.perf_counter()
    options = _check_options(dict(options or {}), _OPTION_KEYS_SR, method)
    if symmetry and any(v != "none" for v in symmetry.values()):
        raise ConfigError("SR has no symmetry prior; drop the symmetry option or use nn-cc+sym / sindy-cc+sym")
    template.check_excitation(traj)
    mask = _fit_mask(traj, options)
    engine = make_engine(sr_options)
    g0 = _initial_gain(traj, template, mask)
    y = g0 * np.asarray(traj.F, dtype=float) - np.asarray(traj.a, dtype=float)
    names = [template.variables[n] for n in template.curve_names]  # ["v", "x"]
    args = template.arguments_of(traj)
    X = np.column_stack([np.asarray(args[n], dtype=float) for n in template.curve_names])
    ops = operators_option(sr_options)
    sticking = bool((~mask).any())
    if ops is None:
        ops = TANH_OPERATORS if sticking else POLY_OPERATORS
    res = engine.fit(X[mask], y[mask], names, random_state=int(random_state), operators=ops)
    symbols = {n: sp.Symbol(template.variables[n]) for n in template.curve_names}
    parts, constant, mixed = decompose(res.expression, symbols)
    decomposable = not mixed
    z = sp.Symbol("z")
    parts_z = {n: e.xreplace({symbols[n]: z}) for n, e in parts.items()}
    gain = g0
    if not decomposable or template.free_gain:
        parts_z, constant, gain = _refit(traj, template, mask, parts_z, g0)
    disp = {template.variables[n]: template.arguments[n] for n in template.curve_names}
    info = {
        "expression": _display(res.expression, disp),
        "decomposable": bool(decomposable),
        "mixed_terms": [_display(t, disp) for t in mixed],
        "constant": float(constant),
        "decomposable_scripts": bool(decomposable and constant == 0.0),
        "operators": list(ops),
        "sr": res.summary(),
    }
    meta = {n: {"source": "sr", "expression": str(parts_z[n])} for n in template.curve_names}
    return _build_model(traj, template, mask, parts_z, constant, gain, method, info, meta, g0=g0, t0=t0)


def fit_sr_cc(traj: Trajectory, template: SeparableTemplate, *, symmetry=None, options=None, sr_options=None,
              random_state: int = 0, method: str = "sr-cc"):
    """SR constrained to ``f1(x') + f2(x)``: the paper's alternating block-coordinate loop.

    Each outer iteration runs univariate SR of f2 on x for the target ``(g F - x'') - f1_prev``,
    then of f1 on x' for ``(g F - x'') - f2_new`` (f1 starts at 0). Mixed terms cannot occur.

    Parameters
    ----------
    traj, template, symmetry, sr_options, random_state, method
        As :func:`fit_sr`. ``operators="auto"``: + - * for both curves, plus tanh for the
        velocity curve when the record has sticking phases.
    options : dict, optional
        ``outer_iterations`` (default 8, the paper's), ``inner_generations`` (default: a
        quarter of the SR generations, at least 10 -- the paper reduces 200 to 50),
        ``tol`` (stop early when neither curve changes by more than ``tol`` times the target's
        RMS between two iterations; default 1e-3, far below any noise level: measured on Duffing
        and stick-slip at 20 dB it gives the same curves as 1e-6 in 35-40 % less time;
        ``tol=0`` runs all the paper's iterations), ``stick_tol``.

    Returns
    -------
    FittedModel
        ``info``: ``iterations`` (run), ``history`` (f1, f2 per iteration), ``decomposable``
        (always True), ``mixed_terms`` ([]), ``constant`` and the last inner SR digests.
    """
    import sympy as sp

    t0 = time.perf_counter()
    options = _check_options(dict(options or {}), _OPTION_KEYS_SRCC, method)
    if symmetry and any(v != "none" for v in symmetry.values()):
        raise ConfigError("SR-CC has no symmetry prior; drop the symmetry option or use nn-cc+sym / sindy-cc+sym")
    n_outer = int(options.get("outer_iterations", OUTER_ITERATIONS))
    if n_outer < 1:
        raise ConfigError(f"outer_iterations must be >= 1, got {n_outer}")
    tol = float(options.get("tol", 1e-3))
    template.check_excitation(traj)
    mask = _fit_mask(traj, options)
    base = make_engine(sr_options)
    inner = int(options.get("inner_generations", max(10, base.generations // 4)))
    if inner < 1:
        raise ConfigError(f"inner_generations must be >= 1, got {inner}")
    engine = make_engine({**(sr_options or {}), "generations": inner})
    g0 = _initial_gain(traj, template, mask)
    y = (g0 * np.asarray(traj.F, dtype=float) - np.asarray(traj.a, dtype=float))[mask]
    args = {n: np.asarray(v, dtype=float)[mask] for n, v in template.arguments_of(traj).items()}
    ops_opt = operators_option(sr_options)
    sticking = bool((~mask).any())
    velocity = [n for n, var in template.variables.items() if var == "v"]
    ops = {n: ops_opt if ops_opt is not None else
           (TANH_OPERATORS if (sticking and n in velocity) else POLY_OPERATORS) for n in template.curve_names}
    z = sp.Symbol("z")
    f1_name, f2_name = template.curve_names
    vals = {n: np.zeros_like(y) for n in template.curve_names}
    exprs = {n: sp.Integer(0) for n in template.curve_names}
    results = {}
    history = []
    scale = float(np.sqrt(np.mean(y**2))) or 1.0
    it = 0
    for it in range(1, n_outer + 1):
        change = 0.0
        # paper order: f2 first (f1 starts at 0), then f1 on the updated residual
        for k, (name, other) in enumerate(((f2_name, f1_name), (f1_name, f2_name))):
            target = y - vals[other]
            res = engine.fit(args[name][:, None], target, ["z"], random_state=int(random_state) + 100 * it + k,
                             operators=ops[name])
            new = _eval(res.expression, [z], args[name][:, None])
            if new is None:  # pragma: no cover - engines return finite models
                continue
            change = max(change, float(np.sqrt(np.mean((new - vals[name]) ** 2))) / scale)
            vals[name], exprs[name], results[name] = new, res.expression, res
        history.append({n: str(exprs[n]) for n in template.curve_names})
        if it > 1 and change <= tol:
            break
    # split constants off the univariate parts: the gauge decides where the constant goes
    constant = 0.0
    parts_z = {}
    for name, e in exprs.items():
        c0 = sum((float(t) for t in sp.Add.make_args(sp.expand(e)) if not t.free_symbols), 0.0)
        constant += c0
        parts_z[name] = sp.expand(e) - c0
    parts_z, constant, gain = _refit(traj, template, mask, parts_z, g0)
    info = {
        "expression": " + ".join(f"{n}({template.arguments[n]}) = {parts_z[n]}" for n in template.curve_names),
        "decomposable": True,
        "mixed_terms": [],
        "constant": float(constant),
        "decomposable_scripts": True,
        "iterations": it,
        "outer_iterations": n_outer,
        "inner_generations": inner,
        "history": history,
        "operators": {n: list(o) for n, o in ops.items()},
        "sr": {n: r.summary() for n, r in results.items()},
    }
    meta = {n: {"source": "sr-cc", "expression": str(parts_z[n])} for n in template.curve_names}
    return _build_model(traj, template, mask, parts_z, constant, gain, method, info, meta, g0=g0, t0=t0)
