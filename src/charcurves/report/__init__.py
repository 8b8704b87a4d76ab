"""Figures and reports."""

from ._figures import plot_curves as plot_curves
