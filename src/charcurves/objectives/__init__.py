"""Objectives: equation error on the prepared columns and output error (multiple shooting with exact
RK4 sensitivities) from an equation-error start.

Public API
----------
EquationError(), OutputError(...), OBJECTIVES, resolve_objective   the objectives and their names
output_error_fit, refine_output_error, free_run_diagnostics         output error of a fitted model
ShootingProblem, CurveBlock, ShootingODE                            multiple shooting
"""

from ._objectives import OBJECTIVES as OBJECTIVES
from ._objectives import EquationError as EquationError
from ._objectives import OutputError as OutputError
from ._objectives import resolve_objective as resolve_objective
from ._output_error import free_run_diagnostics as free_run_diagnostics
from ._output_error import output_error_fit as output_error_fit
from ._output_error import refine_output_error as refine_output_error
from ._shooting import CurveBlock as CurveBlock
from ._shooting import ShootingProblem as ShootingProblem
from ._shooting_ode import ShootingODE as ShootingODE
