"""A forced mass on a spring with viscous damping and Coulomb (dry) friction."""

from __future__ import annotations

import dataclasses
import math
from typing import Any, ClassVar

import numpy as np

from .._errors import ConfigError, DataError, SimulationError
from ..data import Trajectory
from ._base import BenchmarkSystem, solver_failed

__all__ = ["StickSlip", "FRICTION_LAWS"]

#: How the sign of the velocity enters the friction force.
FRICTION_LAWS = ("coulomb", "tanh")

_COMMON = {"k": 1.274, "c": 0.386, "mu_N": 0.801, "A": 2.0, "x0": -0.076, "v0": 0.146, "tanh_scale": 500.0}


@dataclasses.dataclass(frozen=True, kw_only=True)
class StickSlip(BenchmarkSystem):
    """Stick-slip oscillator ``x'' + c x' + μN sgn(x') + k x = A cos(Ω t)``.

    Notes
    -----
    Variants:

    ``"paper"`` (default)
        Ω = 0.363 and true Coulomb friction with sticking: the motion is integrated piecewise,
        switching between slip (fixed direction, an event stops it where x' = 0) and stick
        (x' = 0, x'' = 0 while |F − k x| ≤ μN; the exit time is solved from the cosine forcing
        in closed form).
    ``"smooth"``
        Ω = 0.363 with sgn(v) replaced by tanh(500 v) everywhere (curves, ODE, acceleration).
    ``"scripts"``
        Ω = 0.3 and tanh(500 v) with LSODA's default tolerances (the authors' scripts).

    ``"paper"`` and ``"smooth"`` use tight tolerances (rtol 1e-10, atol 1e-12; LSODA handles
    the stiff tanh law at that setting in ~0.05 s).

    All: k = 1.274, c = 0.386, μN = 0.801, A = 2, x0 = −0.076, v0 = 0.146. ``friction``
    (``"coulomb"`` or ``"tanh"``) and ``tanh_scale`` can be overridden independently.

    Examples
    --------
    >>> from charcurves.systems import StickSlip
    >>> system = StickSlip()
    >>> round(float(system.f1(0.5)), 3), system.friction
    (0.994, 'coulomb')
    >>> record = system.simulate()
    >>> int(system.sticking_mask(record).sum()) > 0
    True
    """

    name: ClassVar[str] = "stick-slip"
    VARIANTS: ClassVar[dict[str, dict[str, Any]]] = {
        "paper": {"Omega": 0.363, "friction": "coulomb", "tolerance": "tight", **_COMMON},
        "smooth": {"Omega": 0.363, "friction": "tanh", "tolerance": "tight", **_COMMON},
        "scripts": {"Omega": 0.3, "friction": "tanh", "tolerance": "scipy-default", **_COMMON},
    }
    _PARAMETER_FIELDS: ClassVar[tuple[str, ...]] = ("k", "c", "mu_N", "A", "Omega", "x0", "v0")

    k: float | None = None
    c: float | None = None
    mu_N: float | None = None
    friction: str | None = None
    tanh_scale: float | None = None
    #: Most stick/slip switches one simulation may take (guards against chattering loops).
    max_switches: int = 10_000

    # ------------------------------------------------------------------ configuration
    def _validate(self) -> None:
        if self.friction not in FRICTION_LAWS:
            raise ConfigError(
                f"unknown friction law {self.friction!r}; choose one of {', '.join(map(repr, FRICTION_LAWS))}"
            )
        assert self.mu_N is not None  # __post_init__ filled the fields from the variant
        if self.mu_N < 0:
            raise ConfigError(f"mu_N (the friction force) must be >= 0, got {self.mu_N}")
        scale = self.tanh_scale
        if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not (math.isfinite(scale) and scale > 0):
            raise ConfigError(f"tanh_scale must be a positive number, got {scale!r}")
        if isinstance(self.max_switches, bool) or not isinstance(self.max_switches, int) or self.max_switches < 1:
            raise ConfigError(f"max_switches must be a positive integer, got {self.max_switches!r}")

    def parameters(self) -> dict[str, float]:
        params = super().parameters()
        if self.friction == "tanh":
            assert self.tanh_scale is not None
            params["tanh_scale"] = float(self.tanh_scale)
        return params

    # ------------------------------------------------------------------ curves
    def _sign(self, v: np.ndarray) -> np.ndarray:
        return np.sign(v) if self.friction == "coulomb" else np.tanh(self.tanh_scale * v)

    def f1(self, v: Any) -> np.ndarray:
        """Friction curve f1(v) = c v + μN sgn(v), with sgn(0) = 0 (or tanh(scale·v))."""
        v = np.asarray(v, dtype=float)
        return self.c * v + self.mu_N * self._sign(v)

    def f2(self, x: Any) -> np.ndarray:
        """Spring curve f2(x) = k x."""
        return self.k * np.asarray(x, dtype=float)

    def acceleration(self, t: Any, x: Any, v: Any) -> np.ndarray:
        """x'' from the equation of motion (vectorised).

        For Coulomb friction at v = 0 the static friction balances the net force while
        |F − k x| ≤ μN (x'' = 0, the mass sticks); beyond that the mass starts to slip.
        """
        v = np.asarray(v, dtype=float)
        if self.friction == "tanh":
            return super().acceleration(t, x, v)
        r = self.forcing(t) - self.f2(x)
        slip = r - self.c * v - self.mu_N * np.sign(v)
        start = np.where(np.abs(r) <= self.mu_N, 0.0, r - self.mu_N * np.sign(r))
        return np.where(v == 0, start, slip)

    def sticking_mask(self, traj: Trajectory) -> np.ndarray:
        """Samples where the mass sticks (v and x'' exactly 0); all False for the tanh law.

        A sample at rest with x'' ≠ 0 (a start from rest, a breakaway) is slipping.

        Raises
        ------
        DataError
            If ``traj`` has no velocity (e.g. after state noise).
        """
        if traj.v is None:
            raise DataError("sticking_mask needs the velocity of the trajectory; use a clean simulated record")
        if self.friction == "tanh":
            return np.zeros(traj.n_samples, dtype=bool)
        mask = np.asarray(traj.v == 0.0)
        if traj.a is not None:
            mask &= traj.a == 0.0
        return mask

    # ------------------------------------------------------------------ simulation
    def _integrate(self, t_eval: np.ndarray, rtol: float, atol: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if self.friction == "tanh":
            return self._integrate_smooth(t_eval, rtol, atol)
        return self._integrate_coulomb(t_eval, rtol, atol)

    def _integrate_smooth(self, t_eval, rtol, atol):
        A, Om, c, muN, k, sc = self.A, self.Omega, self.c, self.mu_N, self.k, self.tanh_scale

        def rhs(t: float, y: np.ndarray) -> list[float]:
            x, v = float(y[0]), float(y[1])
            return [v, A * math.cos(Om * t) - c * v - muN * math.tanh(sc * v) - k * x]

        from scipy.integrate import solve_ivp  # lazily: importing the systems stays light
        sol = solve_ivp(
            rhs, (t_eval[0], t_eval[-1]), [self.x0, self.v0], method="LSODA",
            t_eval=t_eval, rtol=rtol, atol=atol,
        )
        if not sol.success or sol.y.shape[1] != t_eval.size:
            raise solver_failed(self.name, sol.message)
        x, v = sol.y
        return x, v, self.acceleration(t_eval, x, v)

    def _stick_exit(self, t_s: float, x_s: float, strict: bool = False) -> tuple[float, int] | None:
        """First time after ``t_s`` at which a mass stuck at ``x_s`` breaks away, and the direction.

        The mass breaks away where |A cos(Ω t) − k x_s| rises through μN; with the cosine
        forcing those crossings have a closed form, which avoids root finding on a step grid
        (that could miss short excursions) and integrating a motionless phase.
        """
        assert self.A is not None and self.Omega is not None and self.k is not None and self.mu_N is not None
        A, W, kx, muN = self.A, abs(self.Omega), self.k * x_s, self.mu_N
        if A == 0.0 or W == 0.0:
            return None  # constant force: stuck now means stuck forever
        period = 2.0 * math.pi / W
        # A root rounded to just before t_s still counts (the mass breaks away at once).
        earliest = t_s + 1e-9 * period if strict else t_s - 1e-9 * period
        candidates: list[tuple[float, int]] = []
        for s in (1, -1):
            ratio = (kx + s * muN) / A
            if abs(ratio) > 1.0:
                continue
            theta = math.acos(ratio)
            for phase in (theta, -theta):
                n0 = math.ceil((W * t_s - phase) / (2.0 * math.pi))
                for n in (n0 - 1, n0, n0 + 1):
                    t = (phase + 2.0 * math.pi * n) / W
                    if earliest < t <= t_s + 1.01 * period:
                        candidates.append((t, s))
        for t, s in sorted(candidates):
            # Breakaway only where s (F − k x) grows through μN (not at a tangency / an entry).
            if s * (-A * W * math.sin(W * t)) <= 0.0:
                continue
            # Step just past the rounded root so the slip starts with strict s·x'' > 0: the
            # slip's v = 0 event then cannot fire at its own start (no zero-length segment).
            t = max(t, t_s)
            step = 4.0 * math.ulp(max(abs(t), 1.0))
            while s * (A * math.cos(W * t) - kx) - muN <= 0.0 and step < 1e-8 * period:
                t += step
                step *= 2.0
            if s * (A * math.cos(W * t) - kx) - muN > 0.0:
                return t, s
        return None  # |F − k x_s| never exceeds μN: stuck for good

    def _integrate_coulomb(self, t_eval, rtol, atol):
        A, Om, c, muN, k = self.A, self.Omega, self.c, self.mu_N, self.k
        n = t_eval.size
        t_final = float(t_eval[-1])
        x_out = np.empty(n)
        v_out = np.empty(n)
        a_out = np.empty(n)
        filled = 0  # samples t_eval[:filled] are done

        def fill_until(t_stop: float, last: bool) -> slice:
            nonlocal filled
            end = n if last else int(np.searchsorted(t_eval, t_stop, side="left"))
            rows = slice(filled, max(end, filled))
            filled = rows.stop
            return rows

        def direction_after_rest(t: float, x: float) -> int:
            """0 to stick, else the direction of slip for a mass at rest at (t, x)."""
            r = A * math.cos(Om * t) - k * x
            return 0 if abs(r) <= muN else (1 if r > 0 else -1)

        t, x, v = float(t_eval[0]), float(self.x0), float(self.v0)
        mode = (1 if v > 0 else -1) if v != 0.0 else direction_after_rest(t, x)
        switches = 0
        strict = False  # set after a slip from rest that went nowhere
        while filled < n:
            if switches > self.max_switches:
                raise SimulationError(
                    f"stick-slip simulation switched between sticking and slipping more than "
                    f"{self.max_switches} times before t = {t:.6g}; check the parameters or raise max_switches"
                )
            switches += 1
            if mode == 0:  # stick: v = 0, x'' = 0 until the net force overcomes μN
                exit_ = self._stick_exit(t, x, strict)
                strict = False
                last = exit_ is None or exit_[0] >= t_final
                rows = fill_until(t_final if last else exit_[0], last)
                x_out[rows], v_out[rows], a_out[rows] = x, 0.0, 0.0
                if last:
                    break
                t, mode = exit_
                v = 0.0
                continue

            s = mode

            # Slip in a fixed direction: a smooth linear ODE; sgn(v) never evaluated at v ≈ 0.
            def rhs(tt: float, y: np.ndarray, s: int = s) -> list[float]:
                return [float(y[1]), A * math.cos(Om * tt) - c * float(y[1]) - muN * s - k * float(y[0])]

            def stopped(tt: float, y: np.ndarray) -> float:
                return float(y[1])

            stopped.terminal = True
            stopped.direction = -s  # only v leaving the slip direction; v = 0 at a restart is ignored
            from scipy.integrate import solve_ivp  # lazily: importing the systems stays light
            sol = solve_ivp(
                rhs, (t, t_final), [x, v], method="LSODA", dense_output=True,
                events=stopped, rtol=rtol, atol=atol,
            )
            if sol.status == -1:
                raise solver_failed(self.name, sol.message)
            hit = sol.status == 1 and sol.t_events[0].size > 0
            t_stop = float(sol.t_events[0][0]) if hit else t_final
            rows = fill_until(t_stop, not hit)
            tt = t_eval[rows]
            if tt.size:
                xx, vv = sol.sol(tt)
                x_out[rows], v_out[rows] = xx, vv
                a_out[rows] = A * np.cos(Om * tt) - c * vv - muN * s - k * xx
            if not hit:
                break
            if t_stop <= t and v == 0.0:
                # A breakaway that went nowhere (grazing |F − k x| = μN): stay stuck and look
                # for the next breakaway, instead of restarting at the same instant forever.
                mode, strict = 0, True
                continue
            t, x, v = t_stop, float(sol.y_events[0][0][0]), 0.0
            mode = direction_after_rest(t, x)
        return x_out, v_out, a_out
