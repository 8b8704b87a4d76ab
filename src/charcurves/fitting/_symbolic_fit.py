"""Symbolic curves on a template: SR (bivariate, paper method x) and SR-CC (structured, method xi).

Both fit the force target ``y = g F - known`` (``g F - x''`` for the separable family) on the
fitted samples (sticking phases left out) of a template with one equation whose curves enter with
coefficient 1.

* **SR** (``Symbolic(joint=True)``) searches ``y ~ f(args)`` freely and then checks whether ``f``
  decomposes as a sum of univariate curves (expand; terms in one argument -> that curve, a pure
  number -> the free constant b, anything else -> "mixed").
* **SR-CC** enforces the decomposition by construction with the paper's block-coordinate loop
  (univariate SR of each curve on the residual target, repeated). Operon's sklearn interface has
  no way to constrain a tree to a sum of univariate subtrees, so one structured search is not
  available; the alternating scheme also keeps each search univariate (small and fast).

The constant: a pure number in the SR expression is not a crossed term of x and x' -- the
template has a free constant b (the curves can trade it, the gauge fixes it) -- so here it makes
the result neither less nor more decomposable; it is reported as ``info["constant"]``. The
authors' scripts count it as "crossed": ``info["decomposable_scripts"]`` gives that verdict.

Free gain: the search runs on ``g0 F - x''`` with ``g0`` from a least-squares fit of a generic
separable basis (powers of the arguments up to 5, a step in velocity arguments, a constant);
afterwards (SR, and SR-CC with ``Symbolic(refit=True)``) all outer coefficients and g are refitted
jointly by least squares; plain SR-CC (the paper's) keeps g0 and the coefficients its searches found.

Coefficients: SR-CC as the paper runs it (``"sr-cc"``, ``Symbolic()``) keeps the coefficients each
univariate search found (Operon optimises them inside its search); ``"sr-cc+refit"``
(``Symbolic(refit=True)``) keeps the structure and refits the outer coefficients of all curves
jointly by least squares, which on the separable Duffing makes it Parametric whenever SR finds the
true basis. SR refits the separable terms only when it dropped mixed terms (or the gain is free).
"""

from __future__ import annotations

import time

import numpy as np

from .._errors import ConfigError
from ..curves import SymbolicFittedCurve
from ..symbolic import (POLY_OPERATORS, TANH_OPERATORS, SearchInterrupted, decompose, eval_expression, make_engine,
                        split_terms)
from ..templates import EquationTemplate
from ..model import finish_model
from ._sticking import sticking_masks

__all__ = ["fit_symbolic", "fit_sr", "fit_sr_cc", "OUTER_ITERATIONS", "SR_CC_OPTIONS"]

#: Outer iterations of SR-CC (the paper: 8; stability "typically after 4").
OUTER_ITERATIONS = 8
#: Options of SR-CC (``options`` of the estimator): outer_iterations, inner_generations, tol.
SR_CC_OPTIONS = ("outer_iterations", "inner_generations", "tol")


def _check_template(template: EquationTemplate, D: dict, what: str) -> None:
    if D["E"] != 1 or template.scalar_names or any(np.ptp(m) > 0 or m[0] != 1.0 for m in D["mult"].values()):
        raise ConfigError(f"{what} supports templates of one equation whose curves enter with coefficient 1 and no "
                          f"unknown scalars (the separable family), not the {template.family} template; use a "
                          "neural, polynomial, sparse or basis representation there")


def _initial_gain(template: EquationTemplate, D: dict, mask: np.ndarray) -> float:
    """g0 for free-gain runs: least squares of -known on a generic separable basis and -F."""
    if not template.free_gain:
        return float(template.gain)
    cols = [np.ones(int(mask.sum()))]
    for name in _search_order(template):
        z = D["args"][name][mask]
        s = max(np.max(np.abs(z)), 1e-300)
        cols += [(z / s) ** p for p in range(1, 6)]
    for name in template.velocity_curves:
        z = D["args"][name][mask]
        cols.append(np.tanh(z / (0.01 * max(np.max(np.abs(z)), 1e-300))))
    cols.append(-D["F"][mask])
    coef, *_ = np.linalg.lstsq(np.column_stack(cols), -D["y"][mask], rcond=None)
    g = float(coef[-1])
    if not np.isfinite(g) or g == 0.0:
        raise ConfigError("the input gain cannot be estimated from this record (the forcing does not move "
                          "the system); fix the gain instead (free_gain=False)")
    return g


