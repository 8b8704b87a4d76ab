"""Fast scalar evaluation of fitted curves for ODE right-hand sides, and jump splitting.

An ODE solver calls the right-hand side with one state at a time, so a network curve that is
evaluated through numpy pays tens of microseconds of array overhead per call. Here a curve is
prepared once:

* its **smooth part** is evaluated exactly (numpy / lambdified sympy) or from a **table**: a
  cubic spline (``scipy.interpolate.CubicSpline``) on a fine uniform grid over the training
  range plus a margin, evaluated by indexing the uniform grid. The table is checked against
  the exact curve at every interval midpoint (where interpolation errs most) and refined, or
  abandoned for exact evaluation, when the error exceeds ``table_rtol`` times the curve's range.
  Outside the table the exact curve is used.
* a **jump at 0** (dry friction) is split off: ``f(z) = smooth(z) + mu * sign(z)``. It is read
  from the curve's parametrisation (a network's ``mu * tanh(u / eps)`` term, a symbolic
  ``c * tanh(k z)`` or ``c * sign(z)`` term) or, for other curves, detected numerically. Only a
  jump narrower than ``sharp_width`` times the curve's argument scale counts as a jump by
  default; wider ones are smooth enough for the solver.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np

from .._errors import ConfigError
from .._lambdify import numpy_function
from ._jumps import _jump_term_vector, _neural_jump, _numeric_jump, _symbolic_jump, _with_jump_term

__all__ = ["PreparedCurve", "prepare_curve", "EVALUATIONS", "JUMP_MODES"]

EVALUATIONS = ("auto", "exact", "tabulated")
JUMP_MODES = ("auto", "events", "smooth")

#: Default: a tanh jump whose width is below this fraction of the argument scale is a jump.
SHARP_WIDTH = 1e-3
# numpy operations of one vectorised evaluation (PreparedCurve.vector_ops): a table lookup, a
# network's jump term, a network evaluated exactly
_TABLE_OPS, _JUMP_OPS, _NETWORK_OPS = 12, 6, 40


@dataclasses.dataclass
class PreparedCurve:
    """A curve ready for an ODE right-hand side.

    Attributes
    ----------
    smooth : callable float -> float
        The smooth part (the whole curve when ``jump_height`` is 0).
    derivative : callable float -> float
        Derivative of the smooth part.
    jump_height : float
        ``mu`` of the split-off jump ``mu * sign(z)``; 0 when none was split off.
    jump_width : float
        Width of the jump as fitted (``eps`` of ``tanh(z / eps)``; 0 for ``sign``), for reports.
    evaluation : str
        "exact" or "tabulated" (what was actually used).
    table_error : float
        Largest error of the table at the interval midpoints, relative to the curve's range
        (NaN when not tabulated).
    note : str
        Why a requested table was not used, if so.
    vector : callable array -> array, optional
        The smooth part on an array of arguments (what ``smooth`` gives for each element, up to
        rounding): for right-hand sides of many states at once (:func:`simulate_model_batch`).
    vector_ops : int
        About how many numpy operations one ``vector`` call takes (a table's lookup, or the
        closed form's operation count): each costs about a microsecond on small arrays, which
        decides whether stacking runs pays (:func:`simulate_model_batch`).

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.curves import SymbolicFittedCurve
    >>> from charcurves.simulate import PreparedCurve, prepare_curve
    >>> prepared = prepare_curve(SymbolicFittedCurve("f2", "x", (-2.0, 2.0), "z**3 - z"))
    >>> isinstance(prepared, PreparedCurve), prepared.evaluation, prepared.smooth(2.0), prepared.derivative(2.0)
    (True, 'exact', 6.0, 11.0)
    >>> prepared.values(np.array([1.0, 2.0])).tolist()
    [0.0, 6.0]
    """

    smooth: Callable[[float], float]
    derivative: Callable[[float], float]
    jump_height: float = 0.0
    jump_width: float = float("nan")
    evaluation: str = "exact"
    table_error: float = float("nan")
    note: str = ""
    vector: Callable[[np.ndarray], np.ndarray] | None = None
    vector_ops: int = 0

    def values(self, z: np.ndarray) -> np.ndarray:
        """The smooth part at every element of ``z``."""
        z = np.asarray(z, dtype=float)
        if self.vector is not None:
            return np.broadcast_to(np.asarray(self.vector(z), dtype=float), z.shape)
        return np.array([self.smooth(float(u)) for u in z.reshape(-1)]).reshape(z.shape)

    def __call__(self, z: float, direction: int | None = None) -> float:
        """The whole curve; at ``z == 0`` the jump takes the side ``direction`` (0 when None)."""
        s = direction if (z == 0.0 and direction is not None) else (0.0 if z == 0.0 else math.copysign(1.0, z))
        return self.smooth(z) + self.jump_height * s


# ---------------------------------------------------------------------------------- helpers
def _vectorised(curve) -> Callable[[np.ndarray], np.ndarray]:
    def f(z):
        z = np.asarray(z, dtype=float)
        return np.broadcast_to(np.asarray(curve(z), dtype=float), z.shape)

    return f


def _scale_of(curve) -> float:
    dom = getattr(curve, "domain", None)
    if dom is None:
        return 1.0
    s = max(abs(float(dom[0])), abs(float(dom[1])))
    return s if s > 0 and math.isfinite(s) else 1.0


def _finite_difference(f: Callable[[np.ndarray], np.ndarray], scale: float) -> Callable[[float], float]:
    h0 = 1e-6 * scale

    def df(z: float) -> float:
        h = h0 * max(1.0, abs(z) / scale)
        return float((f(np.array([z + h]))[0] - f(np.array([z - h]))[0]) / (2.0 * h))

    return df


def _scalar(f: Callable[[np.ndarray], np.ndarray]) -> Callable[[float], float]:
    def g(z: float) -> float:
        return float(f(np.array([z]))[0])

    return g


# ---------------------------------------------------------------------------------- networks
def _network_vectorised(curve, drop_jump: bool):
    """A network curve's numpy evaluation plus its shift, without its jump term when asked;
    None for other curves.

    The jump is dropped by evaluating a shallow copy whose jump heights are 0 (the curve's own
    numpy path, so nothing of the network is re-implemented here).
    """
    if not hasattr(curve, "numpy_function") or not hasattr(curve, "theta"):
        return None
    net = curve
    if drop_jump and getattr(curve.spec, "jump", False):
        import copy

        net = copy.copy(curve)
        net.__dict__.pop("_np_fn", None)
        net.__dict__.pop("_prepared_for_simulation", None)
        net.theta = curve.theta.copy()
        net.theta[:, curve.spec.slices()["jump_height"]] = 0.0
    fn, shift = net.numpy_function(), float(curve.shift)

    def f(z):
        return fn(np.asarray(z, dtype=float)) + shift

    return f


def _network_scalar(f: Callable[[np.ndarray], np.ndarray]) -> Callable[[float], float]:
    buf = np.empty(1)

    def g(z: float) -> float:
        buf[0] = z
        return float(f(buf)[0])

    return g


def _symbolic_slope(e, zs, smooth_vec, scale) -> Callable[[float], float]:
    """The derivative of a closed form, differentiated and compiled on its first call: only the
    tangent dynamics (Lyapunov exponents) ask for it, and sympy's diff was most of preparing a
    closed-form curve for a validation run (about 20 ms of 40 for a polynomial)."""
    built: list[Callable[[float], float]] = []

    def build() -> Callable[[float], float]:
        import sympy as sp

        # d sign(z)/dz is 0 away from 0 (the jump is not part of the tangent dynamics)
        de = sp.diff(e, zs).subs(sp.Derivative(sp.sign(zs), zs), 0)
        try:
            dfn = numpy_function(zs, de)
            return lambda z: float(dfn(z))
        except Exception:  # a derivative numpy cannot print (unevaluated): central differences
            return _finite_difference(smooth_vec, scale)

    def slope(z: float) -> float:
        if not built:
            built.append(build())
        return built[0](z)

    return slope


# ---------------------------------------------------------------------------------- tables
class _Table:
    """Cubic spline on a uniform grid, evaluated by direct indexing (microseconds per call)."""

    def __init__(self, f: Callable[[np.ndarray], np.ndarray], lo: float, hi: float, n: int):
        from scipy.interpolate import CubicSpline

        self.z = np.linspace(lo, hi, n)
        self.spline = CubicSpline(self.z, f(self.z))
        self.lo, self.hi = lo, hi
        self.inv_h = (n - 1) / (hi - lo)
        self.last = n - 2
        # per interval (left node, c3, c2, c1, c0) as Python floats: a scalar call never touches numpy
        c = self.spline.c
        self.rows = list(zip(self.z[:-1].tolist(), c[0].tolist(), c[1].tolist(), c[2].tolist(), c[3].tolist()))

    def value(self, z: float, exact: Callable[[float], float]) -> float:
        if not (self.lo <= z <= self.hi):
            return exact(z)
        i = int((z - self.lo) * self.inv_h)
        z0, a, b, c, d = self.rows[i if i <= self.last else self.last]
        u = z - z0
        return ((a * u + b) * u + c) * u + d

    def slope(self, z: float, exact: Callable[[float], float]) -> float:
        if not (self.lo <= z <= self.hi):
            return exact(z)
        i = int((z - self.lo) * self.inv_h)
        z0, a, b, c, _ = self.rows[i if i <= self.last else self.last]
        u = z - z0
        return (3.0 * a * u + 2.0 * b) * u + c

    def values(self, z: np.ndarray, exact: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
        """:meth:`value` on an array (``exact`` vectorised: used outside the table)."""
        inside = (z >= self.lo) & (z <= self.hi)
        zi = np.where(inside, z, self.lo)
        i = np.minimum(((zi - self.lo) * self.inv_h).astype(np.intp), self.last)
        c = self.spline.c
        u = zi - self.z[i]
        out = ((c[0, i] * u + c[1, i]) * u + c[2, i]) * u + c[3, i]
        if not inside.all():
            out[~inside] = exact(z[~inside])
        return out

    def midpoint_error(self, f: Callable[[np.ndarray], np.ndarray]) -> float:
        mid = 0.5 * (self.z[:-1] + self.z[1:])
        exact = f(mid)
        spread = float(np.ptp(exact))
        return float(np.max(np.abs(self.spline(mid) - exact)) / max(spread, 1e-300))


def prepare_curve(curve, *, evaluation: str = "auto", jump: str = "auto", margin: float = 1.0,
                  table_points: int = 4097, table_rtol: float = 1e-7, max_table_points: int = 1 << 17,
                  sharp_width: float = SHARP_WIDTH, split_jump: bool = True) -> PreparedCurve:
    """Prepare ``curve`` (a FittedCurve or any vectorised callable) for scalar evaluation.

    Parameters
    ----------
    curve : FittedCurve or callable
    evaluation : {"auto", "exact", "tabulated"}
        "auto" tabulates network curves (per-call overhead dominates there) and evaluates
        closed forms (symbolic and basis curves, lambdified) exactly; "tabulated" tabulates
        every curve with a domain.
    jump : {"auto", "events", "smooth"}
        "auto" splits off a jump narrower than ``sharp_width`` times the argument scale;
        "events" splits off any jump term found (whatever its width); "smooth" never splits.
    margin : float
        The table covers the domain widened by ``margin`` times its width on each side.
    table_points, max_table_points : int
        Initial and largest number of grid nodes (doubled until ``table_rtol`` is met).
    table_rtol : float
        Largest midpoint error of the table relative to the curve's range.
    split_jump : bool
        False for curves whose argument is not a velocity (a jump there is not dry friction).

    Raises
    ------
    ConfigError
        For an unknown ``evaluation`` or ``jump``, or ``jump="events"`` on a curve without a jump.

    Examples
    --------
    >>> from charcurves.curves import BasisFittedCurve
    >>> from charcurves.simulate import prepare_curve
    >>> friction = BasisFittedCurve("f1", "x'", (-1.0, 1.0), ["z", "sign(z)"], [0.386, 0.801])  # Coulomb
    >>> prepared = prepare_curve(friction)  # the jump is split off, for events at x' = 0
    >>> round(prepared.jump_height, 3), round(prepared.smooth(0.5), 3)
    (0.801, 0.193)
    """
    if evaluation not in EVALUATIONS:
        raise ConfigError(f"unknown curve evaluation {evaluation!r}; choose one of {', '.join(EVALUATIONS)}")
    if jump not in JUMP_MODES:
        raise ConfigError(f"unknown jump handling {jump!r}; choose one of {', '.join(JUMP_MODES)}")
    options = (evaluation, jump, margin, table_points, table_rtol, max_table_points, sharp_width, split_jump)
    if not hasattr(curve, "domain"):
        return _prepare(curve, *options)
    # a fitted curve is prepared once per set of options (validation simulates one model many
    # times); the key also holds the mutable gauge shift and domain
    key = (*options, curve.shift, curve.domain)
    cache = curve.__dict__.setdefault("_prepared_for_simulation", _Cache())
    if key not in cache:
        cache[key] = _prepare(curve, *options)
    return cache[key]


class _Cache(dict):
    """Prepared curves kept on a curve object; pickled and copied as empty (they hold closures)."""

    def __reduce__(self):
        return (_Cache, ())


def _prepare(curve, evaluation, jump, margin, table_points, table_rtol, max_table_points, sharp_width,
             split_jump) -> PreparedCurve:
    network = _network_vectorised(curve, drop_jump=False)
    full = network or _vectorised(curve)
    scale = _scale_of(curve)
    smooth_vec, height, width = full, 0.0, float("nan")
    smooth_expr = None
    # a network's own jump term that stays in the curve: added exactly after the table, which
    # then only holds the smooth network part (a near-discontinuity cannot be tabulated)
    kept_jump = False
    expr = curve.expression() if hasattr(curve, "expression") else None
    neural = _neural_jump(curve)
    if neural is not None:
        mu, w = neural
        sharp = None if jump == "events" else sharp_width
        smooth_vec = _network_vectorised(curve, drop_jump=True)  # the network without its jump term
        if split_jump and jump != "smooth" and (sharp is None or w <= sharp * scale):
            height, width = mu, w
        else:
            kept_jump = True
    if split_jump and jump != "smooth" and neural is None:
        sharp = None if jump == "events" else sharp_width
        if expr is not None:
            split = _symbolic_jump(expr, scale, sharp)
            if split is not None:
                smooth_expr, height, width = split
        else:
            found = _numeric_jump(full, scale)
            if found is not None:
                height, width = found
                smooth_vec = lambda z: full(z) - height * np.sign(z)  # noqa: E731
        if jump == "events" and height == 0.0:
            name = getattr(curve, "name", None)
            raise ConfigError(f"{f'curve {name}' if name else 'the curve'} has no jump at 0 to treat with events; "
                              "use jump='auto' or jump='smooth'")

    # exact scalar evaluation (and its derivative)
    if expr is not None and (smooth_expr is not None or smooth_vec is full):
        import sympy as sp
        zs = sp.Symbol("z")
        e = smooth_expr if smooth_expr is not None else expr
        fn = numpy_function(zs, e)
        ops = int(sp.count_ops(e)) + 1
        exact = lambda z: float(fn(z))  # noqa: E731
        if zs in e.free_symbols and not e.has(sp.Piecewise):  # numpy gives an array of z's shape
            smooth_vec = lambda z: np.asarray(fn(np.asarray(z, float)), float)  # noqa: E731
        else:
            smooth_vec = lambda z: np.broadcast_to(np.asarray(fn(np.asarray(z, float)), float), np.shape(z))  # noqa: E731
        exact_slope = _symbolic_slope(e, zs, smooth_vec, scale)
    else:
        exact = _network_scalar(smooth_vec) if network is not None else _scalar(smooth_vec)
        exact_slope = _finite_difference(smooth_vec, scale)
        ops = _NETWORK_OPS

    exact_vector = smooth_vec
    if kept_jump:
        exact, exact_slope = _with_jump_term(exact, exact_slope, curve)
        jump_vec = _jump_term_vector(curve)
        exact_vector = lambda z: smooth_vec(z) + jump_vec(z)  # noqa: E731
        ops += _JUMP_OPS
    dom = getattr(curve, "domain", None)
    want_table = evaluation == "tabulated" or (evaluation == "auto" and expr is None and dom is not None)
    if evaluation == "tabulated" and dom is None:
        raise ConfigError("tabulated evaluation needs a curve with a domain (a fitted curve); "
                          "use evaluation='exact'")
    if not want_table:
        return PreparedCurve(exact, exact_slope, height, width, "exact", vector=exact_vector, vector_ops=ops)
    assert dom is not None  # a table is wanted only for a curve with a domain
    lo, hi = float(dom[0]), float(dom[1])
    pad = margin * (hi - lo) if hi > lo else 1.0
    lo, hi = lo - pad, hi + pad
    n = int(table_points)
    previous = None
    while True:
        table = _Table(smooth_vec, lo, hi, n)
        err = table.midpoint_error(smooth_vec)
        if previous is not None and err > table_rtol:
            # a smooth curve's error falls ~16x per doubling; a kinked one (ReLU) ~4x: give up at
            # once when the observed rate cannot reach the tolerance within max_table_points
            rate = max(previous / max(err, 1e-300), 1.0 + 1e-9)
            doublings = math.log(err / table_rtol) / math.log(rate)
            if doublings > math.log2(max_table_points / n):  # as doublings: 2.0 ** doublings can overflow
                return PreparedCurve(exact, exact_slope, height, width, "exact", err,
                                     f"table error {err:.2g} > {table_rtol:g} with {n} points; evaluated exactly",
                                     exact_vector, ops)
        previous = err
        if err <= table_rtol:
            value = lambda z: table.value(z, exact)  # noqa: E731
            slope = lambda z: table.slope(z, exact_slope)  # noqa: E731
            vector = lambda z, t=table: t.values(z, exact_vector)  # noqa: E731
            ops = _TABLE_OPS
            if kept_jump:
                value, slope = _with_jump_term(value, slope, curve, outside=(lo, hi))
                inner_jump = _jump_term_vector(curve, outside=(lo, hi))
                vector = lambda z, t=table: t.values(z, exact_vector) + inner_jump(z)  # noqa: E731
                ops += _JUMP_OPS
            return PreparedCurve(value, slope, height, width, "tabulated", err, vector=vector, vector_ops=ops)
        if 2 * n - 1 > max_table_points:
            return PreparedCurve(exact, exact_slope, height, width, "exact", err,
                                 f"table error {err:.2g} > {table_rtol:g} with {n} points; evaluated exactly",
                                 exact_vector, ops)
        n = 2 * n - 1
