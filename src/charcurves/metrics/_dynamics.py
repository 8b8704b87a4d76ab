"""Metrics of forward simulations: separation time, trajectory RMSE, largest Lyapunov exponent."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .._errors import SimulationError

__all__ = ["separation_time", "trajectory_rmse", "largest_lyapunov_exponent"]


def separation_time(t, x_model, x_true, *, eps: float = 0.2) -> tuple[float, bool]:
    """First time with ``|x_model - x_true| > eps`` (strict, as the authors' scripts) and whether
    the value is censored (never separated: the last available time is returned).

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.metrics import separation_time
    >>> t = np.linspace(0, 10, 101)
    >>> t_sep, censored = separation_time(t, np.sin(t) + 0.05 * t, np.sin(t), eps=0.2)
    >>> round(t_sep, 3), censored
    (4.1, False)
    >>> separation_time(t, np.sin(t), np.sin(t))  # never separated: censored at the last time
    (10.0, True)
    """
    t = np.asarray(t, dtype=float)
    n = min(len(x_model), len(x_true), len(t))
    d = np.abs(np.asarray(x_model[:n], dtype=float) - np.asarray(x_true[:n], dtype=float))
    d[~np.isfinite(d)] = np.inf
    above = np.flatnonzero(d > eps)
    if above.size:
        return float(t[above[0]]), False
    return float(t[n - 1]) if n else float("nan"), True


def trajectory_rmse(x_model, x_true) -> float:
    """Root-mean-square difference over the samples both trajectories have.

    Examples
    --------
    >>> from charcurves.metrics import trajectory_rmse
    >>> trajectory_rmse([0.0, 1.0, 2.0, 3.0], [0.0, 1.0, 2.0])  # over the 3 samples both have
    0.0
    >>> round(trajectory_rmse([1.0, 2.0], [0.0, 0.0]), 6)
    1.581139
    """
    n = min(len(x_model), len(x_true))
    d = np.asarray(x_model[:n], dtype=float) - np.asarray(x_true[:n], dtype=float)
    return float(np.sqrt(np.mean(d * d))) if n else float("nan")


def _scalar_curve(f: Callable, df: Callable | None, evaluation: str):
    """Scalar value and derivative functions of a curve for the tangent dynamics.

    Fitted curves go through :func:`charcurves.simulate.prepare_curve` (a checked spline table
    with its analytic derivative for networks, sympy derivatives for symbolic curves); plain
    callables are evaluated as given, with central differences unless ``df`` is passed.
    """
    from ..simulate import prepare_curve

    prepared = prepare_curve(f, evaluation=evaluation if hasattr(f, "domain") else "exact", jump="smooth",
                             split_jump=False)
    if df is None:
        return prepared.smooth, prepared.derivative
    return prepared.smooth, (lambda z: float(np.asarray(df(z))))


def largest_lyapunov_exponent(f1: Callable, f2: Callable, forcing: Callable, x0: float, v0: float, *,
                              gain: float = 1.0, offset: float = 0.0, t_transient: float = 100.0,
                              t_total: float = 2000.0, renorm_every: float | None = None,
                              rtol: float = 1e-9, atol: float = 1e-11, df1: Callable | None = None,
                              df2: Callable | None = None, evaluation: str = "auto",
                              method: str = "LSODA") -> float:
    """Benettin's method with the variational (tangent) equations of ``x'' = g F - f1(x') - f2(x) - b``.

    Parameters
    ----------
    f1, f2 : callable or FittedCurve
        The curves: a truth's (vectorised callables) or a fitted model's
        (``model.curves["f1"]``, ``model.curves["f2"]``, with ``gain=model.gain`` and
        ``offset=model.offset``).
    forcing : callable
        ``F(t)`` (scalar calls).
    x0, v0 : float
        Initial state (a transient of ``t_transient`` is discarded).
    renorm_every : float, optional
        Renormalise the tangent vector every this many time units (Benettin's scheme); by
        default it is renormalised whenever its norm leaves [1e-3, 1e3]. The tangent equations
        are linear, so both give the same exponent; the default restarts the solver far less.
    df1, df2 : callable, optional
        Curve derivatives; default: analytic for fitted curves (spline table / sympy),
        central differences for plain callables.
    evaluation : {"auto", "exact", "tabulated"}
        How fitted curves are evaluated (see :func:`charcurves.simulate.simulate_model`).

    Returns
    -------
    float
        The largest exponent: the mean log growth rate of the tangent vector (dx, dv), which
        obeys dx' = dv, dv' = -f1'(x') dv - f2'(x) dx, over ``t_total`` after the transient.

    Notes
    -----
    The tangent dynamics need differentiable curves: a model whose friction has a jump at
    zero velocity (dry friction) has no Lyapunov exponent in this sense.

    Examples
    --------
    The free oscillator x'' + 0.2 x' + x = 0 decays like exp(-0.1 t), so its exponent is -0.1:

    >>> from charcurves.metrics import largest_lyapunov_exponent
    >>> lam = largest_lyapunov_exponent(lambda v: 0.2 * v, lambda x: x, lambda t: 0.0, 1.0, 0.0,
    ...                                 t_transient=5.0, t_total=40.0)
    >>> round(float(lam), 2)
    -0.1
    """
    from scipy.integrate import solve_ivp

    f1s, d1 = _scalar_curve(f1, df1, evaluation)
    f2s, d2 = _scalar_curve(f2, df2, evaluation)
    g, b = float(gain), float(offset)

    def state_rhs(t, y):
        x, v = y.tolist()
        return [v, g * float(forcing(t)) - f1s(v) - f2s(x) - b]

    def full_rhs(t, y):
        x, v, dx, dv = y.tolist()
        return [v, g * float(forcing(t)) - f1s(v) - f2s(x) - b, dv, -d1(v) * dv - d2(x) * dx]

    y = np.array([x0, v0], dtype=float)
    if t_transient > 0:
        y = solve_ivp(state_rhs, (0.0, t_transient), y, method=method, rtol=rtol, atol=atol).y[:, -1]
    from ..simulate import solver_class

    solver_cls = solver_class(method)
    t, t_end = float(t_transient), float(t_transient + t_total)
    state = np.concatenate([y, [1.0, 0.0]])
    total_log = 0.0
    while t < t_end:
        # one solver run until the tangent needs renormalising (or the next fixed renormalisation)
        bound = t_end if renorm_every is None else min(t + float(renorm_every), t_end)
        solver = solver_cls(full_rhs, t, state, bound, rtol=rtol, atol=atol)
        while solver.status == "running":
            message = solver.step()
            if solver.status == "failed":
                raise SimulationError(f"the Lyapunov integration failed at t = {solver.t:.4g}: {message}")
            norm = float(np.hypot(solver.y[2], solver.y[3]))
            if renorm_every is None and not (1e-3 <= norm <= 1e3):
                break
        state = solver.y.copy()
        norm = float(np.hypot(state[2], state[3]))
        if not (np.isfinite(norm) and norm > 0):
            raise SimulationError(f"the tangent vector became {norm} at t = {solver.t:.4g}; the model has no "
                                  "finite Lyapunov exponent from this state")
        total_log += np.log(norm)
        state[2:] /= norm
        t = float(solver.t)
    return total_log / float(t_total)
