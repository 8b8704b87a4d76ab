"""Post-SR: distil learned curves into closed forms (paper methods ii, iv and ix).

Each learned curve is evaluated on ``n`` evenly spaced points over its training range (the
paper: 1000) and symbolic regression is run on ``z -> f(z)``; the result replaces the curve.

Operator set ("auto", the default of ``sr_options["operators"]``): the paper's sets (no unary
operator for Duffing, tanh for stick-slip), and beyond polynomials where the curve asks for it:

* a neural curve with a learned jump (``NeuralFittedCurve`` with ``spec.jump``, added for
  records with sticking) is distilled *by parts*: its jump component ``mu tanh(z/eps)`` already
  is a closed form and is kept as ``muN tanh(k z)``; SR with + - * runs on the smooth remainder
  (curve minus jump), and the outer coefficients of both parts are refitted together. Measured
  on stick-slip curves this is what makes a Coulomb law come out as ``c z + muN tanh(k z)``:
  with tanh in the operator set, SR uses nested tanh to imitate the small network's wiggles
  (the network itself is built from tanh units). ``k = 1/eps`` is lowered to ``20 / min|z|``
  over the grid when larger: a jump narrower than that is a step on every grid point either
  way, and the lower k keeps forward simulations from becoming needlessly stiff;
* every other curve gets two searches (issue 46): first the polynomial one -- + - *, plus tanh
  for a curve with a jump at 0 (a closed form containing tanh/sign/Abs, or samples in which one
  grid step carries more than 5 % of the curve's range and more than 20x the median step), plus
  sin and cos for a curve that turns at least :data:`TRIG_TURNS` times -- then one with
  :data:`~charcurves.symbolic.CLOSED_FORM_OPERATORS` (+ - * abs tanh sin cos exp sqrtabs) added.
  The closed-form search's pick is kept only when its MSE on the samples is
  :data:`CLOSED_FORM_GAIN` times smaller than the polynomial pick's, so a polynomial truth stays a
  polynomial (the wider set offers look-alikes such as ``147 z - 728 sin(0.2 z)`` for z^3 - z that
  fit no better). Both searches are in ``meta["searches"]``; ``meta["operators"]`` is the kept one's.
  Measured in ``benchmarks/bench_postsr_forms.py`` (docs/post-sr.md).

An explicit ``sr_options["operators"]`` overrides all this (one whole-curve search with that set).
"""

from __future__ import annotations

import math
from typing import Any, cast

import numpy as np

from .._errors import ConfigError
from ..curves import FittedCurve, SymbolicFittedCurve, jump_log_eps
from ._selection import REL_MSE_FLOOR
from ._engine import CLOSED_FORM_OPERATORS, POLY_OPERATORS, TANH_OPERATORS, SymbolicRegressionEngine
from ._make import make_engine

__all__ = ["distill_curve", "distill_curve_front", "has_jump", "turns", "TRIG_TURNS", "POST_SR_OPTIONS", "DATA_LOSS_TOLERANCE",
           "post_sr_engine", "polynomial_operators", "CLOSED_FORM_GAIN"]

#: Search settings of post-SR that differ from :data:`DEFAULT_SR_OPTIONS` (``sr_options`` given to a
#: fit override them): a learned curve is a smooth function sampled without noise, so the search
#: needs fewer points and generations than one on a measured record. Measured (2-core machine, one
#: thread) on 144 distillations: NN-CC+sym, NN-CC and SINDy-CC+sym fits of Duffing and stick-slip at
#: 40/20/10/0 dB, 3 noise seeds, both curves. Against 400 points and 40 generations (1.04 s per
#: curve), 100 points and 20 generations take 0.32 s; 141 of 144 closed forms have the same terms,
#: the three others are stick-slip friction curves at 0 dB (no simple form there either way), and
#: the RMSE against the true curve is the same (geometric mean of the ratios 0.996, largest 1.06,
#: mean 0.0380 against 0.0393). 200 points and 20 generations: 0.37 s, 142 of 144, ratios 1.000.
POST_SR_OPTIONS: dict[str, Any] = {"generations": 20, "max_points": 100}

#: A distilled model may fit the training record this much worse (relative data loss) than the
#: model it distils before a curve is replaced by a more accurate member of its front (post-SR of
#: the separable family and of state-space templates).
DATA_LOSS_TOLERANCE = 0.05