def _search_order(template: EquationTemplate) -> list[str]:
    """Curves by the derivative order of their argument (x before x', as the paper's SR variables)."""
    def key(name):
        arg = str(template.argument_exprs[name])
        return (int(arg[-1]) if "__d" in arg else 0), int(name[1:])

    return sorted(template.curve_names, key=key)


def _variable(template: EquationTemplate, name: str) -> str:
    """The name SR uses for a curve's argument: "x", "v" (for x'), else the argument as written."""
    arg = template.arguments[name]
    return "v" if arg == "x'" else ("x" if arg == "x" else f"u{name[1:]}")


def _refit(template, D, mask, parts_z: dict, gain: float):
    """Joint least squares of all outer coefficients (and g when free) on the fitted samples.

    ``parts_z`` holds each curve's expression in ``z`` (their constants are dropped: one joint
    constant is fitted). Inner constants (inside tanh) stay as they are.
    """
    import sympy as sp

    z = sp.Symbol("z")
    cols, owners, bases = [], [], []
    for name, expr in parts_z.items():
        for c, b in split_terms(sp.expand(expr)):
            if b == 1 or c == 0:
                continue
            vals = eval_expression(b, [z], np.asarray(D["args"][name], dtype=float)[mask][:, None])
            if vals is None:
                continue
            cols.append(vals)
            owners.append(name)
            bases.append(b)
    cols.append(np.ones(int(mask.sum())))
    owners.append("__constant")
    bases.append(sp.Integer(1))
    F, y = D["F"][mask], D["y"][mask]
    if template.free_gain:
        cols.append(-F)
        owners.append("__gain")
        bases.append(None)
        target = -y
    else:
        target = gain * F - y
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


def _build(template, record, D, mask, parts_z, constant, gain, method, info, meta, *, g0, t0):
    import sympy as sp

    info = {**info, "gain_initial": float(g0)}
    curves = {}
    for name in template.curve_names:
        expr = parts_z.get(name, sp.Integer(0))
        if not expr.free_symbols:
            constant += float(expr)
            expr = sp.Integer(0)
        z = np.asarray(D["args"][name], dtype=float)
        curves[name] = SymbolicFittedCurve(name, template.arguments[name], (float(z.min()), float(z.max())), expr,
                                           0.0, meta.get(name, {}))
    info.update({"n_samples": int(mask.size), "n_fitted_samples": int(mask.sum()),
                 "n_sticking_samples": int((~mask).sum())})
    model = finish_model(template, method, curves, gain, {0: float(constant)}, {}, record, info, mask)
    model.info["train_seconds"] = time.perf_counter() - t0
    return model


