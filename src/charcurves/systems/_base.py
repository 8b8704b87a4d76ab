"""Common machinery of the benchmark systems x'' + f1(x') + f2(x) = A cos(Ω t)."""

from __future__ import annotations

import abc
import dataclasses
import math
import numbers
from collections.abc import Callable, Iterator, Mapping, Sequence
from typing import Any, ClassVar

import numpy as np

from .._bounds import BOUNDS
from .._errors import CharCurvesError, ConfigError, SimulationError
from ..data import Trajectory

__all__ = ["BenchmarkSystem", "TOLERANCE_NAMES", "MAX_SIMULATE_POINTS", "MAX_SIMULATE_SPAN", "sample_times"]

#: Most samples one simulation returns: 2 million rows are a CSV of about 0.25 GB and stay below
#: about 1 GB of memory while written (10x the longest measured records charcurves fits).
MAX_SIMULATE_POINTS = 2_000_000
#: Longest simulated time span, in the systems' time units: LSODA takes about 1 s per 1000 time
#: units at tight tolerances, so a simulation ends within a few minutes (the paper's longest horizon,
#: the Lyapunov exponent's, is 5000).
MAX_SIMULATE_SPAN = 1e5

#: Named solver-tolerance presets; "tight" is resolved by each system (see ``_tight_tolerances``).
TOLERANCE_NAMES = ("tight", "scipy-default")
#: LSODA's own defaults in ``scipy.integrate.solve_ivp`` (what the authors' scripts ran with).
_SCIPY_DEFAULT = (1e-3, 1e-6)


def sample_times(t_end: Any = None, n_points: Any = None, t_eval: Any = None) -> np.ndarray:
    """The sample times of a simulation: ``linspace(0, t_end, n_points)`` or ``t_eval``, checked
    against :data:`MAX_SIMULATE_POINTS` and :data:`MAX_SIMULATE_SPAN` (ConfigError naming the fix).

    Examples
    --------
    >>> from charcurves.systems import sample_times
    >>> sample_times(10.0, 5).tolist()
    [0.0, 2.5, 5.0, 7.5, 10.0]
    >>> sample_times(10.0, 1)
    Traceback (most recent call last):
    ...
    charcurves._errors.ConfigError: n_points must be an integer >= 2, got 1
    """
    if t_eval is None:
        from .._bounds import check_number

        t_end = _real("t_end", t_end, positive=True)
        if isinstance(n_points, bool) or not isinstance(n_points, numbers.Integral) or n_points < 2:
            raise ConfigError(f"n_points must be an integer >= 2, got {n_points!r}")
        if t_end < BOUNDS["t_end"].low:  # a span of 1e-300 made LSODA step for ever (issue 50)
            check_number("t_end", t_end, label="t_end (--t-end)")
        if n_points > MAX_SIMULATE_POINTS:  # type: ignore[operator]  # typeshed: numbers.Integral vs int
            raise ConfigError(f"n_points (--n-points) {n_points} is more than the {MAX_SIMULATE_POINTS:,} samples a "
                              f"simulation returns (a CSV of about 0.25 GB); give at most {MAX_SIMULATE_POINTS}")
        if t_end > MAX_SIMULATE_SPAN:
            raise ConfigError(f"t_end (--t-end) {t_end:g} is longer than the {MAX_SIMULATE_SPAN:g} time units a "
                              "simulation covers (about 1 s of integration per 1000); give a shorter t_end")
        return np.linspace(0.0, t_end, int(n_points))
    times = np.asarray(t_eval, dtype=float).reshape(-1)
    if times.size < 2 or not np.isfinite(times).all() or (np.diff(times) <= 0).any():
        raise ConfigError("t_eval must be at least 2 finite, strictly increasing times")
    if times.size > MAX_SIMULATE_POINTS or times[-1] - times[0] > MAX_SIMULATE_SPAN:
        raise ConfigError(f"t_eval has {times.size} times over {times[-1] - times[0]:g} time units; a simulation "
                          f"returns at most {MAX_SIMULATE_POINTS:,} samples over at most {MAX_SIMULATE_SPAN:g} "
                          "time units: split it into shorter runs")
    return times


