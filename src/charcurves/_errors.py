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
    """Base class of every error charcurves raises on purpose."""


class DataError(CharCurvesError, ValueError):
    """Measured data cannot be used as given (missing column, NaN, bad time stamps...)."""


class ConfigError(CharCurvesError, ValueError):
    """An option, method, family or constraint name is unknown or inconsistent."""


class IdentifiabilityError(DataError):
    """The data cannot determine the requested curves (no excitation, one-sided records...)."""


class NotFittedError(CharCurvesError, RuntimeError):
    """A fitted attribute was requested before ``fit`` was called."""


class ModelFileError(CharCurvesError, OSError):
    """A saved model cannot be read (missing, corrupted, or from an unknown format version)."""


class SimulationError(CharCurvesError, RuntimeError):
    """A forward simulation could not be carried out."""


class FitError(CharCurvesError, RuntimeError):
    """A fit failed numerically (every training start diverged)."""
