"""Metrics: curve errors, separation time, trajectory RMSE, largest Lyapunov exponent, and the forward
validation of a fitted model from new conditions (t_sep and RMSE[x] per case, paper Fig. 7)."""

from ._curves import curve_errors as curve_errors
from ._curves import curve_rmse as curve_rmse
from ._dynamics import largest_lyapunov_exponent as largest_lyapunov_exponent
from ._dynamics import separation_time as separation_time
from ._dynamics import trajectory_rmse as trajectory_rmse
from ._ensemble import ENSEMBLE_KINDS as ENSEMBLE_KINDS
from ._ensemble import PERFORMANCE_TERMS as PERFORMANCE_TERMS
from ._ensemble import MIWResult as MIWResult
from ._ensemble import curve_residuals as curve_residuals
from ._ensemble import ensemble_by_level as ensemble_by_level
from ._ensemble import ensemble_rmse as ensemble_rmse
from ._ensemble import fit_bias as fit_bias
from ._ensemble import fit_slope_one as fit_slope_one
from ._ensemble import miw as miw
from ._ensemble import performance_percent as performance_percent
from ._validation import HORIZONS as HORIZONS
from ._validation import VALIDATION_RANGES as VALIDATION_RANGES
from ._validation import CaseResult as CaseResult
from ._validation import ForwardEvaluation as ForwardEvaluation
from ._validation import ValidationCase as ValidationCase
from ._validation import ValidationSet as ValidationSet
from ._validation import cached_validation_cases as cached_validation_cases
from ._validation import evaluate_forward as evaluate_forward
from ._validation import make_validation_cases as make_validation_cases
from ._validation import training_box as training_box