def fit_symbolic(record, template: EquationTemplate, reps: dict, *, method: str, mask: np.ndarray,
                 options: dict | None = None, sr_options: dict | None = None, random_state: int = 0, progress=None):
    """SR (every curve ``Symbolic(joint=True)``) or SR-CC (``Symbolic()``) on a prepared record.

    Parameters
    ----------
    options : dict, optional
        SR-CC: ``outer_iterations`` (default 8, the paper's), ``inner_generations`` (default: a
        quarter of the SR generations, at least 10 -- the paper reduces 200 to 50), ``tol`` (stop
        early when no curve changes by more than ``tol`` times the target's RMS between two
        iterations; default 1e-3, far below any noise level: on Duffing and stick-slip at 20 dB
        it gives the same curves as 1e-6 in 35-40 % less time; 0 runs all iterations).
    sr_options : dict, optional
        Engine settings (:func:`charcurves.symbolic.make_engine`); ``operators="auto"``: + - *,
        plus tanh (for velocity curves, SR-CC; for the whole search, SR) when the record has
        sticking phases, as in the paper.
    progress : callable, optional
        ``progress(phase, step, total, loss)``, called while a search runs (every 0.1 s, ``loss``
        nan); the CLI prints it every 2 s.

    Returns
    -------
    FittedModel
        Curves as SymbolicFittedCurve. ``info``: ``expression``, ``decomposable``, ``mixed_terms``,
        ``constant``, ``decomposable_scripts``, ``operators`` and the SR digests; SR-CC also
        ``iterations`` and ``history``. When SR's expression has mixed terms, the curves are its
        separable terms with their coefficients refitted without the mixed terms.

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.curves import Symbolic
    >>> from charcurves.fitting import fit_symbolic
    >>> from charcurves.systems import get_system
    >>> from charcurves.templates import get_template
    >>> record = get_system("duffing").simulate()
    >>> reps = {"f1": Symbolic(joint=True), "f2": Symbolic(joint=True)}
    >>> keep = np.ones(record.n_samples, dtype=bool)  # every sample (no sticking phases)
    >>> model = fit_symbolic(record, get_template(), reps, method="sr", mask=keep, sr_options={"generations": 5})
    >>> model.to_sympy(curves=True, digits=3)
    {'f1': 0.3*z, 'f2': z**3 - z}
    """
    t0 = time.perf_counter()
    joint = {bool(getattr(r, "joint", False)) for r in reps.values()}
    if len(joint) != 1:
        raise ConfigError("mix of joint and per-curve Symbolic curves; use Symbolic(joint=True) for every curve (SR) "
                          "or for none (SR-CC)")
    refit = {bool(getattr(r, "refit", False)) for r in reps.values()}
    if len(refit) != 1:
        raise ConfigError("mix of Symbolic(refit=True) and Symbolic(refit=False); the refit is joint over every "
                          "curve: give every curve the same refit")
    D = template.design(record)
    _check_template(template, D, "symbolic regression (sr, sr-cc)")
    if joint.pop():
        return _fit_sr(template, record, D, mask, method, dict(options or {}), sr_options, random_state, t0, progress)
    return _fit_sr_cc(template, record, D, mask, method, dict(options or {}), sr_options, random_state, t0,
                      refit=refit.pop(), progress=progress)


def _fit_sr(template, record, D, mask, method, options, sr_options, random_state, t0, progress=None):
    import sympy as sp

    from ..symbolic import operators_option

    if options:
        raise ConfigError(f"unknown option(s) {sorted(options)} for {method}; it takes none")
    engine = make_engine(sr_options)
    engine.progress = progress
    g0 = _initial_gain(template, D, mask)
    y = g0 * D["F"] - D["y"]
    order = list(template.curve_names)
    names = [_variable(template, n) for n in order]
    X = np.column_stack([np.asarray(D["args"][n], dtype=float) for n in order])
    ops = operators_option(sr_options)
    if ops is None:
        ops = TANH_OPERATORS if bool((~mask).any()) else POLY_OPERATORS
    interrupted = None
    try:
        res = engine.fit(X[mask], y[mask], names, random_state=int(random_state), operators=ops)
    except SearchInterrupted as exc:  # Ctrl-C or SIGTERM: the pick of the front reached so far
        if exc.result is None:
            raise
        res = exc.result
        interrupted = (f"interrupted (Ctrl-C or SIGTERM) in the search after {res.info.get('generations_run', 0)} "
                       f"of {engine.generations * engine.populations} generations")
    symbols = {n: sp.Symbol(v) for n, v in zip(order, names)}
    parts, constant, mixed = decompose(res.expression, symbols)
    decomposable = not mixed
    z = sp.Symbol("z")
    parts_z = {n: e.xreplace({symbols[n]: z}) for n, e in parts.items()}
    gain = g0
    if not decomposable or template.free_gain:
        parts_z, constant, gain = _refit(template, D, mask, parts_z, g0)
    disp = {_variable(template, n): template.arguments[n] for n in order}
    show = lambda e: str(e.xreplace({sp.Symbol(k): sp.Symbol(v) for k, v in disp.items()}))  # noqa: E731
    info = {
        "expression": show(res.expression),
        "decomposable": bool(decomposable),
        "mixed_terms": [show(t) for t in mixed],
        "constant": float(constant),
        "decomposable_scripts": bool(decomposable and constant == 0.0),
        "operators": list(ops),
        "sr": res.summary(),
    }
    if interrupted:
        info.update(interrupted=True, stopped_by=interrupted)  # the pipeline skips what follows
    meta = {n: {"source": "sr", "expression": str(parts_z[n])} for n in template.curve_names}
    return _build(template, record, D, mask, parts_z, constant, gain, method, info, meta, g0=g0, t0=t0)


