"""Metrics: curve errors (more in later modules: separation time, Lyapunov time, A-fits)."""

from ._curves import curve_errors as curve_errors
from ._curves import curve_rmse as curve_rmse