def post_sr_engine(sr_options: dict | None = None) -> SymbolicRegressionEngine:
    """The engine of post-SR: :data:`POST_SR_OPTIONS` under the given ``sr_options``.

    Examples
    --------
    >>> from charcurves.symbolic import post_sr_engine
    >>> engine = post_sr_engine({"generations": 30})
    >>> engine.generations, engine.max_points, engine.population_size
    (30, 100, 300)
    """
    return make_engine({**POST_SR_OPTIONS, **{k: v for k, v in (sr_options or {}).items() if v is not None}})

#: A curve that turns (changes direction by more than a tenth of its range) at least this many
#: times over its domain oscillates: the automatic operator set then adds sin and cos.
TRIG_TURNS = 4

#: The closed-form search's pick replaces the polynomial search's only when its MSE on the curve's
#: samples is this many times smaller: a polynomial truth stays a polynomial (the wider set offers
#: stand-ins such as ``147 z - 728 sin(0.2 z)`` for z^3 - z that fit no better than the truth).
CLOSED_FORM_GAIN = 2.0

#: One grid step carrying more than this share of the curve's range (and ...)
_JUMP_RANGE_SHARE = 0.05
#: ... more than this many median steps counts as a jump.
_JUMP_MEDIAN_FACTOR = 20.0


def has_jump(curve: FittedCurve, z: np.ndarray | None = None, y: np.ndarray | None = None) -> bool:
    """Whether a curve needs ``tanh`` to be expressed (a jump at 0, dry friction).

    Parameters
    ----------
    curve : FittedCurve
    z, y : arrays, optional
        Samples of the curve on a grid (computed when not given).

    Examples
    --------
    >>> from charcurves.curves import BasisFittedCurve, SymbolicFittedCurve
    >>> from charcurves.symbolic import has_jump
    >>> has_jump(SymbolicFittedCurve("f1", "x'", (-1, 1), "0.3*z + 0.8*tanh(500*z)"))
    True
    >>> has_jump(BasisFittedCurve("f1", "x'", (-1, 1), ["z"], [0.3]))
    False
    """
    import sympy as sp

    comps = curve.components()
    if abs(float(comps.get("jump_height", 0.0))) > 0.0:
        return True
    expr = curve.expression()
    if expr is not None and expr.has(sp.tanh, sp.sign, sp.Abs):
        return True
    if z is None or y is None:
        z = curve.grid(1000)
        y = curve(z)
    d = np.abs(np.diff(np.asarray(y, dtype=float)))
    rng = float(np.ptp(y))
    if d.size < 3 or rng == 0.0:
        return False
    med = float(np.median(d))
    big = float(d.max())
    return big > _JUMP_RANGE_SHARE * rng and big > _JUMP_MEDIAN_FACTOR * max(med, 1e-300)


def distill_curve(curve: FittedCurve, engine: SymbolicRegressionEngine | None = None, *, n: int = 1000,
                  random_state: int = 0, operators=None) -> SymbolicFittedCurve:
    """Closed form of one learned curve by symbolic regression on its samples.

    Parameters
    ----------
    curve : FittedCurve
        Any learned curve (neural, basis, symbolic).
    engine : SymbolicRegressionEngine, optional
        Default: :func:`post_sr_engine` (Operon with the post-SR settings).
    n : int
        Grid points over ``curve.domain`` (the paper: 1000).
    random_state : int
    operators : sequence of str, optional
        Operator set of one search; by default two searches (the module's notes): + - * plus tanh
        when :func:`has_jump`, plus sin and cos when the curve oscillates (:func:`turns` at least
        :data:`TRIG_TURNS` times over its domain), then the same with
        :data:`~charcurves.symbolic.CLOSED_FORM_OPERATORS`.

    Returns
    -------
    SymbolicFittedCurve
        Same name, argument and domain; shift 0 (the expression carries the curve's value at 0;
        :func:`distill_model` re-applies the gauge). ``meta`` holds the SR digest.

    Examples
    --------
    >>> from charcurves.curves import BasisFittedCurve
    >>> from charcurves.symbolic import distill_curve, make_engine
    >>> curve = BasisFittedCurve("f2", "x", (-2.0, 2.0), ["z", "z**3"], [-1.0, 1.0])
    >>> closed = distill_curve(curve, make_engine({"generations": 5}), n=100)
    >>> type(closed).__name__, closed.expression().evalf(3)
    ('SymbolicFittedCurve', 1.0*z**3 - 1.0*z)
    """
    return distill_curve_front(curve, engine, n=n, random_state=random_state, operators=operators)[0]


