"""Figures and reports: the benchmark study's figures, the Markdown/HTML :class:`Report`, and the
one-page report of a single fit (``charcurves report``)."""

from ..model import plot_curves as plot_curves
from ._figures import plot_free_run as plot_free_run
from ._fit_report import fit_report as fit_report
from ._fit_report import load_fit as load_fit
from ._fit_report import versions as versions
from ._fit_report import write_fit_report as write_fit_report
from ._html import Report as Report
from ._study import plot_forward as plot_forward
from ._study import plot_performance as plot_performance
from ._study import plot_phase_space as plot_phase_space
from ._study import plot_rmse_vs_noise as plot_rmse_vs_noise
from ._study import plot_tsep_vs_noise as plot_tsep_vs_noise
