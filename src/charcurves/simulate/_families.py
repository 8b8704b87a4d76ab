"""Forward simulation of fitted models of general templates (first-order, position-damping,
two-dof, user-written equations).

The template's equations are solved at every right-hand-side call for the highest derivative of
each state (x' for first-order templates, x'' for second-order ones): the residual is evaluated
at the current state with the unknown derivatives at 0 and at unit steps (one vectorised call),
which gives the Jacobian of the residual in those unknowns; templates are affine in them in
every built-in family, and a second Newton step covers the rest to solver accuracy.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping

import numpy as np

from .._errors import ConfigError, SimulationError
from .._lambdify import numpy_function
from ._result import SimulationResult

__all__ = ["simulate_template_model", "SimulationStopped"]


def _orders(template) -> dict[str, int]:
    """Highest derivative of each state that appears in the template."""
    import re

    out = {s: 0 for s in template.states}
    for name in template.symbols:
        m = re.match(r"^(x\d*)__d([12])$", name)
        if m:
            out[m.group(1)] = max(out[m.group(1)], int(m.group(2)))
    return out


def _as_state_dict(value, states, what) -> dict[str, float]:
    if isinstance(value, Mapping):
        missing = [s for s in states if s not in value]
        if missing:
            raise ConfigError(f"{what} lacks {missing}; give a value for each of {', '.join(states)}")
        return {s: float(value[s]) for s in states}
    arr = np.atleast_1d(np.asarray(value, dtype=float)).reshape(-1)
    if arr.size != len(states):
        raise ConfigError(f"{what} needs {len(states)} value(s) ({', '.join(states)}), got {arr.size}")
    return {s: float(v) for s, v in zip(states, arr)}


def _forcing_functions(forcing, forces) -> Callable[[float], dict[str, float]]:
    if isinstance(forcing, Mapping):
        missing = [f for f in forces if f not in forcing]
        if missing:
            raise ConfigError(f"forcing lacks {missing}; give a callable for each of {', '.join(forces)}")
        return lambda t: {f: float(np.asarray(forcing[f](t)).reshape(-1)[0]) for f in forces}
    if not callable(forcing):
        raise ConfigError("forcing must be a callable F(t) or a dict of callables, e.g. {'F1': f1, 'F2': f2}")
    if len(forces) == 1:
        return lambda t: {forces[0]: float(np.asarray(forcing(t)).reshape(-1)[0])}

    def many(t):
        val = forcing(t)
        if isinstance(val, Mapping):
            return {f: float(val[f]) for f in forces}
        arr = np.asarray(val, dtype=float).reshape(-1)
        return dict(zip(forces, arr))

    return many


def simulate_template_model(model, t_eval, x0, v0, forcing, *, method: str = "LSODA", rtol: float = 1e-8,
                            atol: float = 1e-10, time_budget: float = 60.0, max_abs: float = 1e6, **ignored):
    """Integrate a fitted general-template model from ``(x0, v0)``.

    Parameters
    ----------
    model : FittedModel
        With an :class:`~charcurves.templates.EquationTemplate`.
    t_eval : array_like
        Increasing sample times.
    x0, v0 : float, sequence or dict
        Initial positions and velocities, one per state (``{"x1": .., "x2": ..}`` or in the order
        of ``model.template.states``); ``v0`` is not used by first-order templates.
    forcing : callable or dict of callables
        ``F(t)``, or one callable per forcing column (``{"F1": ..., "F2": ...}``), or a callable
        returning a dict/array of them.

    Returns
    -------
    SimulationResult
        ``x`` and ``v`` are (N,) for one state and (N, S) for several (``details["states"]``).

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.curves import SymbolicFittedCurve
    >>> from charcurves.fitting import FittedModel
    >>> from charcurves.simulate import simulate_template_model
    >>> from charcurves.templates import get_template
    >>> curves = {"f1": SymbolicFittedCurve("f1", "x", (-2, 2), "z**2 - 1"),
    ...           "f2": SymbolicFittedCurve("f2", "x", (-2, 2), "z")}
    >>> van_der_pol = FittedModel(get_template("position-damping"), "demo", curves, gain=1.0, offset=0.0, loss=0.0)
    >>> res = simulate_template_model(van_der_pol, np.linspace(0, 15, 151), 0.5, 0.0, lambda t: 0.0)
    >>> res.status, round(float(np.max(np.abs(res.x[-40:]))), 1)  # the limit cycle's amplitude
    ('ok', 2.0)
    """
    import sympy as sp
    from scipy.integrate import solve_ivp

    template = model.template
    t_eval = np.asarray(t_eval, dtype=float).reshape(-1)
    if t_eval.size < 2 or not np.all(np.isfinite(t_eval)) or np.any(np.diff(t_eval) <= 0):
        raise ConfigError("t_eval must be finite, strictly increasing sample times; pass e.g. np.linspace(0, 80, 2001)")
    states = list(template.states)
    orders = _orders(template)
    if any(k == 0 for k in orders.values()):
        raise SimulationError(f"the template has no derivative of {[s for s, k in orders.items() if k == 0]}; "
                              "nothing to integrate")
    if template.n_equations != len(states):
        raise SimulationError(f"the template has {template.n_equations} equation(s) for {len(states)} state(s); "
                              "simulation needs one equation per state")
    x0d = _as_state_dict(x0, states, "x0")
    v0d = _as_state_dict(v0 if v0 is not None else [0.0] * len(states), states, "v0")
    force_at = _forcing_functions(forcing, list(template.forces))
    unknowns = [f"{s}__d{orders[s]}" for s in states]
    U = len(unknowns)

    # compiled pieces of every equation: known, input, curve arguments and coefficients, scalar signals
    syms = [sp.Symbol(n, real=True) for n in template.symbols]
    compile_ = lambda e: numpy_function(syms, sp.sympify(e))  # noqa: E731
    eqs = []
    sc = model.scalars
    for e, eq in enumerate(template.equations):
        eqs.append({
            "known": compile_(eq.known), "input": compile_(eq.input),
            "curves": [(model.curves[n], compile_(template.argument_exprs[n]), compile_(m)) for n, m in eq.curves.items()],
            "scalars": [(sc.get(s, 0.0), compile_(sig)) for s, sig in eq.scalars.items()],
            "offset": float(model.offset) if e == 0 else sc.get(f"b{e + 1}", 0.0),
        })
    gain = float(model.gain)
    names = list(template.symbols)

    def residuals(values: dict[str, np.ndarray]) -> np.ndarray:
        args = [values[n] for n in names]
        m = len(next(iter(values.values())))
        out = np.empty((len(eqs), m))

        def full(v):  # (m,) values; np.broadcast_to costs more than the call itself on a vector already (m,)
            return v if isinstance(v, np.ndarray) and v.shape == (m,) else np.broadcast_to(v, (m,))

        for e, q in enumerate(eqs):  # constant pieces stay scalars: numpy broadcasts them to the same numbers
            r = q["known"](*args) - gain * q["input"](*args) + q["offset"]
            for curve, arg, coef in q["curves"]:
                r = r + coef(*args) * curve(full(arg(*args)))
            for value, sig in q["scalars"]:
                r = r + value * sig(*args)
            out[e] = r
        return out

    layout = []  # (state, derivative order) of each entry of the ODE state vector
    for s in states:
        for k in range(orders[s]):
            layout.append((s, k))
    deadline = time.monotonic() + float(time_budget)
    probe = np.vstack([np.zeros(U), np.eye(U)])  # unknowns at 0 and at unit steps
    zeros = np.zeros(U + 1)  # the symbols a right-hand side does not set (read, never written)
    # every built-in template is affine in the unknowns: one Newton step is then exact, and the
    # second one (a residual evaluation per right-hand side, half the cost) only confirms it
    newton_steps = 1 if _affine_in(template, eqs, unknowns) else 2

    base_names = ["t", *template.forces, *(s if k == 0 else f"{s}__d{k}" for s, k in layout)]

    def top_derivatives(t: float, y: np.ndarray) -> np.ndarray:
        F = force_at(t)
        # each known value repeated for the U + 1 probes: the rows of one array, built in one call
        rows = np.repeat(np.array([t, *(F[f] for f in template.forces), *y], dtype=float)[:, None], U + 1, axis=1)
        base = dict(zip(base_names, rows))
        d = np.zeros(U)
        for _ in range(newton_steps):  # affine templates: exact after the first step
            vals = dict(base)
            for j, name in enumerate(unknowns):
                vals[name] = d[j] + probe[:, j]
            R = residuals({n: vals.get(n, zeros) for n in names})
            J = (R[:, 1:] - R[:, :1])
            try:
                step = np.linalg.solve(J, -R[:, 0])
            except np.linalg.LinAlgError:
                raise _Stop("solver_failed", f"the equations cannot be solved for {', '.join(unknowns)} at t = {t:.4g} "
                                             "(a curve coefficient vanished)", t) from None
            d = d + step
            if np.max(np.abs(step)) <= 1e-12 * (1.0 + np.max(np.abs(d))):
                break
        return d

    def rhs(t, y):
        if not np.all(np.isfinite(y)) or np.max(np.abs(y)) > max_abs:
            raise _Stop("diverged", f"the state became non-finite or larger than {max_abs:g} at t = {t:.4g}", t)
        if time.monotonic() > deadline:
            raise _Stop("timeout", f"the time budget of {time_budget:g} s ran out at t = {t:.4g}", t)
        top = top_derivatives(t, y)
        dy = np.empty_like(y)
        for i, (s, k) in enumerate(layout):
            dy[i] = y[i + 1] if k + 1 < orders[s] else top[states.index(s)]
        return dy

    y0 = []
    for s, k in layout:
        y0.append(x0d[s] if k == 0 else v0d[s])
    t0 = time.perf_counter()
    status, message, t_end = "ok", "", float(t_eval[-1])
    try:
        sol = solve_ivp(rhs, (t_eval[0], t_eval[-1]), y0, method=method, t_eval=t_eval, rtol=rtol, atol=atol)
        Y, T = sol.y, sol.t
        if not sol.success:
            status, message, t_end = "solver_failed", sol.message, float(T[-1]) if T.size else float(t_eval[0])
    except _Stop as stop:
        status, message, t_end = stop.status, stop.message, stop.t
        Y, T = np.zeros((len(layout), 0)), np.zeros(0)
        if stop.status != "timeout":
            keep = t_eval[t_eval < stop.t]
            if keep.size >= 2:
                try:
                    sol = solve_ivp(rhs, (keep[0], keep[-1]), y0, method=method, t_eval=keep, rtol=rtol, atol=atol)
                    Y, T = sol.y, sol.t
                except _Stop:
                    pass
    X = np.column_stack([Y[layout.index((s, 0))] for s in states]) if T.size else np.zeros((0, len(states)))
    V = np.zeros_like(X)
    for j, s in enumerate(states):
        if orders[s] >= 2:
            V[:, j] = Y[layout.index((s, 1))]
        elif T.size:
            V[:, j] = [top_derivatives(tt, Y[:, i])[j] for i, tt in enumerate(T)]
    if len(states) == 1:
        X, V = X[:, 0], V[:, 0]
    return SimulationResult(T, X, V, status, message, t_end, time.perf_counter() - t0,
                            details={"states": states, "solved_for": [n.replace("__d1", "'").replace("__d2", "''")
                                                                      for n in unknowns]})


def _affine_in(template, eqs, unknowns) -> bool:
    """True when every equation's residual is affine in the unknown top derivatives: no curve
    argument holds one, and the curves' coefficients and the known, input and scalar-signal parts
    have a zero second derivative in each pair of them (sympy; what it cannot prove counts as not
    affine)."""
    import sympy as sp

    names = set(unknowns)
    for eq in template.equations:
        if any(names & {str(v) for v in sp.sympify(template.argument_exprs[n]).free_symbols} for n in eq.curves):
            return False
        for e in (eq.known, eq.input, *eq.curves.values(), *eq.scalars.values()):
            expr = sp.sympify(e)
            u = [v for v in expr.free_symbols if str(v) in names]  # the template's own symbols (assumptions)
            if any(sp.diff(expr, a, b) != 0 for i, a in enumerate(u) for b in u[i:]):
                return False
    return bool(eqs)


class _Stop(Exception):
    def __init__(self, status: str, message: str, t: float):
        super().__init__(message)
        self.status, self.message, self.t = status, message, t


SimulationStopped = _Stop
"""The stop signal of multi-DOF simulations: ``status``, ``message`` and the time ``t`` (caught by
the outer loop of :mod:`charcurves.selection`).

Examples
--------
>>> from charcurves.simulate import SimulationStopped
>>> try:
...     raise SimulationStopped("left_box", "x left the training box at t = 3.2", 3.2)
... except SimulationStopped as stop:
...     print(stop.status, stop.t)
left_box 3.2
"""