def turns(y: np.ndarray, share: float = 0.1) -> int:
    """How many times ``y`` changes direction by more than ``share`` of its range (wiggles below
    that are ignored): 0 for a monotone curve, 1 for a parabola, about 2 per period of a sine.

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.symbolic import turns
    >>> z = np.linspace(-2, 2, 1000)
    >>> turns(z**3 + z), turns(z**3 - z), turns(np.sin(25 * z))   # 100 rad: 32 extrema of sin
    (0, 0, 32)

    (the wiggle of z³ − z near 0 is under a tenth of its range.)
    """
    y = np.asarray(y, dtype=float)
    thr = share * float(np.ptp(y)) if y.size else 0.0
    if thr <= 0:
        return 0
    count, direction, hi, lo = 0, 0, y[0], y[0]
    for value in y[1:]:
        if direction >= 0 and value > hi:
            hi = value
        if direction <= 0 and value < lo:
            lo = value
        if direction >= 0 and hi - value > thr:
            count += direction == 1
            direction, lo = -1, value
        elif direction <= 0 and value - lo > thr:
            count += direction == -1
            direction, hi = 1, value
    return int(count)


def distill_curve_front(curve: FittedCurve, engine, *, n: int, random_state: int, operators):
    """(selected closed form, every front member as a full-curve sympy expression, simplest first).

    Examples
    --------
    >>> from charcurves.curves import BasisFittedCurve
    >>> from charcurves.symbolic import distill_curve_front, make_engine
    >>> curve = BasisFittedCurve("f2", "x", (-2.0, 2.0), ["z", "z**3"], [-1.0, 1.0])
    >>> engine = make_engine({"generations": 5})
    >>> selected, front = distill_curve_front(curve, engine, n=100, random_state=0, operators=None)
    >>> selected.expression().evalf(3), len(front) > 1
    (1.0*z**3 - 1.0*z, True)
    """
    import sympy as sp

    if engine is None:
        engine = post_sr_engine()
    if int(n) < 10:
        raise ConfigError(f"post-SR needs at least 10 grid points, got n={n}")
    z = curve.grid(int(n))
    y = np.asarray(curve(z), dtype=float)
    if not np.all(np.isfinite(y)):
        raise ConfigError(f"curve {curve.name} has non-finite values on its domain; cannot distil it")
    jump = has_jump(curve, z, y)
    zs = sp.Symbol("z")
    parts = _neural_jump(curve, z) if operators is None else None
    searches: list = []
    if parts is not None:
        jump_vals, _mu, k = parts
        res = engine.fit(z[:, None], y - jump_vals, ["z"], random_state=int(random_state), operators=POLY_OPERATORS,
                         context="curve")
        expr, mse = _refit_with_jump(res.expression, k, z, y)
        front = [_refit_with_jump(e, k, z, y)[0] for _c, _m, e in res.front]
        mode = "smooth part + learned jump"
    elif operators is not None:
        res = engine.fit(z[:, None], y, ["z"], random_state=int(random_state), operators=tuple(operators),
                         context="curve")
        expr, mse = res.expression, res.mse
        front = [e for _c, _m, e in res.front]
        mode = "whole curve"
    else:
        res, front, searches = _auto_search(engine, z, y, jump, int(random_state))
        expr, mse = res.expression, res.mse
        mode = "whole curve, " + ("closed-form" if res is searches[1] else "polynomial") + " search kept"
    if expr.free_symbols - {zs}:  # pragma: no cover - engines only see z
        raise ConfigError(f"post-SR of {curve.name} returned {expr}, which is not a function of z alone")
    if not expr.free_symbols:
        expr = sp.Float(float(expr), 15)
    meta = res.summary()
    meta.update({"source_kind": curve.kind, "n_grid": int(n), "jump_detected": bool(jump), "mode": mode,
                 "expression": str(expr), "distillation_rmse": float(np.sqrt(mse))})
    if parts is None and operators is None:
        meta["searches"] = [{"operators": list(r.operators), "expression": str(r.expression), "mse": float(r.mse),
                             "seconds": float(r.seconds)} for r in searches]
        meta["seconds"] = float(sum(r.seconds for r in searches))
        meta["search_seconds"] = float(sum(r.search_seconds for r in searches))
    front = [e for e in front if not (e.free_symbols - {zs})]
    return SymbolicFittedCurve(curve.name, curve.argument, curve.domain, expr, 0.0, meta), front


