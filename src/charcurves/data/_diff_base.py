"""The differentiator base class, its helpers, and the ``given`` marker.

See :mod:`charcurves.data._differentiate` for the list of methods and their measured accuracy.
"""

from __future__ import annotations

import abc
import math
from typing import Any, ClassVar, final

import numpy as np

from .._errors import ConfigError, DataError
from .._params import Params
from ._trajectory import Trajectory

# Relative tolerance on the time step for "uniform" sampling (same default as Trajectory).
_UNIFORM_TOL = 1e-3

Triple = tuple[np.ndarray, np.ndarray, np.ndarray]


# ---------------------------------------------------------------------------------- helpers
def _as_record(t: Any, x: Any) -> Trajectory:
    """Validate raw ``t``/``x`` arrays through :class:`Trajectory` (finite, 1-D, increasing t)."""
    return Trajectory(t=t, x=x, F=x, name="x(t)")


def _integer(name: str, owner: str, value: Any) -> int:
    if isinstance(value, (bool, np.bool_)):
        raise ConfigError(f"{owner} {name} must be an integer, got {value!r}")
    try:
        as_int = int(value)
        exact = as_int == value
    except (TypeError, ValueError, OverflowError):
        exact = False
    if not exact:
        raise ConfigError(f"{owner} {name} must be an integer, got {value!r}")
    return as_int


def _positive_or_none(name: str, owner: str, value: Any, allow_zero: bool) -> float | None:
    if value is None:
        return None
    bad = isinstance(value, (bool, np.bool_))
    try:
        val = float(value)
    except (TypeError, ValueError):
        bad = True
    if bad or not math.isfinite(val) or val < 0 or (val == 0 and not allow_zero):
        what = "a number >= 0" if allow_zero else "a positive number"
        raise ConfigError(f"{owner} {name} must be None (automatic) or {what}, got {value!r}")
    return val


# ---------------------------------------------------------------------------------- base
class Differentiator(Params, abc.ABC):
    """Turns samples ``x(t)`` into a smoothed ``x̂`` and its derivatives ``x̂'`` and ``x̂''``.

    Call an instance on arrays, ``x_hat, v, a = diff(t, x)``, or give it to
    :func:`estimate_derivatives` together with a :class:`Trajectory`. Instances are plain,
    stateless configurations: :meth:`get_params` returns the constructor arguments, and two
    differentiators of the same class with the same parameters compare equal.

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.data import Differentiator, SavitzkyGolay
    >>> diff = SavitzkyGolay(window=21)
    >>> isinstance(diff, Differentiator), diff.get_params()
    (True, {'window': 21, 'order': 3, 'mode': 'interp'})
    >>> t = np.linspace(0, 10, 501)
    >>> x_hat, v, a = diff(t, np.sin(t))
    >>> print(f"{np.max(np.abs(v - np.cos(t))):.1e}")
    2.8e-04
    """

    #: Registry name (see :data:`DIFFERENTIATOR_NAMES`).
    name: ClassVar[str] = ""
    #: Whether the method needs a uniform time step (checked by ``Trajectory.require_uniform``).
    requires_uniform: ClassVar[bool] = False

    def __call__(self, t: Any, x: Any) -> Triple:
        """Return ``(x_hat, v, a)``: smoothed state, first and second time derivative."""
        return self._apply(_as_record(t, x))

    def _apply(self, traj: Trajectory) -> Triple:
        self._check(traj)
        x_hat, v, a = self._differentiate(traj.t, traj.x)
        return (
            np.ascontiguousarray(x_hat, dtype=float),
            np.ascontiguousarray(v, dtype=float),
            np.ascontiguousarray(a, dtype=float),
        )

    def _check(self, traj: Trajectory) -> None:
        if self.requires_uniform:
            traj.require_uniform(f"the {self.name!r} differentiator", tol=_UNIFORM_TOL)

    @abc.abstractmethod
    def _differentiate(self, t: np.ndarray, x: np.ndarray) -> Triple:
        """The method itself, on validated arrays."""

    # -------------------------------------------------------------- parameters
    def _params_changed(self) -> None:
        """``set_params`` checks the new values as the constructor does (a ConfigError names a bad one)."""
        type(self).__init__(self, **self.get_params(deep=False))  # type: ignore[misc]

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.get_params().items())
        return f"{type(self).__name__}({args})"

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return self.get_params() == other.get_params()  # type: ignore[union-attr]

    def __hash__(self) -> int:
        return hash((type(self).__name__, tuple(sorted(self.get_params().items()))))


# ---------------------------------------------------------------------------------- given
@final
class Given(Differentiator):
    """Marker: use the trajectory's own ``v`` and ``a`` columns as they are (no smoothing).

    Only meaningful in :func:`estimate_derivatives`; calling it on raw arrays raises
    :class:`DataError`, because there is nothing to take the derivatives from.

    Examples
    --------
    >>> from charcurves.data import Given, estimate_derivatives
    >>> from charcurves.systems import get_system
    >>> record = get_system("duffing").simulate()
    >>> estimate_derivatives(record, Given()) is record
    True
    """

    name = "given"

    def __call__(self, t: Any, x: Any) -> Triple:
        raise DataError(
            "'given' derivatives need v and a columns, which raw t, x arrays do not have; "
            "use a Trajectory with v and a (estimate_derivatives(traj, 'given')) or pick a "
            "differentiator that computes them: savgol, spline, spectral or fd"
        )

    def _differentiate(self, t: np.ndarray, x: np.ndarray) -> Triple:  # pragma: no cover
        raise DataError("'given' derivatives are taken from the trajectory, not computed")
