"""Structural templates (families) that say which curves exist and how they combine."""

from ._separable import FAMILY_NAMES as FAMILY_NAMES
from ._separable import SeparableTemplate as SeparableTemplate
from ._separable import get_template as get_template
from ._separable import sticking_mask as sticking_mask
from ._general import EquationTemplate as EquationTemplate
from ._general import FAMILY_EQUATIONS as FAMILY_EQUATIONS
from ._general import parse_equation as parse_equation
