"""Fitting: the estimator, the one fitting path every representation and template goes through, and
the paper's twelve methods as presets. It also re-exports the names of the layers below it that a
fit uses (the fitted model from ``charcurves.model``, the objectives from ``charcurves.objectives``,
the training presets from ``charcurves.train``), so ``from charcurves.fitting import ...`` keeps working.

Public API
----------
CharacteristicCurves(template=..., differentiator=..., objective=..., post_sr=...)   the estimator
CharacteristicCurves.from_method("nn-cc+sym", family=...), MethodPreset   the method presets
fit(record, method="nn-cc+sym", ...)                       shortcut
EquationError(), OutputError(...), Auto(...), Objective   objectives (Objective: the interface)
FittedModel, load_model                                    fitted models and their files
plot_curves, plot_model, model_html, curve_lines, ...      views of a fitted model (figures, text, HTML)
METHODS, PRESETS, TrainingPreset                           method and training presets
window_free_run_error, estimate_window_state        validation with an initialisation window (hidden states)
fit_ensemble(s), bootstrap_records, residual_block, detect_symmetry, parity_tests   ensembles and parity tests
curve_band, posterior_bands, uncertainty_summary, LinearPosterior   the posterior of a fit
closed_form_posterior, ClosedFormPosterior     the posterior of post-SR constants
"""

from ._ensemble import ENSEMBLE_KINDS as ENSEMBLE_KINDS
from ._ensemble import MIN_MEMBERS as MIN_MEMBERS
from ._ensemble import Ensemble as Ensemble
from ._ensemble import bootstrap_records as bootstrap_records
from ._ensemble import residual_block as residual_block
from ._ensemble import check_band_options as check_band_options
from ._ensemble import fit_ensemble as fit_ensemble
from ._ensemble import fit_ensembles as fit_ensembles
from ._estimator import MAX_SEED as MAX_SEED
from ._estimator import CharacteristicCurves as CharacteristicCurves
from ._estimator import fit as fit
from ._fit_path import JUMP_F_THRESHOLD as JUMP_F_THRESHOLD
from ._fit_path import dry_friction_test as dry_friction_test
from ._harmonics import HARMONIC_F_THRESHOLD as HARMONIC_F_THRESHOLD
from ._harmonics import harmonic_test as harmonic_test
from ..train import l0_weight as l0_weight
from ._methods import DEFAULT_BASIS as DEFAULT_BASIS
from ._methods import DEFAULT_GENERAL_BASIS as DEFAULT_GENERAL_BASIS
from ._methods import METHODS as METHODS
from ._methods import parse_basis_option as parse_basis_option
from ._methods import parse_symmetry as parse_symmetry
from ._methods import shared_fit_base as shared_fit_base
from ..model import FORMAT_VERSION as FORMAT_VERSION
from ..model import MODEL_SCHEMA as MODEL_SCHEMA
from ..model import FittedModel as FittedModel
from ..statespace import load_model as load_model
from ..model import validate_model_document as validate_model_document
from ..model import check_model_digest as check_model_digest
from ..model import model_digest as model_digest
from ..objectives import OBJECTIVES as OBJECTIVES
from ..objectives import EquationError as EquationError
from ..objectives import OutputError as OutputError
from ..objectives import Objective as Objective
from ..objectives import resolve_objective as resolve_objective
from ..model import closed_form_text as closed_form_text
from ..objectives import free_run_diagnostics as free_run_diagnostics
from ..objectives import output_error_fit as output_error_fit
from ..objectives import refine_output_error as refine_output_error
from ..model import summary_lines as summary_lines
from ._legacy import cli_objective as cli_objective
from ._legacy import legacy_options as legacy_options
from ._method_preset import MethodPreset as MethodPreset
from ..objectives import Auto as Auto
from ._pipeline import fit_with_post_sr as fit_with_post_sr
from ._pipeline import raw_fit as raw_fit
from ._records import RecordSet as RecordSet
from ..model import figure_png as figure_png
from ..model import plot_curves as plot_curves
from ..model import plot_model as plot_model
from ..model import resolve_truth as resolve_truth
from ._post_sr import DATA_LOSS_TOLERANCE as DATA_LOSS_TOLERANCE
from ._post_sr import distill_model as distill_model
from ._post_sr_posterior import ClosedFormPosterior as ClosedFormPosterior
from ._post_sr_posterior import closed_form_posterior as closed_form_posterior
from ..model import curve_band as curve_band
from ..model import model_posterior as model_posterior
from ..model import posterior_bands as posterior_bands
from ..model import scalar_lines as scalar_lines
from ..model import uncertainty_summary as uncertainty_summary
from ..model import closed_form_lines as closed_form_lines
from ..train import COVARIANCE_KINDS as COVARIANCE_KINDS
from ..train import LinearPosterior as LinearPosterior
from ..train import hac_bandwidth as hac_bandwidth
from ..train import PRESETS as PRESETS
from ..train import TrainingPreset as TrainingPreset
from ..train import get_preset as get_preset
from ._residual_tests import ar_whitener as ar_whitener
from ._residual_tests import autocorrelation as autocorrelation
from ._residual_tests import bin_indices as bin_indices
from ._residual_tests import binned_test as binned_test
from ._residual_tests import binned_tests as binned_tests
from ._residual_tests import input_correlation as input_correlation
from ._residual_tests import whiteness as whiteness
from ._lack_of_fit import LACK_OF_FIT_BINS as LACK_OF_FIT_BINS
from ._lack_of_fit import LACK_OF_FIT_LEVEL as LACK_OF_FIT_LEVEL
from ._lack_of_fit import SPARSE_LACK_OF_FIT as SPARSE_LACK_OF_FIT
from ._lack_of_fit import apply_lack_of_fit as apply_lack_of_fit
from ._lack_of_fit import lack_of_fit_bias as lack_of_fit_bias
from ._lack_of_fit import sparse_fit as sparse_fit
from ._self_check import RESIDUAL_LEVEL as RESIDUAL_LEVEL
from ._self_check import RESIDUAL_MIN_EFFECT as RESIDUAL_MIN_EFFECT
from ._self_check import residual_check as residual_check
from ._self_check import residual_test_rows as residual_test_rows
from ._symbolic_fit import fit_sr as fit_sr
from ._symbolic_fit import fit_sr_cc as fit_sr_cc
from ._symbolic_fit import fit_symbolic as fit_symbolic
from ._symmetry import AUTO_MEMBERS as AUTO_MEMBERS
from ._symmetry import PARITY_THRESHOLD as PARITY_THRESHOLD
from ._detect import detect_symmetry as detect_symmetry
from ._symmetry import fit_many_auto as fit_many_auto
from ._symmetry import parity_tests as parity_tests
from ._symmetry import resolved_estimator as resolved_estimator
from ..model import DISPLAY_DIGITS as DISPLAY_DIGITS
from ..model import curve_lines as curve_lines
from ..model import curve_scale as curve_scale
from ..model import display_expression as display_expression
from ..model import display_number as display_number
from ..model import equation_text as equation_text
from ..model import fit_statistics as fit_statistics
from ..model import format_closed_form as format_closed_form
from ..model import model_html as model_html
from ..model import output_error_rows as output_error_rows
from ..model import settings_rows as settings_rows
from ..model import anchor_notes as anchor_notes
from ..statespace import START_NAMES as START_NAMES
from ..statespace import fit_state_space as fit_state_space
from ..statespace import StateSpaceModel as StateSpaceModel
from ..statespace import estimate_window_state as estimate_window_state
from ..statespace import window_free_run_error as window_free_run_error
