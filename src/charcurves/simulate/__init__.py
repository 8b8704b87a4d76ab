"""Forward simulation of fitted models and of benchmark systems, with failure statuses."""

from ._batch import simulate_model_batch as simulate_model_batch
from ._curve_eval import PreparedCurve as PreparedCurve
from ._curve_eval import prepare_curve as prepare_curve
from ._forward import STATUSES as STATUSES
from ._forward import SimulationResult as SimulationResult
from ._forward import prepare_model_curves as prepare_model_curves
from ._forward import simulate_model as simulate_model
from ._forward import sinusoidal_forcing as sinusoidal_forcing
from ._forward import solver_class as solver_class
from ._families import simulate_template_model as simulate_template_model
from ._sampled import HOLDS as HOLDS
from ._sampled import rk4_sampled as rk4_sampled
from ._sampled import simulate_sampled as simulate_sampled
from ._sampled import stage_inputs as stage_inputs
from ._validate import estimate_initial_state as estimate_initial_state
from ._validate import free_run_error as free_run_error
from ._validate import validate_cli as validate_cli
from ._predictive import predictive_band as predictive_band
from ._families import SimulationStopped as SimulationStopped
from ._sampled import check_hold as check_hold