def _real(name: str, value: Any, *, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
        raise ConfigError(f"{name} must be a finite real number, got {value!r}")
    if positive and value <= 0:
        raise ConfigError(f"{name} must be positive, got {value!r}")
    return float(value)


@dataclasses.dataclass(frozen=True, kw_only=True)
class BenchmarkSystem(abc.ABC):
    """A forced one-degree-of-freedom system ``x'' + f1(x') + f2(x) = A cos(Ω t)`` (unit mass).

    Parameters left as ``None`` take the value of the chosen ``variant``; ``rtol``/``atol``
    left as ``None`` follow ``tolerance`` (``"tight"`` or ``"scipy-default"``), whose own default
    depends on the variant.

    Parameters
    ----------
    variant : str
        Named parameter set (see ``VARIANTS`` of the subclass).
    A, Omega : float
        Forcing amplitude and angular frequency.
    x0, v0 : float
        Initial displacement and velocity (at the first output time).
    tolerance : {"tight", "scipy-default"}, optional
        Solver-tolerance preset.
    rtol, atol : float, optional
        LSODA tolerances; override ``tolerance``.

    Examples
    --------
    >>> from charcurves.systems import BenchmarkSystem, get_system
    >>> system = get_system("duffing", A=0.3)
    >>> isinstance(system, BenchmarkSystem), system.parameters()["A"]
    (True, 0.3)
    >>> record = system.simulate(t_end=20.0, n_points=401)
    >>> record.n_samples, record.has_derivatives
    (401, True)
    >>> float(system.f2(2.0))
    6.0
    """

    #: Registry name, also the name of the simulated trajectories.
    name: ClassVar[str] = "system"
    #: The template family whose equation the system follows (CharacteristicCurves.from_method(family=...)).
    family: ClassVar[str] = "separable"
    #: Variant name -> default field values (every field left ``None`` must be listed).
    VARIANTS: ClassVar[dict[str, dict[str, Any]]] = {}
    #: Fields reported by :meth:`parameters`, in order.
    _PARAMETER_FIELDS: ClassVar[tuple[str, ...]] = ("A", "Omega", "x0", "v0")

    variant: str = "paper"
    A: float | None = None
    Omega: float | None = None
    x0: float | None = None
    v0: float | None = None
    tolerance: str | None = None
    rtol: float | None = None
    atol: float | None = None

    def __post_init__(self) -> None:
        if self.variant not in self.VARIANTS:
            raise ConfigError(
                f"unknown {self.name} variant {self.variant!r}; choose one of "
                f"{', '.join(map(repr, self.VARIANTS))}"
            )
        defaults = self.VARIANTS[self.variant]
        for f in dataclasses.fields(self):
            if getattr(self, f.name) is None and f.name in defaults:
                object.__setattr__(self, f.name, defaults[f.name])
        if self.tolerance not in TOLERANCE_NAMES:
            raise ConfigError(
                f"unknown tolerance preset {self.tolerance!r}; choose one of "
                f"{', '.join(map(repr, TOLERANCE_NAMES))}, or give rtol= and atol="
            )
        rtol, atol = self._tight_tolerances() if self.tolerance == "tight" else _SCIPY_DEFAULT
        object.__setattr__(self, "rtol", _real("rtol", rtol if self.rtol is None else self.rtol, positive=True))
        object.__setattr__(self, "atol", _real("atol", atol if self.atol is None else self.atol, positive=True))
        for key in self._PARAMETER_FIELDS:
            object.__setattr__(self, key, _real(key, getattr(self, key)))
        self._validate()

    # ------------------------------------------------------------------ hooks
    def _tight_tolerances(self) -> tuple[float, float]:
        """(rtol, atol) of the ``"tight"`` preset: a solver-independent reference solution."""
        return 1e-10, 1e-12

    def _validate(self) -> None:
        """Extra checks of a subclass (raise :class:`ConfigError`)."""

    @abc.abstractmethod
    def f1(self, v: Any) -> np.ndarray:
        """True damping curve f1(x') (vectorised)."""

    @abc.abstractmethod
    def f2(self, x: Any) -> np.ndarray:
        """True stiffness curve f2(x) (vectorised)."""

    @abc.abstractmethod
    def _integrate(self, t_eval: np.ndarray, rtol: float, atol: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Solve from (t_eval[0], x0, v0); return x, v, a at ``t_eval``."""

    # ------------------------------------------------------------------ public API
    def forcing(self, t: Any) -> np.ndarray:
        """External force F(t) = A cos(Ω t) (vectorised)."""
        return self.A * np.cos(self.Omega * np.asarray(t, dtype=float))

    def acceleration(self, t: Any, x: Any, v: Any) -> np.ndarray:
        """x'' = F(t) − f1(v) − f2(x) (vectorised)."""
        return self.forcing(t) - self.f1(v) - self.f2(x)

    def true_curves(self) -> dict[str, Callable[[Any], np.ndarray]]:
        """The true characteristic curves, ``{"f1": f1, "f2": f2}``."""
        return {"f1": self.f1, "f2": self.f2}

    def parameters(self) -> dict[str, float]:
        """Physical parameters (curves, forcing, initial conditions) as a plain dict."""
        return {key: float(getattr(self, key)) for key in self._PARAMETER_FIELDS}

    def sticking_mask(self, traj: Trajectory) -> np.ndarray:
        """Boolean mask of samples where the mass sticks (none for systems without dry friction)."""
        return np.zeros(traj.n_samples, dtype=bool)

    def simulate(
        self,
        t_end: float = 40.0,
        n_points: int = 1000,
        *,
        x0: float | None = None,
        v0: float | None = None,
        A: float | None = None,
        Omega: float | None = None,
        t_eval: Any = None,
        rtol: float | None = None,
        atol: float | None = None,
    ) -> Trajectory:
        """Integrate the system with LSODA and sample it.

        Parameters
        ----------
        t_end : float
            End time; the samples are ``linspace(0, t_end, n_points)``; at most
            :data:`MAX_SIMULATE_SPAN` (1e5).
        n_points : int
            Number of samples, at most :data:`MAX_SIMULATE_POINTS` (2 million).
        x0, v0, A, Omega : float, optional
            Override the system's initial conditions / forcing (e.g. validation trajectories).
        t_eval : array_like, optional
            Explicit strictly increasing sample times (replaces ``t_end``/``n_points``); the
            initial conditions hold at ``t_eval[0]``.
        rtol, atol : float, optional
            Override the system's tolerances.

        Returns
        -------
        Trajectory
            ``x``, ``v`` from the solver, ``a`` from the equation of motion at the samples (not
            differentiated), clean ``F``.
        """
        changes: dict[str, Any] = {k: val for k, val in {"x0": x0, "v0": v0, "A": A, "Omega": Omega}.items()
                                   if val is not None}
        system = dataclasses.replace(self, **changes) if changes else self
        times = sample_times(t_end, n_points, t_eval)
        rtol = system.rtol if rtol is None else _real("rtol", rtol, positive=True)
        atol = system.atol if atol is None else _real("atol", atol, positive=True)
        assert rtol is not None and atol is not None  # __post_init__ sets the system's tolerances
        x, v, a = system._integrate(times, rtol, atol)
        if not (np.isfinite(x).all() and np.isfinite(v).all()):
            raise SimulationError(f"{self.name} simulation produced non-finite values; check the parameters")
        return Trajectory(t=times, x=x, F=system.forcing(times), v=v, a=a, name=self.name)


    def simulate_many(self, t_eval: Any, draws: Sequence[Mapping[str, float]],
                      box: Mapping[str, tuple[float, float]] | None = None) -> Iterator[tuple | None]:
        """``(x, v)`` on ``t_eval`` from each draw's ``x0, v0, A, Omega`` (None where the solver fails),
        in draw order.

        The base class simulates the draws one by one as they are taken (a caller that stops
        early pays for no more); a system may integrate them stacked in one solver run (the
        tight-tolerance Duffing does), which is as accurate, to its tolerances, but not bit for
        bit the run of one draw alone. With ``box`` (``{"x": (lo, hi), "v": (lo, hi)}``), a draw
        whose samples leave it gives None: a system with a plain right-hand side (``_plain_rhs``,
        no events) then stops its run at the first solver step with a sample outside, where the
        rest of the run could not change the answer (:func:`_lsoda_samples_inside`: the same LSODA
        steps and samples as ``solve_ivp``, so a draw that stays inside gives the same bits).

        Examples
        --------
        >>> import numpy as np
        >>> from charcurves.systems import get_system
        >>> t = np.linspace(0.0, 10.0, 101)
        >>> [(x, v)] = get_system("stick-slip").simulate_many(t, [{"x0": 0.1, "v0": 0.0, "A": 1.0, "Omega": 0.36}])
        >>> x.shape, v.shape
        ((101,), (101,))
        """
        plain_rhs = getattr(type(self), "_plain_rhs", None) if box is not None else None
        times = sample_times(t_eval=t_eval)
        for d in draws:
            if plain_rhs is not None and box is not None:
                system = dataclasses.replace(self, x0=d["x0"], v0=d["v0"], A=d["A"], Omega=d["Omega"])
                assert system.rtol is not None and system.atol is not None
                yield _lsoda_samples_inside(plain_rhs(system), times, [float(d["x0"]), float(d["v0"])], system.rtol,
                                            system.atol, box)
                continue
            try:
                tr = self.simulate(t_eval=t_eval, x0=d["x0"], v0=d["v0"], A=d["A"], Omega=d["Omega"])
            except CharCurvesError:
                yield None
                continue
            x, v = np.asarray(tr.x), np.asarray(tr.v)
            yield (x, v) if box is None or _in_box(x, v, box) else None


def _in_box(x: np.ndarray, v: np.ndarray, box: Mapping[str, tuple[float, float]]) -> bool:
    (xl, xh), (vl, vh) = box["x"], box["v"]
    return bool(np.all(np.isfinite(x)) and np.all(np.isfinite(v)) and x.min() >= xl and x.max() <= xh
                and v.min() >= vl and v.max() <= vh)


def _lsoda_samples_inside(fun: Callable, t_eval: np.ndarray, y0: Sequence[float], rtol: float, atol: float,
                         box: Mapping[str, tuple[float, float]]) -> tuple[np.ndarray, np.ndarray] | None:
    """``(x, v)`` at ``t_eval`` of ``y' = fun(t, y)`` (``y = (x, v)``) by LSODA, or None as soon as a
    sample leaves ``box`` (or is not finite, or the solver fails).

    The loop is ``solve_ivp``'s for LSODA with ``t_eval``: one solver step, then the samples inside
    it from the step's dense output, so a run that stays inside gives ``solve_ivp``'s samples to the
    last bit; a run that leaves stops at the step where it does. Rejection sampling of validation
    cases (most draws leave the training box, a median 13 s into the 80 s of the scripts' Duffing)
    then pays for the steps up to the exit only.

    """
    from scipy.integrate import LSODA

    t_eval = np.asarray(t_eval, dtype=float)
    solver = LSODA(fun, float(t_eval[0]), np.asarray(y0, dtype=float), float(t_eval[-1]), rtol=rtol, atol=atol)
    chunks, i = [], 0
    while True:
        solver.step()
        if solver.status == "failed":
            return None
        j = int(np.searchsorted(t_eval, solver.t, side="right"))
        if j > i:
            y = solver.dense_output()(t_eval[i:j])
            if not _in_box(y[0], y[1], box):
                return None
            chunks.append(y)
            i = j
        if solver.status == "finished":
            break
    Y = np.hstack(chunks) if chunks else np.empty((2, 0))
    return (Y[0], Y[1]) if Y.shape[1] == t_eval.size else None


def solver_failed(name: str, message: str) -> SimulationError:
    return SimulationError(f"{name} simulation failed in LSODA ({message}); try looser tolerances or a shorter t_end")
