"""Metrics: curve errors, separation time, trajectory RMSE, largest Lyapunov exponent."""

from ._curves import curve_errors as curve_errors
from ._curves import curve_rmse as curve_rmse
from ._dynamics import largest_lyapunov_exponent as largest_lyapunov_exponent
from ._dynamics import separation_time as separation_time
from ._dynamics import trajectory_rmse as trajectory_rmse