def _fit_sr_cc(template, record, D, mask, method, options, sr_options, random_state, t0, *, refit: bool = False,
               progress=None):
    import sympy as sp

    from ..symbolic import operators_option

    unknown = sorted(set(options) - set(SR_CC_OPTIONS))
    if unknown:
        raise ConfigError(f"unknown option(s) {unknown} for {method}; valid: {', '.join(SR_CC_OPTIONS)}")
    n_outer = int(options.get("outer_iterations", OUTER_ITERATIONS))
    if n_outer < 1:
        raise ConfigError(f"outer_iterations must be >= 1, got {n_outer}")
    tol = float(options.get("tol", 1e-3))
    base = make_engine(sr_options)
    inner = int(options.get("inner_generations", max(10, base.generations // 4)))
    if inner < 1:
        raise ConfigError(f"inner_generations must be >= 1, got {inner}")
    engine = make_engine({**(sr_options or {}), "generations": inner})
    engine.progress = progress
    g0 = _initial_gain(template, D, mask)
    y = (g0 * D["F"] - D["y"])[mask]
    args = {n: np.asarray(v, dtype=float)[mask] for n, v in D["args"].items()}
    ops_opt = operators_option(sr_options)
    sticking = bool((~mask).any())
    ops = {n: ops_opt if ops_opt is not None else
           (TANH_OPERATORS if (sticking and n in template.velocity_curves) else POLY_OPERATORS)
           for n in template.curve_names}
    z = sp.Symbol("z")
    vals = {n: np.zeros_like(y) for n in template.curve_names}
    exprs = {n: sp.Integer(0) for n in template.curve_names}
    results, history = {}, []
    scale = float(np.sqrt(np.mean(y**2))) or 1.0
    it = 0
    interrupted = None  # Ctrl-C or SIGTERM after a search returned: keep the curves found so far
    try:
        for it in range(1, n_outer + 1):
            change = 0.0
            # the paper's order: the position curve first (the velocity curve starts at 0)
            for k, name in enumerate(_search_order(template)):
                target = y - sum((vals[o] for o in template.curve_names if o != name), np.zeros_like(y))
                res = engine.fit(args[name][:, None], target, ["z"], random_state=int(random_state) + 100 * it + k,
                                 operators=ops[name])
                new = eval_expression(res.expression, [z], args[name][:, None])
                if new is None:  # pragma: no cover - engines return finite models
                    continue
                change = max(change, float(np.sqrt(np.mean((new - vals[name]) ** 2))) / scale)
                vals[name], exprs[name], results[name] = new, res.expression, res
            history.append({n: str(exprs[n]) for n in template.curve_names})
            if it > 1 and change <= tol:
                break
    except KeyboardInterrupt as exc:
        found = getattr(exc, "result", None)  # SearchInterrupted: the search's pick of its front so far
        if found is not None and (new := eval_expression(found.expression, [z], args[name][:, None])) is not None:
            vals[name], exprs[name], results[name] = new, found.expression, found
        if not results:
            raise  # no search returned yet: there is no model to keep
        interrupted = f"interrupted (Ctrl-C or SIGTERM) in outer iteration {it} of {n_outer}"
        history.append({n: str(exprs[n]) for n in template.curve_names})
    # split constants off the univariate parts: the gauge decides where the constant goes
    constant = 0.0
    parts_z = {}
    for name, e in exprs.items():
        c0 = sum((float(t) for t in sp.Add.make_args(sp.expand(e)) if not t.free_symbols), 0.0)
        constant += c0
        parts_z[name] = sp.expand(e) - c0
    gain = g0
    if refit:  # sr-cc+refit: the structure SR found, its outer coefficients refitted jointly
        parts_z, constant, gain = _refit(template, D, mask, parts_z, g0)
    info = {
        "expression": " + ".join(f"{n}({template.arguments[n]}) = {parts_z[n]}" for n in template.curve_names),
        "decomposable": True,
        "mixed_terms": [],
        "constant": float(constant),
        "decomposable_scripts": True,
        "refit": bool(refit),
        "iterations": it,
        "outer_iterations": n_outer,
        "inner_generations": inner,
        "history": history,
        "operators": {n: list(o) for n, o in ops.items()},
        "sr": {n: r.summary() for n, r in results.items()},
    }
    if interrupted:
        info.update(interrupted=True, stopped_by=interrupted)  # the pipeline skips what follows
    meta = {n: {"source": "sr-cc", "expression": str(parts_z[n])} for n in template.curve_names}
    return _build(template, record, D, mask, parts_z, constant, gain, method, info, meta, g0=g0, t0=t0)


def unfitted_symbolic(record, template: EquationTemplate, *, method: str, mask: np.ndarray):
    """The model of a record that an interrupt kept from being searched: every curve 0, the known gain,
    marked ``interrupted`` with ``stopped_by="not fitted: interrupted"`` (like the trainer's
    untrained chunks)."""
    D = template.design(record)
    info = {"interrupted": True, "stopped_by": "not fitted: interrupted", "expression": "", "decomposable": True,
            "mixed_terms": [], "constant": 0.0, "decomposable_scripts": True, "sr": {}}
    meta = {n: {"source": method, "expression": "0"} for n in template.curve_names}
    return _build(template, record, D, mask, {}, 0.0, float(template.gain), method, info, meta,
                  g0=float(template.gain), t0=time.perf_counter())


def _functional(joint: bool):
    def run(traj, template: EquationTemplate, *, symmetry=None, options=None, sr_options=None, random_state: int = 0,
            method: str | None = None):
        from ..curves import Symbolic

        what = "SR" if joint else "SR-CC"
        if symmetry and any(v != "none" for v in symmetry.values()):
            raise ConfigError(f"{what} has no symmetry prior; drop the symmetry option or use nn-cc+sym / sindy-cc+sym")
        options = dict(options or {})
        stick_tol = options.pop("stick_tol", "default")
        template.check_excitation(traj)
        mask = sticking_masks([traj], template, [False], exclude=True, kind="symbolic", stick_tol=stick_tol)[0]
        # SR-CC's coefficient refit is the method "sr-cc+refit" (Symbolic(refit=True))
        reps = {n: Symbolic(joint=joint, refit=not joint and method == "sr-cc+refit") for n in template.curve_names}
        return fit_symbolic(traj, template, reps, method=method or ("sr" if joint else "sr-cc"), mask=mask,
                            options=options, sr_options=sr_options, random_state=random_state)

    run.__name__ = "fit_sr" if joint else "fit_sr_cc"
    run.__doc__ = (f"{'SR' if joint else 'SR-CC'} of a prepared record on a template (see :func:`fit_symbolic`); the "
                   "functional form of ``CharacteristicCurves.from_method(method=" + ("'sr'" if joint else "'sr-cc'") + ")``.")
    return run


fit_sr = _functional(True)
"""SR of a prepared record on a template (see :func:`fit_symbolic`): ``CharacteristicCurves.from_method(method='sr')``.

Examples
--------
>>> from charcurves.fitting import fit_sr
>>> from charcurves.systems import get_system
>>> from charcurves.templates import get_template
>>> model = fit_sr(get_system("duffing").simulate(), get_template(), sr_options={"generations": 5})
>>> model.method, model.to_sympy(curves=True, digits=3)
('sr', {'f1': 0.3*z, 'f2': z**3 - z})
"""
fit_sr_cc = _functional(False)
"""SR-CC of a prepared record on a template (see :func:`fit_symbolic`): ``CharacteristicCurves.from_method(method='sr-cc')``.

Examples
--------
>>> from charcurves.fitting import fit_sr_cc
>>> from charcurves.systems import get_system
>>> from charcurves.templates import get_template
>>> short = {"outer_iterations": 1, "inner_generations": 3}  # a short search: its coefficients are rough
>>> record = get_system("duffing").simulate()
>>> model = fit_sr_cc(record, get_template(), options=short, sr_options={"generations": 3})
>>> model.method, model.to_sympy(curves=True, digits=3)
('sr-cc', {'f1': 0.3*z, 'f2': 1.01*z**3 - 1.01*z})
>>> refit = fit_sr_cc(record, get_template(), options=short, sr_options={"generations": 3}, method="sr-cc+refit")
>>> refit.to_sympy(curves=True, digits=3)  # the same structure, its coefficients refitted jointly
{'f1': 0.3*z, 'f2': z**3 - z}
"""
