"""Forward integration of a fitted second-order model, bounded in time and state.

A learned model can blow up, leave the region where its curves were trained, or become so
stiff that the solver crawls. Each of these ends the run with a status instead of a hang:
"ok", "left_box" (the state left the allowed box), "diverged" (non-finite or huge state),
"timeout" (the wall-clock budget ran out) or "solver_failed" (the solver gave up, or the
stick-slip event loop exceeded its number of switches).

The solver is driven step by step (scipy's ``OdeSolver`` classes), so every accepted step is
checked against the state bounds and the time budget, and the samples computed before a
failure are kept; a run without events with LSODA (the default) is one ``scipy.integrate.odeint``
call over all samples instead (no Python work per internal step or per sample), run again from sample
to sample (``scipy.integrate.ode``, checked at every sample) where it leaves its bounds or fails, to
say where and why it stopped. A velocity curve with a jump at 0 (dry friction) is integrated with events:
slip phases with a fixed friction direction, sticking phases with ``x' = 0`` while the net
force stays within the friction limit (see ``docs/simulation.md``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np

from .._errors import ConfigError
from ._curve_eval import PreparedCurve, prepare_curve
from ._families import simulate_template_model
from ._result import STATUSES, SimulationResult, _Stop, sinusoidal_forcing, solver_class

__all__ = ["SimulationResult", "simulate_model", "sinusoidal_forcing", "prepare_model_curves", "STATUSES",
           "solver_class"]


def prepare_model_curves(model, *, evaluation: str = "auto", jump: str = "auto",
                         **options) -> tuple[PreparedCurve, PreparedCurve]:
    """The model's f1 (velocity curve, jump split off when present) and f2, ready for scalar use.

    ``options`` go to :func:`charcurves.simulate.prepare_curve` (e.g. ``table_rtol``, ``margin``).

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.simulate import prepare_model_curves
    >>> from charcurves.systems import get_system
    >>> f1, f2 = prepare_model_curves(cc.fit(get_system("duffing").simulate(), method="parametric", basis="f1=z; f2=z, z**3"))
    >>> f1.evaluation, round(f2.smooth(2.0), 6), round(f2.derivative(2.0), 6)
    ('exact', 6.0, 11.0)
    """
    f1 = prepare_curve(model.curves["f1"], evaluation=evaluation, jump=jump, **options)
    f2 = prepare_curve(model.curves["f2"], evaluation=evaluation, jump="smooth", split_jump=False, **options)
    return f1, f2


class _Output:
    """The requested samples, filled in time order as the run proceeds."""

    def __init__(self, t_eval: np.ndarray):
        self.t = t_eval
        self.x = np.full(t_eval.size, np.nan)
        self.v = np.full(t_eval.size, np.nan)
        self.filled = 0

    def _upto(self, t: float) -> int:
        return int(np.searchsorted(self.t, t, side="right"))

    def due(self, t: float) -> bool:
        """Whether samples up to ``t`` are still to be filled."""
        return self.filled < self.t.size and self.t[self.filled] <= t

    def dense(self, interp, t: float) -> None:
        end = self._upto(t)
        if end > self.filled:
            y = interp(self.t[self.filled:end])
            self.x[self.filled:end], self.v[self.filled:end] = y[0], y[1]
            self.filled = end

    def constant(self, x: float, t: float) -> None:
        end = self._upto(t)
        if end > self.filled:
            self.x[self.filled:end], self.v[self.filled:end] = x, 0.0
            self.filled = end


class _Run:
    """One simulation: the right-hand sides, the checks and the stick/slip loop."""

    def __init__(self, f1: PreparedCurve, f2: PreparedCurve, g: float, b: float, forcing, t_eval, solver,
                 rtol, atol, time_budget, box, max_abs, max_events, stick_step):
        self.f1, self.f2, self.g, self.b, self.forcing = f1, f2, g, b, forcing
        self.out = _Output(t_eval)
        self.t_final = float(t_eval[-1])
        self.solver, self.rtol, self.atol = solver, rtol, atol
        self.time_budget = float(time_budget)
        self.deadline = time.monotonic() + self.time_budget
        self.xb = box.get("x") if box else None
        self.vb = box.get("v") if box else None
        self.max_abs = float(max_abs)
        self.max_events = int(max_events)
        self.switches = 0
        self.stick_seconds = 0.0
        self.mu = float(f1.jump_height)
        if stick_step is None:
            spacing = float(np.min(np.diff(t_eval))) if t_eval.size > 1 else self.t_final - float(t_eval[0])
            stick_step = 0.25 * spacing if spacing > 0 else 1e-3
        self.stick_step = float(stick_step)
        self._vector_forcing = None

    # ---------------------------------------------------------------- checks
    def check_time(self, t: float) -> None:
        if time.monotonic() > self.deadline:
            raise _Stop("timeout", f"the time budget of {self.time_budget:g} s ran out at t = {t:.4g}", t)

    def check_state(self, t: float, x: float, v: float) -> None:
        m = self.max_abs
        if not (-m <= x <= m and -m <= v <= m):  # NaN fails every comparison
            raise _Stop("diverged", f"the state became non-finite or larger than {m:g} at t = {t:.4g}", t)
        xb, vb = self.xb, self.vb
        if xb is not None and not (xb[0] <= x <= xb[1]):
            raise _Stop("left_box", f"x = {x:.4g} left [{xb[0]:.4g}, {xb[1]:.4g}] at t = {t:.4g}", t)
        if vb is not None and not (vb[0] <= v <= vb[1]):
            raise _Stop("left_box", f"x' = {v:.4g} left [{vb[0]:.4g}, {vb[1]:.4g}] at t = {t:.4g}", t)

    def count_switch(self, t: float) -> None:
        self.switches += 1
        if self.switches > self.max_events:
            raise _Stop("solver_failed", f"more than {self.max_events} stick/slip switches before t = {t:.4g}; "
                        "the model chatters at zero velocity (raise max_events or check the friction curve)", t)

    # ---------------------------------------------------------------- forces
    def net_force_at_rest(self, t, x: float):
        """g F(t) - f2(x) - b - f1_smooth(0): what friction must hold for the mass to stay at rest."""
        return self.g * self._force(t) - self.f2.smooth(x) - self.b - self.f1.smooth(0.0)

    def _force(self, t):
        if np.ndim(t) == 0:
            return float(self.forcing(float(t)))
        if self._vector_forcing is None:
            try:
                probe = np.asarray(self.forcing(t), dtype=float)
                self._vector_forcing = probe.shape == np.shape(t)
            except Exception:  # a scalar-only callable (math.cos...)
                self._vector_forcing = False
        if self._vector_forcing:
            return np.asarray(self.forcing(t), dtype=float)
        return np.array([float(self.forcing(float(ti))) for ti in t])

    def rhs(self, direction: int):
        """Right-hand side; ``direction`` (+1/-1) fixes the sign of the jump term during a slip."""
        f1, f2, g, b, forcing = self.f1.smooth, self.f2.smooth, self.g, self.b, self.forcing
        jump = self.mu * direction
        m, run = self.max_abs, self
        clock = time.monotonic
        deadline = self.deadline

        def fun(t, y):
            x, v = y.tolist()
            if not (-m <= x <= m and -m <= v <= m):
                run.check_state(t, x, v)
            if clock() > deadline:
                run.check_time(t)
            return [v, g * forcing(t) - f1(v) - jump - f2(x) - b]

        return fun

    # ---------------------------------------------------------------- phases
    def slip(self, t0: float, x0: float, v0: float, direction: int):
        """Integrate until the end or, with a jump, until x' returns to 0 against ``direction``.

        Returns ("end" | "stopped" | "nowhere", t, x).
        """
        from scipy.optimize import brentq

        solver = self.solver(self.rhs(direction), t0, np.array([x0, v0], dtype=float), self.t_final,
                             rtol=self.rtol, atol=self.atol)
        s = direction
        while True:
            t_old, v_old = solver.t, float(solver.y[1])
            message = solver.step()
            if solver.status == "failed":
                raise _Stop("solver_failed", f"the solver failed at t = {solver.t:.4g}: {message}", solver.t)
            t_new = solver.t
            x_new, v_new = (float(u) for u in solver.y)
            self.check_state(t_new, x_new, v_new)
            if s != 0 and s * v_new <= 0.0:
                interp = solver.dense_output()
                t_lo = t_old if s * v_old > 0.0 else None
                if t_lo is None:  # the phase began at rest: find where the motion went the right way
                    for tt in np.linspace(t_old, t_new, 10)[1:-1]:
                        if s * float(interp(tt)[1]) > 0.0:
                            t_lo = float(tt)
                            break
                if t_lo is None:
                    return "nowhere", t_old, float(interp(t_old)[0])
                t_hit = t_new if v_new == 0.0 else brentq(lambda tt: float(interp(tt)[1]), t_lo, t_new,
                                                          xtol=1e-14, rtol=4 * np.finfo(float).eps)
                self.out.dense(interp, t_hit)
                return "stopped", t_hit, float(interp(t_hit)[0])
            if self.out.due(t_new):  # a step between two samples needs no interpolant
                self.out.dense(solver.dense_output(), t_new)
            if solver.status == "finished":
                return "end", t_new, x_new
            self.check_time(t_new)

    def free_odeint(self, t0: float, x0: float, v0: float) -> bool:
        """A run without events in one ``scipy.integrate.odeint`` call over all samples; False (nothing
        filled) where :meth:`free_lsoda` must decide instead.

        odeint drives the same LSODA as ``scipy.integrate.ode`` with the same settings and the same
        output times, so the samples are the same to the last bit, without a Python call per sample
        (about half the time of a validation case). A state out of bounds or a spent budget at a
        right-hand-side call raises there, which ends odeint at once. A spent budget ends the run as
        "timeout" at that time; after a state out of bounds, a solver failure, an exception or a sample
        outside the bounds, :meth:`free_lsoda` runs the case again from sample to sample and reports
        where and why it stopped (such a run costs up to twice its time, within the same budget)."""
        import warnings

        from scipy.integrate import ODEintWarning, odeint

        out = self.out
        if out.filled or out.t.size < 2 or float(out.t[0]) != t0:
            return False
        inner = self.rhs(0)  # raises "diverged" and "timeout" as in stepping
        fun = inner
        m = self.max_abs
        x_lo, x_hi = (max(-m, self.xb[0]), min(m, self.xb[1])) if self.xb is not None else (-m, m)
        v_lo, v_hi = (max(-m, self.vb[0]), min(m, self.vb[1])) if self.vb is not None else (-m, m)
        if self.xb is not None or self.vb is not None:
            def fun(t, y):  # leaving the box ends odeint early; the sample-by-sample run says where
                x, v = y.tolist()
                if not (x_lo <= x <= x_hi and v_lo <= v <= v_hi):
                    raise _Stop("left_box", "", t)
                return inner(t, y)

        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ODEintWarning)  # a failure is run again and reported there
                y, info = odeint(fun, [x0, v0], out.t, tfirst=True, rtol=self.rtol, atol=self.atol,
                                 mxstep=10**9, full_output=True)
        except _Stop as stop:  # odeint returns as soon as the right-hand side raises
            if stop.status == "timeout":
                raise
            return False
        except Exception:  # noqa: BLE001 - a curve or forcing that raises: the sample-by-sample run says where
            return False
        if info["message"] != "Integration successful.":
            return False
        x, v = y[:, 0], y[:, 1]
        if not (np.all((x >= x_lo) & (x <= x_hi)) and np.all((v >= v_lo) & (v <= v_hi))):
            return False
        out.x[:], out.v[:], out.filled = x, v, out.t.size
        return True

    def free_lsoda(self, t0: float, x0: float, v0: float) -> None:
        """A run without events by LSODA: :meth:`free_odeint` when it completes, else from sample to
        sample (``scipy.integrate.ode``: the solver steps in Fortran between samples, about twice as
        fast as stepping through ``scipy.integrate.LSODA``), with the state checked at every sample and
        at every right-hand-side call ("diverged", "timeout")."""
        from scipy.integrate import ode

        if self.free_odeint(t0, x0, v0):
            return

        solver = ode(self.rhs(0)).set_integrator("lsoda", rtol=self.rtol, atol=self.atol, nsteps=10**9)
        solver.set_initial_value([x0, v0], t0)
        out, t = self.out, self.out.t
        for i in range(out.filled, t.size):
            if t[i] <= t0:  # the initial sample
                out.x[i], out.v[i], out.filled = x0, v0, i + 1
                continue
            y = solver.integrate(float(t[i]))
            if not solver.successful():
                raise _Stop("solver_failed", f"the solver failed before t = {t[i]:.4g} (LSODA status "
                                             f"{solver.get_return_code()})", float(t[i - 1]))
            x, v = float(y[0]), float(y[1])
            self.check_state(float(t[i]), x, v)
            out.x[i], out.v[i], out.filled = x, v, i + 1
            self.check_time(float(t[i]))

    def stick(self, t_s: float, x_s: float):
        """Stay at rest from ``t_s`` until |net force| exceeds the jump height.

        Returns (t_breakaway, direction) or None when the mass sticks to the end.
        """
        from scipy.optimize import brentq

        mu, step = self.mu, self.stick_step
        base = self.f2.smooth(x_s) + self.b + self.f1.smooth(0.0)
        r = lambda tt: self.g * self._force(tt) - base  # noqa: E731
        clock0 = time.perf_counter()
        t_a = t_s
        while t_a < self.t_final:
            self.check_time(t_a)
            grid = np.minimum(t_a + step * np.arange(1, 513), self.t_final)
            values = r(grid)
            over = np.abs(values) > mu
            if over.any():
                i = int(np.argmax(over))
                t_hi = float(grid[i])
                t_lo = float(grid[i - 1]) if i else t_a
                s = 1 if values[i] > 0 else -1
                excess = lambda tt, s=s: s * float(r(tt)) - mu  # noqa: E731
                t_b = t_lo if excess(t_lo) >= 0.0 else brentq(excess, t_lo, t_hi, xtol=1e-14,
                                                                  rtol=4 * np.finfo(float).eps)
                # step just past the rounded root: the slip must start with a strict push
                nudge = 4.0 * math.ulp(max(abs(t_b), 1.0))
                while excess(t_b) <= 0.0 and t_b < t_hi:
                    t_b = min(t_b + nudge, t_hi)
                    nudge *= 2.0
                self.out.constant(x_s, t_b)
                self.stick_seconds += time.perf_counter() - clock0
                return t_b, s
            self.out.constant(x_s, float(grid[-1]))
            t_a = float(grid[-1])
        self.stick_seconds += time.perf_counter() - clock0
        return None

    def direction_at_rest(self, t: float, x: float) -> int:
        r = self.net_force_at_rest(t, x)
        return 0 if abs(r) <= self.mu else (1 if r > 0 else -1)

    def run(self, t0: float, x0: float, v0: float) -> None:
        self.check_state(t0, x0, v0)
        if t0 >= self.t_final:  # a single sample: the initial state
            self.out.x[0], self.out.v[0], self.out.filled = x0, v0, 1
            return
        if self.mu == 0.0:
            if getattr(self.solver, "__name__", "") == "LSODA":
                self.free_lsoda(t0, x0, v0)
            else:
                self.slip(t0, x0, v0, 0)
            return
        t, x = t0, x0
        mode = (1 if v0 > 0 else -1) if v0 != 0.0 else self.direction_at_rest(t, x)
        v = v0
        while True:
            if mode == 0:
                exit_ = self.stick(t, x)
                if exit_ is None:
                    return
                t, mode = exit_
                v = 0.0
                self.count_switch(t)
                continue
            kind, t_end, x_end = self.slip(t, x, v, mode)
            if kind == "end":
                return
            if kind == "nowhere":  # a grazing breakaway: stay at rest and look for the next one
                t, x, mode = t_end, x_end, 0
                self.count_switch(t)
                continue
            t, x, v = t_end, x_end, 0.0
            mode = self.direction_at_rest(t, x)
            self.count_switch(t)


def simulate_model(model, t_eval, x0: float, v0: float, forcing: Callable[[float], float], *,
                   method: str = "LSODA", rtol: float = 1e-8, atol: float = 1e-10,
                   time_budget: float = 60.0, box: dict | None = None, max_abs: float = 1e6,
                   evaluation: str = "auto", jump: str = "auto", max_events: int = 10_000,
                   stick_step: float | None = None, table_rtol: float = 1e-7) -> SimulationResult:
    """Integrate ``x'' = g F(t) - f1(x') - f2(x) - b`` of a fitted model from ``(x0, v0)``.

    Parameters
    ----------
    model : FittedModel
        Or any object with ``curves`` (``"f1"``, ``"f2"``), ``gain`` and ``offset``.
    t_eval : array_like
        Increasing sample times; the run starts at ``t_eval[0]``.
    x0, v0 : float
        Initial state.
    forcing : callable
        ``F(t)``; scalar calls during slip, vectorised calls (when it accepts arrays) while sticking.
    method : str
        A scipy ``OdeSolver``: "LSODA" (default), "RK45", "DOP853", "Radau", "BDF", "RK23".
    rtol, atol : float
        Solver tolerances.
    time_budget : float
        Wall-clock seconds for the whole run (status "timeout" beyond; checked at every
        right-hand-side call, every step and every sticking scan).
    box : dict, optional
        ``{"x": (lo, hi), "v": (lo, hi)}``: status "left_box" when an accepted step leaves it
        (e.g. the curves' training ranges, where a learned model has no support).
    max_abs : float
        Status "diverged" when |x| or |x'| exceeds it or becomes non-finite.
    evaluation : {"auto", "exact", "tabulated"}
        How curves are evaluated: "auto" tabulates network curves (a checked cubic spline, see
        :func:`charcurves.simulate.prepare_curve`) and evaluates closed forms exactly.
    jump : {"auto", "events", "smooth"}
        Dry friction in f1: "auto" integrates a sharp jump at zero velocity (a network's jump
        term or a symbolic ``c*tanh(k*v)``/``c*sign(v)`` with a width below 1e-3 of the velocity
        range) with stick/slip events; "events" does so for any jump term; "smooth" integrates
        the curve as it is.
    max_events : int
        Most stick/slip switches (status "solver_failed" beyond).
    stick_step : float, optional
        Time step at which a sticking phase scans the net force for the breakaway (refined by
        root finding); default a quarter of the output spacing.
    table_rtol : float
        Largest relative error a curve table may add (else the curve is evaluated exactly).

    Returns
    -------
    SimulationResult

    Raises
    ------
    ConfigError
        For an unknown ``method``, ``evaluation`` or ``jump``, or unusable ``t_eval``.

    Examples
    --------
    >>> import numpy as np
    >>> import charcurves as cc
    >>> from charcurves.simulate import simulate_model, sinusoidal_forcing
    >>> from charcurves.systems import get_system
    >>> system = get_system("duffing")
    >>> model = cc.fit(system.simulate(), method="parametric", basis="f1=z; f2=z, z**3")
    >>> t = np.linspace(0.0, 20.0, 401)
    >>> res = simulate_model(model, t, system.x0, system.v0, sinusoidal_forcing(system.A, system.Omega))
    >>> res.status, float(np.max(np.abs(res.x - system.simulate(t_eval=t).x))) < 1e-3
    ('ok', True)
    """
    if getattr(getattr(model, "template", None), "is_general", False):  # first-order, position-damping, two-dof...
        return simulate_template_model(model, t_eval, x0, v0, forcing, method=method, rtol=rtol, atol=atol,
                                       time_budget=time_budget, max_abs=max_abs)
    t_eval = np.asarray(t_eval, dtype=float).reshape(-1)
    if t_eval.size < 1 or not np.all(np.isfinite(t_eval)) or np.any(np.diff(t_eval) <= 0):
        raise ConfigError("t_eval must be finite, strictly increasing sample times; pass e.g. np.linspace(0, 80, 2001)")
    if int(max_events) < 1:
        raise ConfigError(f"max_events must be a positive integer, got {max_events!r}")
    if stick_step is not None and not (np.isfinite(stick_step) and stick_step > 0):
        raise ConfigError(f"stick_step must be a positive time step, got {stick_step!r}")
    solver = solver_class(method)
    t0 = time.perf_counter()
    f1, f2 = prepare_model_curves(model, evaluation=evaluation, jump=jump, table_rtol=table_rtol)
    run = _Run(f1, f2, float(model.gain), float(model.offset), forcing, t_eval, solver, float(rtol), float(atol),
               time_budget, box, max_abs, max_events, stick_step)
    details = {"f1": f1.evaluation, "f2": f2.evaluation, "jump_height": f1.jump_height,
               "events": f1.jump_height != 0.0, "prepare_seconds": time.perf_counter() - t0}
    status, message, t_end = "ok", "", float(t_eval[-1])
    try:
        run.run(float(t_eval[0]), float(x0), float(v0))
    except _Stop as stop:
        status, message, t_end = stop.status, stop.message, float(stop.t)
    details["stick_seconds"] = run.stick_seconds
    seconds = time.perf_counter() - t0
    n = run.out.filled if status != "timeout" else 0
    if status == "ok" and n < t_eval.size:  # cannot happen unless the solver stopped short silently
        status, message = "solver_failed", "the solver stopped before the last sample"
        t_end = float(t_eval[max(n - 1, 0)])
    return SimulationResult(t_eval[:n], run.out.x[:n], run.out.v[:n], status, message, t_end, seconds,
                            run.switches, details)
