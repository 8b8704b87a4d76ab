"""Forward simulation of fitted models and of benchmark systems, with failure statuses."""

from ._forward import SimulationResult as SimulationResult
from ._forward import simulate_model as simulate_model
from ._forward import sinusoidal_forcing as sinusoidal_forcing
