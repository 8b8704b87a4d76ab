"""Exception types raised by charcurves.

Every error a user can cause is one of these, with a one-line message that names the
problem and the fix; the CLI turns them into exit code 2 without a traceback.
"""

from __future__ import annotations

__all__ = [
    "CharCurvesError",
    "DataError",
    "ConfigError",
    "FitError",
    "NotFittedError",
    "ModelFileError",
    "SimulationError",
    "IdentifiabilityError",
]


class CharCurvesError(Exception):
    """Base class of every error charcurves raises on purpose.

    Examples
    --------
    >>> import charcurves as cc
    >>> try:
    ...     cc.get_system("pendulum")
    ... except cc.CharCurvesError as exc:
    ...     print(type(exc).__name__)
    ConfigError
    """


class DataError(CharCurvesError, ValueError):
    """Measured data cannot be used as given (missing column, NaN, bad time stamps...).

    Examples
    --------
    >>> import charcurves as cc
    >>> try:
    ...     cc.Trajectory(t=[0.0, 1.0, 1.0], x=[0.0, 1.0, 2.0], F=[0.0, 0.0, 0.0])
    ... except cc.DataError as exc:
    ...     print(str(exc)[:38])
    time repeats at row 2 (t=1 after 1); t
    """


class ConfigError(CharCurvesError, ValueError):
    """An option, method, family or constraint name is unknown or inconsistent.

    Examples
    --------
    >>> import charcurves as cc
    >>> try:
    ...     cc.fit(None, method="magic")
    ... except cc.ConfigError as exc:
    ...     print(str(exc)[:22])
    unknown method 'magic'
    """


class IdentifiabilityError(DataError):
    """The data cannot determine the requested curves (no excitation, one-sided records...).

    Examples
    --------
    >>> import charcurves as cc
    >>> try:
    ...     cc.EquationTemplate("x'' + f1(x') + f2(x') = F")
    ... except cc.IdentifiabilityError as exc:
    ...     print(str(exc)[:58])
    f1(x') and f2(x') enter the template in the same way: any
    """


class NotFittedError(CharCurvesError, RuntimeError):
    """A fitted attribute was requested before ``fit`` was called.

    Examples
    --------
    >>> import charcurves as cc
    >>> try:
    ...     cc.CharacteristicCurves.from_method(method="poly-cc").curves_
    ... except cc.NotFittedError as exc:
    ...     print(exc)
    this CharacteristicCurves is not fitted yet; call fit(trajectory) first
    """


class ModelFileError(CharCurvesError, OSError):
    """A saved model cannot be read (missing, corrupted, or from an unknown format version).

    Examples
    --------
    >>> import charcurves as cc
    >>> try:
    ...     cc.load_model("no-such-model")
    ... except cc.ModelFileError as exc:
    ...     print(str(exc)[:48])
    model directory 'no-such-model' is missing (does
    """


class SimulationError(CharCurvesError, RuntimeError):
    """A forward simulation could not be carried out.

    Also a ``RuntimeError``; a simulation of a fitted model that diverges or times out returns a
    status instead (see :class:`~charcurves.simulate.SimulationResult`).

    Examples
    --------
    >>> import charcurves as cc
    >>> issubclass(cc.SimulationError, RuntimeError), issubclass(cc.SimulationError, cc.CharCurvesError)
    (True, True)
    """


class FitError(CharCurvesError, RuntimeError):
    """A fit failed numerically (every training start diverged).

    Examples
    --------
    >>> import charcurves as cc
    >>> issubclass(cc.FitError, RuntimeError), issubclass(cc.FitError, cc.CharCurvesError)
    (True, True)
    """
