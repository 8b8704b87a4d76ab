"""Training: batched least-squares problems, Adam then Levenberg-Marquardt with MacKay's evidence,
warm starts, long records in two stages, and the fitters built on them (gradient-trained curves of
any mix, linear least squares and pysindy), with the training presets they read.

Public API
----------
TrainingPreset, PRESETS, get_preset      how curves are built and trained (re-exported by charcurves.fitting)
l0_weight, constrained_sr3               the sparse linear fits' weight and SR3 solver
EVIDENCE_GUARD, SWEEP_TOL, ...           constants of the evidence updates

The layers above also import the training loop (``train``, ``torch_threads``), the problem base
class (``LeastSquaresProblem``), the fitters (``fit_gradient``, ``fit_linear``) and
``subset_indices`` from here; the other parts (batched problems, Adam, evidence sweeps, warm starts,
long records) are used inside this package.
"""

from ._evidence import EVIDENCE_GUARD as EVIDENCE_GUARD
from ._evidence import EVIDENCE_SETTLED as EVIDENCE_SETTLED
from ._evidence import SWEEP_TOL as SWEEP_TOL
from ._linear_fit import l0_weight as l0_weight
from ._long_record import SUBSET_SAMPLES as SUBSET_SAMPLES
from ._posterior_linear import COVARIANCE_KINDS as COVARIANCE_KINDS
from ._posterior_linear import LinearPosterior as LinearPosterior
from ._posterior_linear import hac_bandwidth as hac_bandwidth
from ._posterior_network import NetworkPosterior as NetworkPosterior
from ._posterior_network import gauge_map as gauge_map
from ._posterior_factors import covariance_factors as covariance_factors
from ._presets import PRESETS as PRESETS
from ._presets import TrainingPreset as TrainingPreset
from ._presets import get_preset as get_preset
from ._problem import DECAY_GROUPS as DECAY_GROUPS
from ._problem import RELEVANCE_LABEL as RELEVANCE_LABEL
from ._sr3 import constrained_sr3 as constrained_sr3

# the interface the layers above build on (not on the API page: see the modules' docstrings)
from ._train import torch_threads, train  # noqa: F401
from ._gradient_fit import fit_gradient  # noqa: F401
from ._linear_fit import fit_linear  # noqa: F401
from ._long_record import subset_indices  # noqa: F401
from ._problem import LeastSquaresProblem  # noqa: F401
from ._posterior_network import attach_posterior, laplace_posterior  # noqa: F401

__all__ = ["DECAY_GROUPS", "EVIDENCE_GUARD", "EVIDENCE_SETTLED", "PRESETS", "RELEVANCE_LABEL", "SUBSET_SAMPLES",
           "SWEEP_TOL", "TrainingPreset", "constrained_sr3", "get_preset", "l0_weight", "COVARIANCE_KINDS",
           "LinearPosterior", "NetworkPosterior", "gauge_map", "hac_bandwidth", "covariance_factors"]
