"""Forward integration of a fitted second-order model, bounded in time and state.

A learned model can blow up, leave the region where its curves were trained, or become so
stiff that the solver crawls. Each of these ends the run with a status instead of a hang:
"ok", "left_box" (the state left the allowed box), "diverged" (non-finite or huge state),
"timeout" (the wall-clock budget ran out) or "solver_failed".
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable

import numpy as np

__all__ = ["SimulationResult", "simulate_model", "sinusoidal_forcing", "STATUSES"]

STATUSES = ("ok", "left_box", "diverged", "timeout", "solver_failed")


@dataclasses.dataclass
class SimulationResult:
    """Samples of a forward simulation; after a failure they stop at ``t_end_reached``."""

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    status: str
    message: str = ""
    t_end_reached: float = float("nan")
    seconds: float = 0.0

    @property
    def ok(self) -> bool:
        return self.status == "ok"


class _Stop(Exception):
    def __init__(self, status: str, message: str, t: float):
        super().__init__(message)
        self.status, self.message, self.t = status, message, t


def sinusoidal_forcing(A: float, Omega: float) -> Callable[[float], float]:
    """F(t) = A cos(Ω t)."""
    return lambda t: A * np.cos(Omega * t)


def _scalar(curve) -> Callable[[float], float]:
    fn = curve.numpy_function() if hasattr(curve, "numpy_function") else curve
    shift = getattr(curve, "shift", 0.0) if hasattr(curve, "numpy_function") else 0.0

    def f(z: float) -> float:
        return float(np.asarray(fn(np.array([z]))).reshape(-1)[0]) + shift

    return f


def simulate_model(model, t_eval, x0: float, v0: float, forcing: Callable[[float], float], *,
                   method: str = "LSODA", rtol: float = 1e-8, atol: float = 1e-10,
                   time_budget: float = 60.0, box: dict | None = None, max_abs: float = 1e6) -> SimulationResult:
    """Integrate ``x'' = g F(t) - f1(x') - f2(x) - b`` of a fitted model (or any object with
    ``curves``, ``gain``, ``offset``) from ``(x0, v0)``.

    ``box`` (``{"x": (lo, hi), "v": (lo, hi)}``) ends the run with status "left_box" when the
    state leaves it (e.g. the curves' training ranges, where a learned model has no support).
    """
    from scipy.integrate import solve_ivp

    t_eval = np.asarray(t_eval, dtype=float)
    f1 = _scalar(model.curves["f1"])
    f2 = _scalar(model.curves["f2"])
    g, b = float(model.gain), float(model.offset)
    deadline = time.monotonic() + float(time_budget)
    xb = box.get("x") if box else None
    vb = box.get("v") if box else None
    last_t = [float(t_eval[0])]

    def rhs(t, y):
        x, v = float(y[0]), float(y[1])
        last_t[0] = t
        if not (np.isfinite(x) and np.isfinite(v)) or abs(x) > max_abs or abs(v) > max_abs:
            raise _Stop("diverged", f"the state became non-finite or larger than {max_abs:g} at t = {t:.4g}", t)
        if xb is not None and not (xb[0] <= x <= xb[1]):
            raise _Stop("left_box", f"x = {x:.4g} left [{xb[0]:.4g}, {xb[1]:.4g}] at t = {t:.4g}", t)
        if vb is not None and not (vb[0] <= v <= vb[1]):
            raise _Stop("left_box", f"x' = {v:.4g} left [{vb[0]:.4g}, {vb[1]:.4g}] at t = {t:.4g}", t)
        if time.monotonic() > deadline:
            raise _Stop("timeout", f"the time budget of {time_budget:g} s ran out at t = {t:.4g}", t)
        return [v, g * forcing(t) - f1(v) - f2(x) - b]

    t0 = time.perf_counter()
    try:
        sol = solve_ivp(rhs, (t_eval[0], t_eval[-1]), [float(x0), float(v0)], method=method, t_eval=t_eval,
                        rtol=rtol, atol=atol)
    except _Stop as stop:
        return _partial(model, t_eval, x0, v0, forcing, stop, method, rtol, atol, time.perf_counter() - t0)
    seconds = time.perf_counter() - t0
    if not sol.success:
        n = sol.t.size
        return SimulationResult(t_eval[:n], sol.y[0], sol.y[1], "solver_failed", sol.message,
                                float(sol.t[-1]) if n else float(t_eval[0]), seconds)
    return SimulationResult(t_eval, sol.y[0], sol.y[1], "ok", "", float(t_eval[-1]), seconds)


def _partial(model, t_eval, x0, v0, forcing, stop, method, rtol, atol, seconds):
    """After a stop, the samples up to the failure time (re-integrated to that time; bounded)."""
    from scipy.integrate import solve_ivp

    keep = t_eval < stop.t
    if keep.sum() < 2 or stop.status == "timeout":
        n = int(keep.sum()) if stop.status != "timeout" else 0
        return SimulationResult(t_eval[:n], np.full(n, np.nan), np.full(n, np.nan), stop.status, stop.message,
                                stop.t, seconds)
    f1 = _scalar(model.curves["f1"])
    f2 = _scalar(model.curves["f2"])
    g, b = float(model.gain), float(model.offset)
    te = t_eval[keep]
    sol = solve_ivp(lambda t, y: [y[1], g * forcing(t) - f1(y[1]) - f2(y[0]) - b], (te[0], te[-1]),
                    [float(x0), float(v0)], method=method, t_eval=te, rtol=rtol, atol=atol)
    n = sol.t.size
    return SimulationResult(te[:n], sol.y[0], sol.y[1], stop.status, stop.message, stop.t, seconds)
