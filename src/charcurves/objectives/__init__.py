"""Objectives: what a fit does after its equation-error start -- nothing (equation error), output
error (multiple shooting with exact RK4 sensitivities), or the choice per record (auto).

Public API
----------
Objective                                                     the interface (subclass it for a new objective)
EquationError(), OutputError(...), Auto(...), OBJECTIVES      the objectives and their names
resolve_objective                                             an ``objective=`` setting to its object
output_error_fit, refine_output_error, free_run_diagnostics   output error of a fitted model
"""

from ._base import Objective as Objective
from ._objectives import OBJECTIVES as OBJECTIVES
from ._objectives import Auto as Auto
from ._objectives import EquationError as EquationError
from ._objectives import OutputError as OutputError
from ._objectives import refine_output_error as refine_output_error
from ._objectives import resolve_objective as resolve_objective
from ._output_error import free_run_diagnostics as free_run_diagnostics
from ._output_error import output_error_fit as output_error_fit

# the interface the layers above build on (not on the API page: see the modules' docstrings)
from ._output_error import choose_substeps  # noqa: F401
from ._shooting import CurveBlock, ShootingProblem  # noqa: F401

__all__ = ["Auto", "EquationError", "OBJECTIVES", "Objective", "OutputError", "free_run_diagnostics",
           "output_error_fit", "refine_output_error", "resolve_objective"]
