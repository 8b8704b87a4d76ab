"""State-space templates with hidden states, fitted by output error (grey-box identification).

fit_state_space                                 fit a :class:`~charcurves.templates.StateSpace` template
StateSpaceModel                                 the fitted model: free runs, curves, save/load
START_NAMES                                     the starts a fit can use ("growing", "linear")
estimate_window_state, window_free_run_error    validation with an initialisation window
load_model                                      load a model file, state-space or not

``charcurves.fitting`` re-exports these names; this package sits below it (it imports the
objectives, the trainer, curves, templates and models, never the estimator).
"""

from ._fit import START_NAMES as START_NAMES
from ._fit import fit_state_space as fit_state_space
from ._model import StateSpaceModel as StateSpaceModel
from ._model import load_model as load_model
from ._window import estimate_window_state as estimate_window_state
from ._window import window_free_run_error as window_free_run_error

__all__ = ["START_NAMES", "StateSpaceModel", "estimate_window_state", "fit_state_space", "load_model",
           "window_free_run_error"]
