"""Benchmark systems of the families beyond separable: position-dependent damping (a forced
Van der Pol-type oscillator), a first-order system, and a coupled two-degree-of-freedom pair.

Each has known curves (``true_curves()``), the name of the family that describes it
(``family``) and ``simulate()`` with LSODA at tight tolerances.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Callable
from typing import Any, ClassVar

import numpy as np

from .._errors import ConfigError, SimulationError
from ._base import BenchmarkSystem, sample_times, solver_failed

__all__ = ["VanDerPolDamping", "FirstOrderSystem", "TwoDOF", "corrupt_forces"]


@dataclasses.dataclass(frozen=True, kw_only=True)
class VanDerPolDamping(BenchmarkSystem):
    """Forced Van der Pol-type oscillator with a hardening spring (position-dependent damping):

    ``x'' + mu (x^2 - 1) x' + alpha x + beta x^3 = A cos(Omega t)``, i.e. the family
    ``x'' + f1(x) x' + f2(x) = F`` with ``f1(x) = mu (x^2 - 1)`` and ``f2(x) = alpha x + beta x^3``.

    Variant ``"paper"`` (the only one): mu = 1, alpha = 1, beta = 0.5, A = 1.2, Omega = 1.3,
    x0 = 0.5, v0 = 0 (a quasi-periodic response that covers |x| up to about 2 in 40 time units).

    Examples
    --------
    >>> from charcurves.systems import VanDerPolDamping
    >>> s = VanDerPolDamping()
    >>> float(s.f1(1.0)), s.family
    (0.0, 'position-damping')
    """

    name: ClassVar[str] = "van-der-pol"
    family: ClassVar[str] = "position-damping"
    VARIANTS: ClassVar[dict[str, dict[str, Any]]] = {
        "paper": {"mu": 1.0, "alpha": 1.0, "beta": 0.5, "A": 1.2, "Omega": 1.3, "x0": 0.5, "v0": 0.0,
                  "tolerance": "tight"},
    }
    _PARAMETER_FIELDS: ClassVar[tuple[str, ...]] = ("mu", "alpha", "beta", "A", "Omega", "x0", "v0")

    mu: float | None = None
    alpha: float | None = None
    beta: float | None = None

    def f1(self, x: Any) -> np.ndarray:
        """Position-dependent damping coefficient f1(x) = mu (x^2 - 1) (multiplies x')."""
        x = np.asarray(x, dtype=float)
        return self.mu * (x**2 - 1.0)

    def f2(self, x: Any) -> np.ndarray:
        """Stiffness f2(x) = alpha x + beta x^3."""
        x = np.asarray(x, dtype=float)
        return self.alpha * x + self.beta * x**3

    def acceleration(self, t: Any, x: Any, v: Any) -> np.ndarray:
        return self.forcing(t) - self.f1(x) * np.asarray(v, dtype=float) - self.f2(x)

    def _integrate(self, t_eval, rtol, atol):
        A, Om, mu, al, be = self.A, self.Omega, self.mu, self.alpha, self.beta

        def rhs(t: float, y: np.ndarray) -> list[float]:
            x, v = float(y[0]), float(y[1])
            return [v, A * math.cos(Om * t) - mu * (x * x - 1.0) * v - al * x - be * x**3]

        from scipy.integrate import solve_ivp

        sol = solve_ivp(rhs, (t_eval[0], t_eval[-1]), [self.x0, self.v0], method="LSODA", t_eval=t_eval,
                        rtol=rtol, atol=atol)
        if not sol.success or sol.y.shape[1] != t_eval.size:
            raise solver_failed(self.name, sol.message)
        x, v = sol.y
        return x, v, self.acceleration(t_eval, x, v)


@dataclasses.dataclass(frozen=True, kw_only=True)
class FirstOrderSystem(BenchmarkSystem):
    """First-order system ``f1(x) + f2(x) x' = A cos(Omega t) + B cos(Omega2 t)`` (the family
    "first-order"): ``f1(x) = k x + c x^3`` (restoring), ``f2(x) = r0 + r2 x^2`` (a
    position-dependent resistance, kept positive so that x' is defined).

    Variant ``"paper"``: k = 1, c = 0.5, r0 = 0.5, r2 = 1, A = 2, Omega = 0.8, B = 1, Omega2 = 2.3,
    x0 = 0.5. Two forcing frequencies make the record visit each x with several velocities (on
    a single-frequency limit cycle x' is nearly a function of x, which leaves f1 and f2 poorly
    separated). ``v0`` is not used (x' follows from the equation); the simulated ``a`` is the
    exact time derivative of x'.

    Examples
    --------
    >>> from charcurves.systems import FirstOrderSystem
    >>> FirstOrderSystem().family
    'first-order'
    """

    name: ClassVar[str] = "first-order"
    family: ClassVar[str] = "first-order"
    VARIANTS: ClassVar[dict[str, dict[str, Any]]] = {
        "paper": {"k": 1.0, "c": 0.5, "r0": 0.5, "r2": 1.0, "A": 2.0, "Omega": 0.8, "B": 1.0, "Omega2": 2.3,
                  "x0": 0.5, "v0": 0.0, "tolerance": "tight"},
    }
    _PARAMETER_FIELDS: ClassVar[tuple[str, ...]] = ("k", "c", "r0", "r2", "A", "Omega", "B", "Omega2", "x0", "v0")

    k: float | None = None
    c: float | None = None
    r0: float | None = None
    r2: float | None = None
    B: float | None = None
    Omega2: float | None = None

    def forcing(self, t: Any) -> np.ndarray:
        """F(t) = A cos(Omega t) + B cos(Omega2 t)."""
        t = np.asarray(t, dtype=float)
        return self.A * np.cos(self.Omega * t) + self.B * np.cos(self.Omega2 * t)

    def _validate(self) -> None:
        assert self.r0 is not None and self.r2 is not None  # __post_init__ filled the fields from the variant
        if self.r0 <= 0 or self.r2 < 0:
            raise ConfigError(f"f2(x) = r0 + r2 x^2 must stay positive: need r0 > 0 and r2 >= 0, got r0={self.r0}, "
                              f"r2={self.r2}")

    def f1(self, x: Any) -> np.ndarray:
        """Restoring curve f1(x) = k x + c x^3."""
        x = np.asarray(x, dtype=float)
        return self.k * x + self.c * x**3

    def f2(self, x: Any) -> np.ndarray:
        """Resistance f2(x) = r0 + r2 x^2 (multiplies x')."""
        x = np.asarray(x, dtype=float)
        return self.r0 + self.r2 * x**2

    def velocity(self, t: Any, x: Any) -> np.ndarray:
        return (self.forcing(t) - self.f1(x)) / self.f2(x)

    def acceleration(self, t: Any, x: Any, v: Any) -> np.ndarray:
        """d/dt of x' = (F - f1(x)) / f2(x), by the chain rule."""
        t = np.asarray(t, dtype=float)
        x = np.asarray(x, dtype=float)
        v = np.asarray(v, dtype=float)
        assert self.A is not None and self.Omega is not None and self.B is not None and self.Omega2 is not None
        assert self.k is not None and self.c is not None and self.r2 is not None
        dF = -self.A * self.Omega * np.sin(self.Omega * t) - self.B * self.Omega2 * np.sin(self.Omega2 * t)
        df1 = self.k + 3 * self.c * x**2
        df2 = 2 * self.r2 * x
        f2 = self.f2(x)
        return (dF - df1 * v) / f2 - (self.forcing(t) - self.f1(x)) * df2 * v / f2**2

    def _integrate(self, t_eval, rtol, atol):
        from scipy.integrate import solve_ivp

        A, Om, B, Om2, k, c, r0, r2 = self.A, self.Omega, self.B, self.Omega2, self.k, self.c, self.r0, self.r2

        def rhs(t: float, y: np.ndarray) -> list[float]:
            x = float(y[0])
            return [(A * math.cos(Om * t) + B * math.cos(Om2 * t) - k * x - c * x**3) / (r0 + r2 * x * x)]

        sol = solve_ivp(rhs, (t_eval[0], t_eval[-1]), [self.x0], method="LSODA", t_eval=t_eval, rtol=rtol, atol=atol)
        if not sol.success or sol.y.shape[1] != t_eval.size:
            raise solver_failed(self.name, sol.message)
        x = sol.y[0]
        v = self.velocity(t_eval, x)
        return x, v, self.acceleration(t_eval, x, v)


@dataclasses.dataclass(frozen=True, kw_only=True)
class TwoDOF:
    """Two masses coupled by a nonlinear spring, each with its own nonlinear damper:

    ``x1'' + f1(x1') + f2(x1 - x2) = A1 cos(Omega1 t)``,
    ``x2'' + f3(x2') + f4(x2 - x1) = A2 cos(Omega2 t)``

    with ``f1(v) = c1 v + d1 v^3``, ``f3(v) = c3 v + d3 v^3``, the coupling
    ``f2(z) = k z + q z^2 + k3 z^3`` and its reaction ``f4(z) = -f2(-z)`` (Newton's third law;
    the quadratic term makes f2 and f4 different curves).

    Variant ``"paper"``: c1 = 0.3, d1 = 0.05, c3 = 0.2, d3 = 0.1, k = 1, q = 0.3, k3 = 0.5,
    A1 = 1, Omega1 = 0.9, A2 = 0.7, Omega2 = 1.7, initial state (0.5, 0, -0.3, 0).

    Examples
    --------
    >>> from charcurves.systems import TwoDOF
    >>> s = TwoDOF()
    >>> sorted(s.true_curves())
    ['f1', 'f2', 'f3', 'f4']
    """

    name: ClassVar[str] = "two-dof"
    family: ClassVar[str] = "two-dof"
    VARIANTS: ClassVar[dict[str, dict[str, Any]]] = {
        "paper": {"c1": 0.3, "d1": 0.05, "c3": 0.2, "d3": 0.1, "k": 1.0, "q": 0.3, "k3": 0.5, "A1": 1.0,
                  "Omega1": 0.9, "A2": 0.7, "Omega2": 1.7, "x10": 0.5, "v10": 0.0, "x20": -0.3, "v20": 0.0},
    }
    _PARAMETER_FIELDS: ClassVar[tuple[str, ...]] = ("c1", "d1", "c3", "d3", "k", "q", "k3", "A1", "Omega1", "A2",
                                                     "Omega2", "x10", "v10", "x20", "v20")

    variant: str = "paper"
    c1: float | None = None
    d1: float | None = None
    c3: float | None = None
    d3: float | None = None
    k: float | None = None
    q: float | None = None
    k3: float | None = None
    A1: float | None = None
    Omega1: float | None = None
    A2: float | None = None
    Omega2: float | None = None
    x10: float | None = None
    v10: float | None = None
    x20: float | None = None
    v20: float | None = None
    rtol: float = 1e-10
    atol: float = 1e-12

    def __post_init__(self) -> None:
        if self.variant not in self.VARIANTS:
            raise ConfigError(f"unknown {self.name} variant {self.variant!r}; choose one of "
                              f"{', '.join(map(repr, self.VARIANTS))}")
        for key in self._PARAMETER_FIELDS:
            val = getattr(self, key)
            if val is None:
                val = self.VARIANTS[self.variant][key]
            if isinstance(val, bool) or not isinstance(val, numbers.Real) or not math.isfinite(val):
                raise ConfigError(f"{key} must be a finite real number, got {val!r}")
            object.__setattr__(self, key, float(val))

    def f1(self, v):
        v = np.asarray(v, dtype=float)
        return self.c1 * v + self.d1 * v**3

    def f3(self, v):
        v = np.asarray(v, dtype=float)
        return self.c3 * v + self.d3 * v**3

    def f2(self, z):
        z = np.asarray(z, dtype=float)
        return self.k * z + self.q * z**2 + self.k3 * z**3

    def f4(self, z):
        return -self.f2(-np.asarray(z, dtype=float))

    def true_curves(self) -> dict[str, Callable]:
        return {"f1": self.f1, "f2": self.f2, "f3": self.f3, "f4": self.f4}

    def parameters(self) -> dict[str, float]:
        return {key: float(getattr(self, key)) for key in self._PARAMETER_FIELDS}

    def forcing(self, t) -> dict[str, np.ndarray]:
        t = np.asarray(t, dtype=float)
        return {"F1": self.A1 * np.cos(self.Omega1 * t), "F2": self.A2 * np.cos(self.Omega2 * t)}

    def simulate(self, t_end: float = 60.0, n_points: int = 1500, *, t_eval=None):
        """Integrate with LSODA; returns a MultiTrajectory with x1, x2, F1, F2 and exact derivatives."""
        from scipy.integrate import solve_ivp

        from ..data import MultiTrajectory

        times = sample_times(t_end, n_points, t_eval)
        p = self

        def rhs(t, y):
            x1, v1, x2, v2 = (float(u) for u in y)
            z = x1 - x2
            spring = p.k * z + p.q * z * z + p.k3 * z**3
            a1 = p.A1 * math.cos(p.Omega1 * t) - (p.c1 * v1 + p.d1 * v1**3) - spring
            a2 = p.A2 * math.cos(p.Omega2 * t) - (p.c3 * v2 + p.d3 * v2**3) + spring
            return [v1, a1, v2, a2]

        sol = solve_ivp(rhs, (times[0], times[-1]), [self.x10, self.v10, self.x20, self.v20], method="LSODA",
                        t_eval=times, rtol=self.rtol, atol=self.atol)
        if not sol.success or sol.y.shape[1] != times.size:
            raise solver_failed(self.name, sol.message)
        x1, v1, x2, v2 = sol.y
        if not np.all(np.isfinite(sol.y)):
            raise SimulationError(f"{self.name} simulation produced non-finite values; check the parameters")
        F = self.forcing(times)
        a1 = F["F1"] - self.f1(v1) - self.f2(x1 - x2)
        a2 = F["F2"] - self.f3(v2) - self.f4(x2 - x1)
        return MultiTrajectory(times, {"x1": x1, "x2": x2}, F, {"x1": v1, "x2": v2}, {"x1": a1, "x2": a2},
                               name=self.name)


def corrupt_forces(record, snr_db: float, *, seed=None, reference: str = "std"):
    """Gaussian noise on every forcing column of a MultiTrajectory at ``snr_db`` (each relative
    to its own signal), from one seeded generator.

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.systems import TwoDOF, corrupt_forces
    >>> clean = TwoDOF().simulate()
    >>> noisy = corrupt_forces(clean, 20, seed=0)
    >>> sorted(noisy.forces)
    ['F1', 'F2']
    >>> [round(float(np.std(noisy.forces[k] - clean.forces[k]) / np.std(clean.forces[k])), 2) for k in ("F1", "F2")]
    [0.1, 0.1]
    """
    from ..data import add_noise, as_rng

    rng = as_rng(seed)
    return record.replace(forces={k: add_noise(v, snr_db, rng, reference) for k, v in record.forces.items()})
