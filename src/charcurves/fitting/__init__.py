"""Fitters and the named methods of the paper."""

from ._estimator import METHODS as METHODS
from ._estimator import CharacteristicCurves as CharacteristicCurves
from ._estimator import fit as fit
from ._estimator import parse_symmetry as parse_symmetry
from ._linear import DEFAULT_BASIS as DEFAULT_BASIS
from ._model import FittedModel as FittedModel
from ._model import load_model as load_model
from ._presets import PRESETS as PRESETS
from ._presets import TrainingPreset as TrainingPreset
from ._presets import get_preset as get_preset
