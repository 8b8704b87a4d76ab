"""The fitted model: its curves, gain and constant, its file format (save/load, schema, digest), and
its views for people (closed forms to the precision a fit supports, text, HTML, figures).

Public API
----------
FittedModel, load_model                                    a fitted model and its files
FORMAT_VERSION, MODEL_SCHEMA, validate_model_document      the file format
model_digest, check_model_digest                           the digest of a model's document
display_expression, format_closed_form, display_number     closed forms and numbers as printed
equation_text, curve_lines, fit_statistics, model_html ... views of a model (text, HTML)
plot_curves, plot_model, figure_png, resolve_truth         figures (matplotlib loads when drawing)
closed_form_text, summary_lines                            what the command line prints of a fit
StoredPosterior, PlusMinus, constant_sds_of, closed_form_lines   a fit's posterior as saved; constants' ±
"""

from ._display import DISPLAY_DIGITS as DISPLAY_DIGITS
from ._display import curve_scale as curve_scale
from ._display import display_expression as display_expression
from ._display import display_number as display_number
from ._display import format_closed_form as format_closed_form
from ._model import DISTILLABLE_METHODS as DISTILLABLE_METHODS
from ._model import FORMAT_VERSION as FORMAT_VERSION
from ._model import MODEL_SCHEMA as MODEL_SCHEMA
from ._model import FittedModel as FittedModel
from ._model import load_model as load_model
from ._model import validate_model_document as validate_model_document
from ._model_schema import check_model_digest as check_model_digest
from ._model_schema import model_digest as model_digest
from ._oe_report import closed_form_text as closed_form_text
from ._oe_report import summary_lines as summary_lines
from ._plots import figure_png as figure_png
from ._posterior import curve_band as curve_band
from ._posterior import model_posterior as model_posterior
from ._posterior import posterior_bands as posterior_bands
from ._posterior import scalar_lines as scalar_lines
from ._posterior import sup_t_factor as sup_t_factor
from ._posterior import uncertainty_summary as uncertainty_summary
from ._posterior_constants import PlusMinus as PlusMinus
from ._posterior_constants import closed_form_lines as closed_form_lines
from ._posterior_constants import constant_sds_of as constant_sds_of
from ._posterior_lack import LackOfFitPosterior as LackOfFitPosterior
from ._posterior_store import StoredPosterior as StoredPosterior
from ._plots import plot_curves as plot_curves
from ._plots import plot_model as plot_model
from ._plots import resolve_truth as resolve_truth
from ._gauge_notes import anchor_notes as anchor_notes
from ._views import curve_lines as curve_lines
from ._views import equation_text as equation_text
from ._views import fit_statistics as fit_statistics
from ._views import model_html as model_html
from ._views import output_error_rows as output_error_rows
from ._views import settings_rows as settings_rows
from ._finish import finish_model as finish_model
