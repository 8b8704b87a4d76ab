"""Free-run simulation driven by a *sampled* input: fixed-step RK4 on the sample grid.

Real records give the input u only at the sample times, so a free run has to say what u is
between samples (the *hold*):

* ``"linear"`` (first-order hold): u interpolated linearly between samples -- what
  :func:`~charcurves.simulate.simulate_model` sees with ``forcing = lambda t: np.interp(t, ts, us)``;
* ``"zoh"`` (zero-order hold): u constant over each sample interval, as a DAC outputs it;
* ``"bandlimited"``: u interpolated through its spectrum (FFT zero padding), the right choice for
  an input that is band-limited well below the Nyquist frequency.

The ODE ``x'' = g u - f1(x') - f2(x) - b`` is integrated by classical RK4 with ``substeps``
equal steps per sample interval. With ``substeps=1`` and the linear hold this is the
discrete-time "RK4 model" that system-identification papers often fit (one step per sample);
more sub-steps approach the exact solution of the ODE for that hold.

Why fixed steps instead of solve_ivp: at a few samples per period an adaptive solver spends
its time in Python calls of the right-hand side (50-130 s for 21 688 samples of the
Silverbox record, docs/silverbox.md), while a fixed-step loop on Python floats takes
~0.1 s, and the same loop over numpy arrays advances many candidate parameter sets or record
segments at once (what the output-error refinement needs for its Jacobians).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from .._errors import ConfigError, DataError
from ..data import HOLDS, check_hold, rk4_sampled, stage_inputs
from ._forward import SimulationResult

__all__ = ["HOLDS", "stage_inputs", "rk4_sampled", "simulate_sampled", "model_acceleration", "check_hold"]

#: Check for divergence and the time budget every this many samples (a check costs a few ops).
_CHECK_EVERY = 32


def model_acceleration(model) -> Callable:
    """``accel(x, v, u) = g u - f1(v) - f2(x) - b`` of a fitted model, fast on Python floats.

    Closed-form curves are compiled with ``math`` functions (a Python float in, a float out);
    other curves (neural) go through their numpy evaluation.
    """
    g, b = float(model.gain), float(model.offset)
    f1 = _float(model.curves["f1"])
    f2 = _float(model.curves["f2"])

    def accel(x, v, u):
        return g * u - f1(v) - f2(x) - b

    return accel


def simulate_sampled(model, u, x0: float, v0: float, *, dt: float | None = None, t=None, hold: str = "linear",
                     substeps: int = 1, max_abs: float = 1e6, time_budget: float = 60.0) -> SimulationResult:
    """Free run of a fitted model driven by a sampled input (fixed-step RK4, module docstring).

    Parameters
    ----------
    model : FittedModel
        Any object with ``curves`` ("f1", "f2"), ``gain`` and ``offset``.
    u : array (n,) or Trajectory
        The sampled input; a Trajectory gives its forcing ``F`` and its time step.
    x0, v0 : float
        State at the first sample.
    dt : float, optional
        Sample interval (or give ``t``, uniformly spaced sample times).
    hold : {"linear", "zoh", "bandlimited"}
        The input between samples.
    substeps : int
        RK4 steps per sample interval (1: the discrete-time RK4 model).
    max_abs : float
        |x| or |x'| above this ends the run with status "diverged".
    time_budget : float
        Seconds; status "timeout" when spent.

    Returns
    -------
    SimulationResult
        As :func:`simulate_model`: after "diverged" the samples before the failure, after
        "timeout" none.

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.curves import SymbolicFittedCurve
    >>> from charcurves.fitting import FittedModel
    >>> from charcurves.simulate import simulate_sampled
    >>> from charcurves.templates import get_template
    >>> curves = {"f1": SymbolicFittedCurve("f1", "x'", (-1, 1), "0.2*z"),
    ...           "f2": SymbolicFittedCurve("f2", "x", (-1, 1), "z")}
    >>> m = FittedModel(get_template("separable"), "demo", curves, 1.0, 0.0, 0.0)
    >>> res = simulate_sampled(m, np.zeros(200), 1.0, 0.0, dt=0.05, substeps=2)
    >>> res.status, round(float(res.x[-1]), 3)  # exact: exp(-0.995) (cos 9.90 + 0.1005 sin 9.90) = -0.3454
    ('ok', -0.346)
    """
    if hasattr(u, "F") and hasattr(u, "t"):
        traj = u
        traj.require_uniform("a sampled-input simulation")
        u, t = np.asarray(traj.F), np.asarray(traj.t)
    u = np.asarray(u, dtype=float).reshape(-1)
    if t is not None:
        t = np.asarray(t, dtype=float).reshape(-1)
        if t.shape != u.shape:
            raise DataError(f"t has {t.size} samples but u has {u.size}; give one time per input sample")
        steps = np.diff(t)
        if steps.size == 0 or np.any(steps <= 0) or np.max(np.abs(steps - np.median(steps))) > 1e-3 * np.median(steps):
            raise DataError("a sampled-input simulation needs uniformly spaced, increasing t; resample the record")
        dt = float(np.median(steps))
        t0 = float(t[0])
    else:
        if dt is None or not dt > 0:
            raise ConfigError(f"give the sample interval dt > 0 (or the sample times t), got dt={dt!r}")
        t0 = 0.0
    times = t0 + np.arange(u.size) * float(dt)
    ua, um, ub = stage_inputs(u, substeps, hold)
    started = time.perf_counter()
    x, v, status = rk4_sampled(model_acceleration(model), ua, um, ub, x0, v0, float(dt), substeps, max_abs=max_abs,
                               time_budget=time_budget)
    seconds = time.perf_counter() - started
    if status == "ok":
        return SimulationResult(times, x, v, "ok", "", float(times[-1]), seconds)
    good = np.isfinite(x) & np.isfinite(v)
    n_ok = int(np.argmin(good)) if not good.all() else good.size
    if status == "diverged":
        msg = f"the state became non-finite or larger than {max_abs:g} after t = {times[max(n_ok - 1, 0)]:.4g}"
    else:
        msg = f"the time budget of {time_budget:g} s ran out at t = {times[max(n_ok - 1, 0)]:.4g}"
        n_ok = 0  # as simulate_model: a run cut short by the clock says nothing about the model
    return SimulationResult(times[:n_ok], x[:n_ok], v[:n_ok], status, msg,
                            float(times[max(n_ok - 1, 0)]), seconds)


def _float(curve) -> Callable:
    return curve.float_function()
