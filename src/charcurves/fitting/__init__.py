"""Fitting: objectives, the one fitting path every representation and template goes through, the
fitted model and its files, and the paper's twelve methods as presets.

Public API
----------
CharacteristicCurves(template=..., differentiator=..., objective=..., post_sr=...)   the estimator
CharacteristicCurves.from_method("nn-cc+sym", family=...), MethodPreset   the method presets
fit(record, method="nn-cc+sym", ...)                       shortcut
EquationError(), OutputError(...), Auto(...)               objectives
FittedModel, load_model                                    fitted models and their files
plot_curves, plot_model, model_html, curve_lines, ...      views of a fitted model (figures, text, HTML)
METHODS, PRESETS, TrainingPreset                           method and training presets
fit_ensemble(s), bootstrap_records, detect_symmetry, parity_tests   ensembles and parity tests
"""

from ._ensemble import ENSEMBLE_KINDS as ENSEMBLE_KINDS
from ._ensemble import MIN_MEMBERS as MIN_MEMBERS
from ._ensemble import Ensemble as Ensemble
from ._ensemble import bootstrap_records as bootstrap_records
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
from ._linear_fit import l0_weight as l0_weight
from ._methods import DEFAULT_BASIS as DEFAULT_BASIS
from ._methods import DEFAULT_GENERAL_BASIS as DEFAULT_GENERAL_BASIS
from ._methods import METHODS as METHODS
from ._methods import parse_basis_option as parse_basis_option
from ._methods import parse_symmetry as parse_symmetry
from ._methods import shared_fit_base as shared_fit_base
from ._model import FORMAT_VERSION as FORMAT_VERSION
from ._model import MODEL_SCHEMA as MODEL_SCHEMA
from ._model import FittedModel as FittedModel
from ._model import load_model as load_model
from ._model import validate_model_document as validate_model_document
from ._model_schema import check_model_digest as check_model_digest
from ._model_schema import model_digest as model_digest
from ._legacy import cli_objective as cli_objective
from ._legacy import legacy_options as legacy_options
from ._method_preset import MethodPreset as MethodPreset
from ._objectives import OBJECTIVES as OBJECTIVES
from ._objectives import Auto as Auto
from ._objectives import EquationError as EquationError
from ._objectives import OutputError as OutputError
from ._oe_report import closed_form_text as closed_form_text
from ._output_error import free_run_diagnostics as free_run_diagnostics
from ._output_error import output_error_fit as output_error_fit
from ._output_error import refine_output_error as refine_output_error
from ._oe_report import summary_lines as summary_lines
from ._pipeline import fit_with_post_sr as fit_with_post_sr
from ._pipeline import raw_fit as raw_fit
from ._plots import figure_png as figure_png
from ._plots import plot_curves as plot_curves
from ._plots import plot_model as plot_model
from ._plots import resolve_truth as resolve_truth
from ._post_sr import DATA_LOSS_TOLERANCE as DATA_LOSS_TOLERANCE
from ._post_sr import distill_model as distill_model
from ._presets import PRESETS as PRESETS
from ._presets import TrainingPreset as TrainingPreset
from ._presets import get_preset as get_preset
from ._residual_tests import ar_whitener as ar_whitener
from ._residual_tests import autocorrelation as autocorrelation
from ._residual_tests import bin_indices as bin_indices
from ._residual_tests import binned_test as binned_test
from ._residual_tests import binned_tests as binned_tests
from ._residual_tests import input_correlation as input_correlation
from ._residual_tests import whiteness as whiteness
from ._self_check import RESIDUAL_LEVEL as RESIDUAL_LEVEL
from ._self_check import RESIDUAL_MIN_EFFECT as RESIDUAL_MIN_EFFECT
from ._self_check import residual_check as residual_check
from ._self_check import residual_test_rows as residual_test_rows
from ._symbolic_fit import fit_sr as fit_sr
from ._symbolic_fit import fit_sr_cc as fit_sr_cc
from ._symbolic_fit import fit_symbolic as fit_symbolic
from ._symmetry import AUTO_MEMBERS as AUTO_MEMBERS
from ._symmetry import PARITY_THRESHOLD as PARITY_THRESHOLD
from ._symmetry import detect_symmetry as detect_symmetry
from ._symmetry import fit_many_auto as fit_many_auto
from ._symmetry import parity_tests as parity_tests
from ._symmetry import resolved_estimator as resolved_estimator
from ._views import DISPLAY_DIGITS as DISPLAY_DIGITS
from ._views import curve_lines as curve_lines
from ._views import curve_scale as curve_scale
from ._views import display_expression as display_expression
from ._views import display_number as display_number
from ._views import equation_text as equation_text
from ._views import fit_statistics as fit_statistics
from ._views import format_closed_form as format_closed_form
from ._views import model_html as model_html
from ._views import output_error_rows as output_error_rows
from ._views import settings_rows as settings_rows
