"""What a forward run returns, and the pieces every simulator shares: statuses, solver names, forcing.

Examples
--------
>>> from charcurves.simulate import STATUSES
>>> STATUSES
('ok', 'left_box', 'diverged', 'timeout', 'solver_failed')
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from .._errors import ConfigError

__all__ = ["SimulationResult", "sinusoidal_forcing", "STATUSES", "solver_class"]

STATUSES = ("ok", "left_box", "diverged", "timeout", "solver_failed")

_SOLVERS = ("RK23", "RK45", "DOP853", "Radau", "BDF", "LSODA")


@dataclasses.dataclass
class SimulationResult:
    """Samples of a forward simulation.

    After "left_box", "diverged" or "solver_failed" the samples stop before ``t_end_reached``;
    after "timeout" there are none (a run cut short by the clock says nothing about the model).
    ``switches`` counts stick/slip transitions (0 without a jump); ``details`` records how the
    curves were evaluated (``"f1"``/``"f2"``: "exact" or "tabulated"), the jump height used for
    events and the time spent sticking.

    Examples
    --------
    >>> import numpy as np
    >>> import charcurves as cc
    >>> from charcurves.simulate import SimulationResult, simulate_model, sinusoidal_forcing
    >>> from charcurves.systems import get_system
    >>> system = get_system("duffing")
    >>> model = cc.fit(system.simulate(), method="parametric", basis="f1=z; f2=z, z**3")
    >>> forcing = sinusoidal_forcing(system.A, system.Omega)
    >>> res = simulate_model(model, np.linspace(0, 20, 401), system.x0, system.v0, forcing)
    >>> isinstance(res, SimulationResult), res.ok, res.x.shape, res.details["f1"]
    (True, True, (401,), 'exact')
    """

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    status: str
    message: str = ""
    t_end_reached: float = float("nan")
    seconds: float = 0.0
    switches: int = 0
    details: dict = dataclasses.field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status == "ok"


class _Stop(Exception):
    def __init__(self, status: str, message: str, t: float):
        super().__init__(message)
        self.status, self.message, self.t = status, message, t


def sinusoidal_forcing(A: float, Omega: float) -> Callable[[float], float]:
    """F(t) = A cos(Ω t) (vectorised).

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.simulate import sinusoidal_forcing
    >>> F = sinusoidal_forcing(2.0, 0.5)
    >>> float(F(0.0)), F(np.array([0.0, np.pi])).round(6).tolist()
    (2.0, [2.0, 0.0])
    """
    return lambda t: A * np.cos(Omega * t)


def solver_class(method):
    """The scipy ``OdeSolver`` class of a method name (or the class itself); ConfigError for others.

    Examples
    --------
    >>> from charcurves.simulate import solver_class
    >>> solver_class("RK45").__name__, solver_class("LSODA").__name__
    ('RK45', 'LSODA')
    """
    import scipy.integrate as si

    cls = getattr(si, method, None) if isinstance(method, str) and method in _SOLVERS else method
    if not (isinstance(cls, type) and issubclass(cls, si.OdeSolver)):
        raise ConfigError(f"unknown solver method {method!r}; choose one of {', '.join(_SOLVERS)}")
    return cls
