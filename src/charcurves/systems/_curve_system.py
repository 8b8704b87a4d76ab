"""A system of any family with curves you give: simulate ``x'' + f1(x') + f2(x) = F`` (or the
position-damping, first-order or two-dof equation) for arbitrary true curves."""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from .._errors import ConfigError, SimulationError
from ._base import sample_times, solver_failed

__all__ = ["CurveSystem", "CURVE_SYSTEM_FAMILIES"]

#: Families a :class:`CurveSystem` simulates, with the curve names each needs.
CURVE_SYSTEM_FAMILIES: dict[str, tuple[str, ...]] = {
    "separable": ("f1", "f2"), "position-damping": ("f1", "f2"), "first-order": ("f1", "f2"),
    "two-dof": ("f1", "f2", "f3", "f4")}
_STATES = {"separable": 2, "position-damping": 2, "first-order": 1, "two-dof": 4}
#: Step of the central differences that give the first-order family's x'' (its curves' slopes).
_SLOPE_STEP = 1e-6


def _real(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
        raise ConfigError(f"{name} must be a finite real number, got {value!r}")
    return float(value)


def _as_float_function(f: Callable[[Any], Any]) -> Callable[[Any], np.ndarray]:
    def curve(z: Any) -> np.ndarray:
        return np.asarray(f(np.asarray(z, dtype=float)), dtype=float)

    return curve


def _tones(name: str, value: Any) -> tuple[tuple[float, float], ...]:
    try:
        pairs = tuple((_real(f"{name} amplitude", a), _real(f"{name} frequency", w)) for a, w in value)
    except (TypeError, ValueError):
        raise ConfigError(f"{name} must be a sequence of (amplitude, angular frequency) pairs, got {value!r}") from None
    if not pairs:
        raise ConfigError(f"{name} needs at least one (amplitude, angular frequency) pair")
    return pairs


@dataclasses.dataclass(frozen=True, eq=False)
class CurveSystem:
    """A forced system of one of the template families with given true curves.

    The equations are those of the templates (unit mass, gain 1):

    * ``separable``: ``x'' + f1(x') + f2(x) = F``
    * ``position-damping``: ``x'' + f1(x) x' + f2(x) = F``
    * ``first-order``: ``f1(x) + f2(x) x' = F`` (``f2`` must stay away from 0 along the record)
    * ``two-dof``: ``x1'' + f1(x1') + f2(x1 - x2) = F1; x2'' + f3(x2') + f4(x2 - x1) = F2``

    with each forcing a sum of cosines ``sum_k A_k cos(Omega_k t)``.

    Parameters
    ----------
    family : {"separable", "position-damping", "first-order", "two-dof"}
    curves : mapping of str to callable
        The true curves by name (``f1, f2``; two-dof: ``f1 .. f4``), each vectorised over a
        NumPy array.
    forcing : sequence of (amplitude, angular frequency), or a mapping {"F1": ..., "F2": ...}
        The cosines of the forcing (two-dof: one sequence per force).
    initial : sequence of float
        Initial state at ``t = 0``: ``(x0, v0)``; first-order ``(x0,)``; two-dof
        ``(x10, v10, x20, v20)``.
    name : str
        Name of the simulated records.
    rtol, atol : float
        LSODA tolerances.

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.systems import CurveSystem
    >>> system = CurveSystem("separable", {"f1": lambda v: 0.2 * v + 0.15 * v * np.abs(v), "f2": np.tanh},
    ...                      forcing=[(0.8, 1.1)], initial=(0.0, 0.0))
    >>> record = system.simulate(t_end=20.0, n_points=401)
    >>> record.n_samples, record.has_derivatives
    (401, True)
    >>> bool(np.allclose(record.a + system.curves["f1"](record.v) + np.tanh(record.x), record.F))
    True
    """

    family: str
    curves: Mapping[str, Callable[[Any], Any]]
    forcing: Any
    initial: Sequence[float]
    name: str = "curve-system"
    rtol: float = 1e-10
    atol: float = 1e-12

    def __post_init__(self) -> None:
        if self.family not in CURVE_SYSTEM_FAMILIES:
            raise ConfigError(f"unknown family {self.family!r}; choose one of "
                              f"{', '.join(map(repr, CURVE_SYSTEM_FAMILIES))}")
        names = CURVE_SYSTEM_FAMILIES[self.family]
        if not isinstance(self.curves, Mapping) or sorted(self.curves) != sorted(names):
            got = sorted(self.curves) if isinstance(self.curves, Mapping) else self.curves
            raise ConfigError(f"the {self.family} family needs the curves {', '.join(names)}, got {got!r}")
        bad = [k for k, f in self.curves.items() if not callable(f)]
        if bad:
            raise ConfigError(f"curve(s) {', '.join(bad)} must be callables of a NumPy array")
        if self.family == "two-dof":
            if not isinstance(self.forcing, Mapping) or sorted(self.forcing) != ["F1", "F2"]:
                raise ConfigError("a two-dof CurveSystem needs forcing={'F1': [(A, Omega), ...], 'F2': [...]}")
            tones: Any = {k: _tones(k, self.forcing[k]) for k in ("F1", "F2")}
        else:
            tones = _tones("forcing", self.forcing)
        object.__setattr__(self, "forcing", tones)
        init = tuple(_real("initial", u) for u in np.atleast_1d(np.asarray(self.initial, dtype=object)))
        if len(init) != _STATES[self.family]:
            raise ConfigError(f"the {self.family} family needs {_STATES[self.family]} initial values, got {len(init)}")
        object.__setattr__(self, "initial", init)
        object.__setattr__(self, "curves", dict(self.curves))
        for key in ("rtol", "atol"):
            if _real(key, getattr(self, key)) <= 0:
                raise ConfigError(f"{key} must be positive, got {getattr(self, key)!r}")

    # ------------------------------------------------------------------ the system
    def true_curves(self) -> dict[str, Callable[[Any], np.ndarray]]:
        """The true curves by name."""
        return {k: _as_float_function(f) for k, f in self.curves.items()}

    def force(self, t: Any) -> Any:
        """The forcing at ``t``: an array (two-dof: ``{"F1": ..., "F2": ...}``)."""
        t = np.asarray(t, dtype=float)

        def total(tones):
            return sum((a * np.cos(w * t) for a, w in tones), np.zeros_like(t))

        if self.family == "two-dof":
            return {k: total(v) for k, v in self.forcing.items()}
        return total(self.forcing)

    def _rhs(self) -> Callable[[float, np.ndarray], list[float]]:
        c = self.true_curves()

        def F(t: float) -> Any:
            return self.force(np.array([t]))

        if self.family == "separable":
            return lambda t, y: [y[1], float(F(t)[0] - c["f1"](y[1:2])[0] - c["f2"](y[0:1])[0])]
        if self.family == "position-damping":
            return lambda t, y: [y[1], float(F(t)[0] - c["f1"](y[0:1])[0] * y[1] - c["f2"](y[0:1])[0])]
        if self.family == "first-order":
            return lambda t, y: [float((F(t)[0] - c["f1"](y[0:1])[0]) / c["f2"](y[0:1])[0])]

        def two(t, y):
            f = F(t)
            z = y[0:1] - y[2:3]
            return [y[1], float(f["F1"][0] - c["f1"](y[1:2])[0] - c["f2"](z)[0]),
                    y[3], float(f["F2"][0] - c["f3"](y[3:4])[0] - c["f4"](-z)[0])]
        return two

    def simulate(self, t_end: float = 40.0, n_points: int = 1000, *, t_eval: Any = None):
        """Integrate with LSODA from ``initial`` at ``t = 0`` and sample the record.

        Returns
        -------
        Trajectory or MultiTrajectory
            Exact ``x``, ``v`` (from the solver) and ``a`` (from the equation at the samples;
            first-order: the chain rule, the curves' slopes by central differences of step 1e-6),
            clean forcing. Two-dof: a MultiTrajectory with states x1, x2 and forces F1, F2.

        Raises
        ------
        SimulationError
            When the solver fails or the state leaves the finite numbers (an unbounded system).
        """
        from scipy.integrate import solve_ivp

        from ..data import MultiTrajectory, Trajectory

        times = sample_times(t_end, n_points, t_eval)
        if times[0] != 0.0:
            raise ConfigError("t_eval must start at 0, where the initial state holds")
        with np.errstate(all="ignore"):
            sol = solve_ivp(self._rhs(), (0.0, float(times[-1])), list(self.initial), method="LSODA",
                            t_eval=times, rtol=self.rtol, atol=self.atol)
        if not sol.success or sol.y.shape[1] != times.size:
            raise solver_failed(self.name, sol.message)
        if not np.all(np.isfinite(sol.y)):
            raise SimulationError(f"{self.name} simulation produced non-finite values; the system is not bounded")
        c, F = self.true_curves(), self.force(times)
        if self.family == "two-dof":
            x1, v1, x2, v2 = sol.y
            a1 = F["F1"] - c["f1"](v1) - c["f2"](x1 - x2)
            a2 = F["F2"] - c["f3"](v2) - c["f4"](x2 - x1)
            return MultiTrajectory(times, {"x1": x1, "x2": x2}, F, {"x1": v1, "x2": v2}, {"x1": a1, "x2": a2},
                                   name=self.name)
        x = sol.y[0]
        if self.family == "first-order":
            v = (F - c["f1"](x)) / c["f2"](x)
            h = _SLOPE_STEP
            d1 = (c["f1"](x + h) - c["f1"](x - h)) / (2 * h)
            d2 = (c["f2"](x + h) - c["f2"](x - h)) / (2 * h)
            dF = self._force_rate(times)
            a = (dF - d1 * v - d2 * v * v) / c["f2"](x)
        else:
            v = sol.y[1]
            damp = c["f1"](v) if self.family == "separable" else c["f1"](x) * v
            a = F - damp - c["f2"](x)
        return Trajectory(t=times, x=x, F=F, v=v, a=a, name=self.name)

    def _force_rate(self, t: np.ndarray) -> np.ndarray:
        """dF/dt of a one-force system."""
        return sum((-a * w * np.sin(w * t) for a, w in self.forcing), np.zeros_like(t))
