"""Training: batched least-squares problems, Adam then Levenberg-Marquardt with MacKay's evidence,
warm starts, long records in two stages, and the fitters built on them (gradient-trained curves of
any mix, linear least squares and pysindy), with the training presets they read.

Public API
----------
TrainingPreset, PRESETS, get_preset                     how curves are built and trained
fit_gradient, fit_linear, l0_weight                     the gradient-trained and the linear fitter
BatchedProblem, CurveTerm, LeastSquaresProblem          problems the training loop sees
train, train_in_chunks, train_with_preset, TrainingLog  the training loop
EvidenceSweeps, evidence_update, initial_decay, ...     Bayesian regularisation (MacKay's evidence)
subset_indices, is_long, train_long_record              records of more than SUBSET_SAMPLES samples
"""

from ._evidence import EVIDENCE_GUARD as EVIDENCE_GUARD
from ._evidence import EVIDENCE_SETTLED as EVIDENCE_SETTLED
from ._evidence import SWEEP_TOL as SWEEP_TOL
from ._evidence import EvidenceSweeps as EvidenceSweeps
from ._evidence import decay_moves as decay_moves
from ._evidence import evidence_update as evidence_update
from ._evidence import initial_decay as initial_decay
from ._evidence import set_evidence as set_evidence
from ._evidence import with_decay as with_decay
from ._gradient_fit import fit_gradient as fit_gradient
from ._linear_fit import column_name as column_name
from ._linear_fit import fit_linear as fit_linear
from ._linear_fit import l0_weight as l0_weight
from ._long_record import SUBSET_SAMPLES as SUBSET_SAMPLES
from ._long_record import is_long as is_long
from ._long_record import subset_indices as subset_indices
from ._long_record import train_long_record as train_long_record
from ._presets import PRESETS as PRESETS
from ._presets import TrainingPreset as TrainingPreset
from ._presets import get_preset as get_preset
from ._problem import DECAY_GROUPS as DECAY_GROUPS
from ._problem import RELEVANCE_LABEL as RELEVANCE_LABEL
from ._problem import BatchedProblem as BatchedProblem
from ._problem import CurveTerm as CurveTerm
from ._problem import LeastSquaresProblem as LeastSquaresProblem
from ._sr3 import constrained_sr3 as constrained_sr3
from ._train import BatchedAdam as BatchedAdam
from ._train import TrainingLog as TrainingLog
from ._train import chunk_log as chunk_log
from ._train import merge_logs as merge_logs
from ._train import torch_threads as torch_threads
from ._train import train as train
from ._train import train_in_chunks as train_in_chunks
from ._train import train_with_preset as train_with_preset
