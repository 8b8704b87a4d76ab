"""Metrics of forward simulations: separation time, trajectory RMSE, largest Lyapunov exponent."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = ["separation_time", "trajectory_rmse", "largest_lyapunov_exponent"]


def separation_time(t, x_model, x_true, *, eps: float = 0.2) -> tuple[float, bool]:
    """First time with ``|x_model - x_true| > eps`` (strict, as the authors' scripts) and whether
    the value is censored (never separated: the last available time is returned)."""
    t = np.asarray(t, dtype=float)
    n = min(len(x_model), len(x_true), len(t))
    d = np.abs(np.asarray(x_model[:n], dtype=float) - np.asarray(x_true[:n], dtype=float))
    d[~np.isfinite(d)] = np.inf
    above = np.flatnonzero(d > eps)
    if above.size:
        return float(t[above[0]]), False
    return float(t[n - 1]) if n else float("nan"), True


def trajectory_rmse(x_model, x_true) -> float:
    """Root-mean-square difference over the samples both trajectories have."""
    n = min(len(x_model), len(x_true))
    d = np.asarray(x_model[:n], dtype=float) - np.asarray(x_true[:n], dtype=float)
    return float(np.sqrt(np.mean(d * d))) if n else float("nan")


def _derivative(f: Callable, h_rel: float = 1e-6) -> Callable:
    def df(z):
        z = np.asarray(z, dtype=float)
        h = h_rel * np.maximum(1.0, np.abs(z))
        return (np.asarray(f(z + h)) - np.asarray(f(z - h))) / (2 * h)

    return df


def largest_lyapunov_exponent(f1: Callable, f2: Callable, forcing: Callable, x0: float, v0: float, *,
                              gain: float = 1.0, t_transient: float = 100.0, t_total: float = 2000.0,
                              renorm_every: float = 1.0, rtol: float = 1e-9, atol: float = 1e-11,
                              df1: Callable | None = None, df2: Callable | None = None) -> float:
    """Benettin's method with the variational (tangent) equations of ``x'' = g F - f1(x') - f2(x)``.

    The tangent vector (dx, dv) obeys dx' = dv, dv' = -f1'(x') dv - f2'(x) dx; it is
    renormalised every ``renorm_every`` time units and the mean log growth rate over
    ``t_total`` (after a transient) is the largest exponent. Curve derivatives default to
    central differences, so any callable curve (a truth, a fitted network) works.
    """
    from scipy.integrate import solve_ivp

    df1 = df1 or _derivative(f1)
    df2 = df2 or _derivative(f2)

    def state_rhs(t, y):
        return [y[1], gain * forcing(t) - float(np.asarray(f1(y[1]))) - float(np.asarray(f2(y[0])))]

    def full_rhs(t, y):
        x, v, dx, dv = y
        a = gain * forcing(t) - float(np.asarray(f1(v))) - float(np.asarray(f2(x)))
        return [v, a, dv, -float(np.asarray(df1(v))) * dv - float(np.asarray(df2(x))) * dx]

    y = np.array([x0, v0], dtype=float)
    if t_transient > 0:
        y = solve_ivp(state_rhs, (0.0, t_transient), y, method="LSODA", rtol=rtol, atol=atol).y[:, -1]
    state = np.concatenate([y, [1.0, 0.0]])
    t, total_log = t_transient, 0.0
    n = int(round(t_total / renorm_every))
    for _ in range(n):
        sol = solve_ivp(full_rhs, (t, t + renorm_every), state, method="LSODA", rtol=rtol, atol=atol)
        state = sol.y[:, -1]
        norm = float(np.hypot(state[2], state[3]))
        total_log += np.log(norm)
        state[2:] /= norm
        t += renorm_every
    return total_log / (n * renorm_every)
