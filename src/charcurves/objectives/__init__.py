"""Objectives: equation error on the prepared columns and output error (multiple shooting with exact
RK4 sensitivities) from an equation-error start.

Public API
----------
EquationError(), OutputError(...), OBJECTIVES                 the objectives and their names
output_error_fit, refine_output_error, free_run_diagnostics   output error of a fitted model

The estimator's layer also imports ``resolve_objective`` (an objective setting to one object).
"""

from ._objectives import OBJECTIVES as OBJECTIVES
from ._objectives import Auto as Auto
from ._objectives import EquationError as EquationError
from ._objectives import OutputError as OutputError
from ._output_error import free_run_diagnostics as free_run_diagnostics
from ._output_error import output_error_fit as output_error_fit
from ._output_error import refine_output_error as refine_output_error

# the interface the layers above build on (not on the API page: see the modules' docstrings)
from ._objectives import resolve_objective, runs_output_error  # noqa: F401
from ._output_error import choose_substeps  # noqa: F401
from ._shooting import CurveBlock, ShootingProblem  # noqa: F401

__all__ = ["Auto", "EquationError", "OBJECTIVES", "OutputError", "free_run_diagnostics", "output_error_fit",
           "refine_output_error"]
