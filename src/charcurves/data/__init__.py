"""Measured data: trajectories (one degree of freedom, or several: MultiTrajectory), noise models,
the noise floor of an equation's loss, and differentiators."""

from ._trajectory import MIN_SAMPLES as MIN_SAMPLES
from ._trajectory import Trajectory as Trajectory
from ._trajectory import MultiTrajectory as MultiTrajectory
from ._noise import NOISE_TARGETS as NOISE_TARGETS
from ._noise import add_noise as add_noise
from ._noise import as_rng as as_rng
from ._noise import corrupt as corrupt
from ._noise import noise_sigma as noise_sigma
from ._noise import snr_to_eta as snr_to_eta
from ._differentiate import DIFFERENTIATOR_NAMES as DIFFERENTIATOR_NAMES
from ._differentiate import Differentiator as Differentiator
from ._differentiate import FiniteDifference as FiniteDifference
from ._differentiate import Given as Given
from ._differentiate import KalmanSmoother as KalmanSmoother
from ._differentiate import SavitzkyGolay as SavitzkyGolay
from ._differentiate import SmoothingSpline as SmoothingSpline
from ._differentiate import Spectral as Spectral
from ._differentiate import TotalVariation as TotalVariation
from ._differentiate import estimate_derivatives as estimate_derivatives
from ._differentiate import make_differentiator as make_differentiator
from ._floor import NOISE_SETTINGS as NOISE_SETTINGS
from ._floor import REL_FLOOR as REL_FLOOR
from ._floor import NoiseFloor as NoiseFloor
from ._floor import equation_floors as equation_floors
from ._floor import noise_floor as noise_floor
from ._floor import noise_variance as noise_variance
from ._holds import HOLDS as HOLDS
from ._holds import check_hold as check_hold
from ._holds import rk4_sampled as rk4_sampled
from ._holds import stage_inputs as stage_inputs

Spline = SmoothingSpline
"""The older name of :class:`SmoothingSpline`.

Examples
--------
>>> from charcurves.data import SmoothingSpline, Spline
>>> Spline is SmoothingSpline
True
"""
