"""charcurves: interpretable equation discovery with characteristic curves.

State a structural template such as ``x'' + f1(x') + f2(x) = F(t)``; each unknown univariate
function (a characteristic curve) is learned from measured x(t), F(t) by a neural network,
a basis expansion or symbolic regression, under priors such as odd/even symmetry.

Importing the package does no work: heavy modules (torch, scipy, matplotlib) load on first use.
"""

from __future__ import annotations

import importlib
import logging

from ._version import VERSION

__version__ = VERSION

logging.getLogger(__name__).addHandler(logging.NullHandler())

# public name -> module that defines it (loaded on first attribute access)
_LAZY: dict[str, str | tuple[str, str]] = {
    # data
    "Trajectory": "charcurves.data",
    "MultiTrajectory": "charcurves.data",
    "corrupt": "charcurves.data",
    "add_noise": "charcurves.data",
    "estimate_derivatives": "charcurves.data",
    "Differentiator": "charcurves.data",
    "SavitzkyGolay": "charcurves.data",
    "Spectral": "charcurves.data",
    "SmoothingSpline": "charcurves.data",
    "Spline": "charcurves.data",
    "FiniteDifference": "charcurves.data",
    "Given": "charcurves.data",
    "KalmanSmoother": "charcurves.data",
    "TotalVariation": "charcurves.data",
    "get_system": "charcurves.systems",
    # curve representations
    "AbstractCurve": "charcurves.curves",
    "LinearCurve": "charcurves.curves",
    "Neural": "charcurves.curves",
    "Polynomial": "charcurves.curves",
    "SparseLibrary": "charcurves.curves",
    "Basis": "charcurves.curves",
    "Symbolic": "charcurves.curves",
    "register_curve": "charcurves.curves",
    "NeuralCurve": "charcurves.curves",
    # templates
    "Separable": "charcurves.templates",
    "PositionDamping": "charcurves.templates",
    "FirstOrder": "charcurves.templates",
    "TwoDOF": "charcurves.templates",
    "Equation": "charcurves.templates",
    "EquationTemplate": "charcurves.templates",
    # fitting
    "CharacteristicCurves": "charcurves.fitting",
    "EquationError": "charcurves.fitting",
    "OutputError": "charcurves.fitting",
    "Auto": "charcurves.fitting",
    "Objective": "charcurves.objectives",
    "MethodPreset": "charcurves.fitting",
    "FittedModel": "charcurves.fitting",
    "fit": "charcurves.fitting",
    "load_model": "charcurves.fitting",
    "TrainingPreset": "charcurves.fitting",
    "PRESETS": "charcurves.fitting",
    "METHODS": "charcurves.fitting",
    "curve_rmse": "charcurves.metrics",
    "curve_errors": "charcurves.metrics",
    "plot_curves": "charcurves.report",
    "CharCurvesError": "charcurves._errors",
    "DataError": "charcurves._errors",
    "ConfigError": "charcurves._errors",
    "ModelFileError": "charcurves._errors",
    "NotFittedError": "charcurves._errors",
    "SimulationError": "charcurves._errors",
    "FitError": "charcurves._errors",
    "IdentifiabilityError": "charcurves._errors",
}

__all__ = sorted(_LAZY) + ["__version__"]


def __getattr__(name: str):
    if name in _LAZY:
        entry = _LAZY[name]
        module, attr = entry if isinstance(entry, tuple) else (entry, name)
        value = getattr(importlib.import_module(module), attr)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'charcurves' has no attribute {name!r}")


def __dir__():
    return __all__
