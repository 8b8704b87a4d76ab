"""Symbolic regression: engines behind one interface, expression utilities, curve distillation.

Public API
----------
make_engine(sr_options) -> SymbolicRegressionEngine
    Operon (default) or PySR, with the shared parsimony selection and constant polishing.
distill_curve(curve, engine, *, n, random_state) -> SymbolicFittedCurve
    A learned curve's closed form (post-SR works curve by curve through it).
decompose(expr, var_of_curve)
    Split an expression of several variables into univariate parts.

Fitting with symbolic curves (SR, SR-CC) and post-SR of whole models are fitters, in
:mod:`charcurves.fitting`.

Examples
--------
>>> import numpy as np
>>> from charcurves.symbolic import make_engine
>>> z = np.linspace(-1.5, 1.5, 200)
>>> res = make_engine({"generations": 5}).fit(z[:, None], z**3 - z, ["z"], random_state=0)
>>> sorted(str(t.as_coeff_Mul()[1]) for t in res.expression.as_ordered_terms())
['z', 'z**3']
"""

from ._decompose import decompose
from ._distill import (CLOSED_FORM_GAIN, DATA_LOSS_TOLERANCE, POST_SR_OPTIONS, TRIG_TURNS, distill_curve, distill_curve_front, has_jump,
                       polynomial_operators, post_sr_engine, turns)
from ._engine import (
    CLOSED_FORM_OPERATORS,
    DEFAULT_SR_OPTIONS,
    OPERATORS,
    POLY_OPERATORS,
    SR_OPTION_KEYS,
    TANH_OPERATORS,
    OperonEngine,
    SymbolicRegressionEngine,
    operators_option,
    searches_running,
)
from ._make import make_engine
from ._memo import forget_searches
from ._stoppable import SearchInterrupted
from ._pysr import PySREngine
from ._expressions import eval_expression, expression_complexity, parse_infix, polish_constants, split_terms
from ._selection import SELECTION_CRITERIA, FrontEntry, SRResult, select_model

__all__ = [
    "CLOSED_FORM_GAIN",
    "CLOSED_FORM_OPERATORS",
    "DEFAULT_SR_OPTIONS",
    "OPERATORS",
    "POLY_OPERATORS",
    "POST_SR_OPTIONS",
    "DATA_LOSS_TOLERANCE",
    "SELECTION_CRITERIA",
    "SR_OPTION_KEYS",
    "TRIG_TURNS",
    "TANH_OPERATORS",
    "FrontEntry",
    "OperonEngine",
    "PySREngine",
    "SRResult",
    "SearchInterrupted",
    "SymbolicRegressionEngine",
    "decompose",
    "distill_curve",
    "distill_curve_front",
    "eval_expression",
    "expression_complexity",
    "forget_searches",
    "searches_running",
    "has_jump",
    "turns",
    "make_engine",
    "operators_option",
    "polynomial_operators",
    "parse_infix",
    "polish_constants",
    "post_sr_engine",
    "select_model",
    "split_terms",
]
