"""Figures and reports."""

from ._figures import plot_curves as plot_curves
from ._figures import plot_free_run as plot_free_run
from ._html import Report as Report
from ._study import plot_forward as plot_forward
from ._study import plot_performance as plot_performance
from ._study import plot_phase_space as plot_phase_space
from ._study import plot_rmse_vs_noise as plot_rmse_vs_noise
from ._study import plot_tsep_vs_noise as plot_tsep_vs_noise
