"""Curve representations and their fitted forms."""

from ._fitted import BasisFittedCurve as BasisFittedCurve
from ._fitted import FittedCurve as FittedCurve
from ._fitted import NeuralFittedCurve as NeuralFittedCurve
from ._neural import SYMMETRIES as SYMMETRIES
from ._neural import NeuralCurve as NeuralCurve
from ._fitted import SymbolicFittedCurve as SymbolicFittedCurve
from ._fitted import parse_basis_function as parse_basis_function