def polynomial_operators(jump: bool, y: np.ndarray) -> tuple[str, ...]:
    """The first search of the automatic choice: + - *, tanh for a jump, sin and cos for a curve
    that oscillates (:func:`turns` at least :data:`TRIG_TURNS` times).

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.symbolic import polynomial_operators
    >>> z = np.linspace(-2, 2, 1000)
    >>> polynomial_operators(False, z**3 - z), polynomial_operators(True, np.sign(z)), polynomial_operators(False, np.sin(25 * z))
    (('add', 'sub', 'mul'), ('add', 'sub', 'mul', 'tanh'), ('add', 'sub', 'mul', 'sin', 'cos'))
    """
    ops = TANH_OPERATORS if jump else POLY_OPERATORS
    return ops + ("sin", "cos") if turns(y) >= TRIG_TURNS else ops


def _auto_search(engine: SymbolicRegressionEngine, z: np.ndarray, y: np.ndarray, jump: bool, random_state: int):
    """Both searches of ``operators="auto"``: (result kept, front, both results). The front (what the data
    guard of post-SR walks, simplest first) is the kept search's, then the other's: a curve whose pick
    breaks the guard moves up its own search's front before it takes the other family's forms."""
    first = polynomial_operators(jump, y)
    wide = tuple(dict.fromkeys(CLOSED_FORM_OPERATORS + first))
    results = [engine.fit(z[:, None], y, ["z"], random_state=random_state, operators=ops, context="curve")
               for ops in (first, wide)]
    poly, closed = results
    floor = REL_MSE_FLOOR * float(np.var(y))  # round-off is no gain (clean samples of a polynomial)
    keep = closed if max(closed.mse, floor) * CLOSED_FORM_GAIN < max(poly.mse, floor) else poly
    other = poly if keep is closed else closed
    return keep, [e for r in (keep, other) for _c, _m, e in r.front], results


def _neural_jump(curve: FittedCurve, z: np.ndarray):
    """(jump values on z, muN, k) of a neural curve's learned jump; None when it has none."""
    spec = getattr(curve, "spec", None)
    if spec is None or not getattr(spec, "jump", False):
        return None
    sl = spec.slices()
    neural: Any = curve  # a neural curve (theta, in_scale, out_scale): it has a spec with a jump
    mu_m = neural.theta[:, sl["jump_height"]].reshape(-1) * neural.out_scale
    eps_m = np.exp(jump_log_eps(neural.theta[:, sl["jump_log_eps"]].reshape(-1))) * neural.in_scale
    with np.errstate(over="ignore", divide="ignore"):
        vals = np.mean(mu_m[:, None] * np.tanh(z[None, :] / eps_m[:, None]), axis=0)
    # k = 1/eps, lowered to where the step is still saturated (|k z| >= 20) at every grid point:
    # a jump narrower than that is a step on the grid either way, and the lower k keeps forward
    # simulations from being needlessly stiff. (Capping at the grid spacing instead would leave
    # a grid point that happens to lie very near 0 on the slope of the tanh.)
    az = np.abs(z[z != 0])
    k_sat = 20.0 / float(az.min()) if az.size else math.inf
    k = float(min(1.0 / max(float(np.median(eps_m)), 1e-300), k_sat))
    return vals, float(np.mean(mu_m)), k


def _refit_with_jump(smooth_expr, k: float, z: np.ndarray, y: np.ndarray):
    """``smooth + muN tanh(k z)`` with all outer coefficients (muN too) refitted by least squares."""
    import sympy as sp

    from ._expressions import eval_expression, split_terms

    zs = sp.Symbol("z")
    step = sp.tanh(sp.Float(k, 15) * zs)
    terms = [b for c, b in split_terms(sp.expand(smooth_expr)) if c != 0] + [step]
    # finite on z: the smooth terms were fitted there (polynomial operators) and tanh is bounded
    A = np.column_stack([cast(np.ndarray, eval_expression(b, [zs], z[:, None])) for b in terms])
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    expr = sp.Add(*[sp.Float(float(c), 15) * b for c, b in zip(coef, terms)])
    return expr, float(np.mean((A @ coef - y) ** 2))
