"""Symbolic regression: engines behind one interface, post-SR distillation, SR and SR-CC.

Public API
----------
make_engine(sr_options) -> SymbolicRegressionEngine
    Operon (default) or PySR, with the shared parsimony selection and constant polishing.
distill_curve(curve, engine, *, n, random_state) -> SymbolicFittedCurve
distill_model(model, *, sr_options, random_state) -> FittedModel        (post-SR)
fit_sr(traj, template, ...) / fit_sr_cc(traj, template, ...) -> FittedModel

Examples
--------
>>> import numpy as np
>>> from charcurves.symbolic import make_engine
>>> z = np.linspace(-1.5, 1.5, 200)
>>> res = make_engine({"generations": 20}).fit(z[:, None], z**3 - z, ["z"], random_state=0)
>>> sorted(str(t.as_coeff_Mul()[1]) for t in res.expression.as_ordered_terms())
['z', 'z**3']
"""

from ._distill import distill_curve, distill_model, has_jump
from ._engine import (
    DEFAULT_SR_OPTIONS,
    OPERATORS,
    SELECTION_CRITERIA,
    SR_OPTION_KEYS,
    FrontEntry,
    OperonEngine,
    PySREngine,
    SRResult,
    SymbolicRegressionEngine,
    expression_complexity,
    make_engine,
    polish_constants,
    select_model,
)
from ._methods import decompose, fit_sr, fit_sr_cc

__all__ = [
    "DEFAULT_SR_OPTIONS",
    "OPERATORS",
    "SELECTION_CRITERIA",
    "SR_OPTION_KEYS",
    "FrontEntry",
    "OperonEngine",
    "PySREngine",
    "SRResult",
    "SymbolicRegressionEngine",
    "decompose",
    "distill_curve",
    "distill_model",
    "expression_complexity",
    "fit_sr",
    "fit_sr_cc",
    "has_jump",
    "make_engine",
    "polish_constants",
    "select_model",
]
