"""Curve representations (what a characteristic curve may be) and fitted curves.

Representations (compose them into a template): :class:`Neural`, :class:`Polynomial`,
:class:`SparseLibrary`, :class:`Basis`, :class:`Symbolic` (:class:`ContinuedPolynomial`: linear
outside its range); the interface they share is
:class:`AbstractCurve`, and :class:`LinearCurve` is the extension point for user-written
representations that are linear in their parameters.
"""

from ._base import SYMMETRY_NAMES as SYMMETRY_NAMES
from ._base import AbstractCurve as AbstractCurve
from ._base import LinearCurve as LinearCurve
from ._base import LinearParametrisation as LinearParametrisation
from ._base import normalise_symmetry as normalise_symmetry
from ._base import register_curve as register_curve
from ._expr import ALLOWED_FUNCS as ALLOWED_FUNCS
from ._expr import expression_cost_problem as expression_cost_problem
from ._expr import expression_shape_problem as expression_shape_problem
from ._expr import first_disallowed_token as first_disallowed_token
from ._expr import parse_basis_function as parse_basis_function
from ._fitted import BasisFittedCurve as BasisFittedCurve
from ._fitted import FittedCurve as FittedCurve
from ._fitted import LinearFittedCurve as LinearFittedCurve
from ._fitted import NeuralFittedCurve as NeuralFittedCurve
from ._fitted import SymbolicFittedCurve as SymbolicFittedCurve
from ._input_map import neural_input_map as neural_input_map
from ._registry import curve_from_spec as curve_from_spec
from ._registry import register_curve_kind as register_curve_kind
from ._mlp import ACTIVATIONS as ACTIVATIONS
from ._mlp import BatchedMLP as BatchedMLP
from ._neural import EVEN_INPUT_WEIGHTS as EVEN_INPUT_WEIGHTS
from ._neural import SYMMETRIES as SYMMETRIES
from ._neural import NeuralCurve as NeuralCurve
from ._neural import jump_log_eps as jump_log_eps
from ._polynomial import POLY_BASES as POLY_BASES
from ._polynomial import RESCALINGS as RESCALINGS
from ._polynomial import Polynomial as Polynomial
from ._continued import ContinuedPolynomial as ContinuedPolynomial
from ._polynomial import build_polynomial_curve as build_polynomial_curve
from ._polynomial import column_numpy as column_numpy
from ._polynomial import poly_powers as poly_powers
from ._polynomial import series_in_s as series_in_s
from ._refit import CurveRefit as CurveRefit
from ._refit import SymbolicParametrisation as SymbolicParametrisation
from ._refit import trainable as trainable
from ._specs import SPARSE_OPTIMIZERS as SPARSE_OPTIMIZERS
from ._specs import Basis as Basis
from ._specs import Neural as Neural
from ._specs import SparseLibrary as SparseLibrary
from ._specs import Symbolic as Symbolic
