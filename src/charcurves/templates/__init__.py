"""Structural templates: which curves exist, on which argument, how they combine into the equation.

Compose a template from its family and a representation per curve --
:class:`Separable`, :class:`PositionDamping`, :class:`FirstOrder`, :class:`TwoDOF` or a
user-written :class:`Equation` -- and hand it to :class:`charcurves.CharacteristicCurves`.
:class:`EquationTemplate` is the parsed structure every fitter works with.
"""

from ._families import FAMILY_NAMES as FAMILY_NAMES
from ._families import Equation as Equation
from ._families import FirstOrder as FirstOrder
from ._families import PositionDamping as PositionDamping
from ._families import Separable as Separable
from ._families import Template as Template
from ._families import TwoDOF as TwoDOF
from ._families import as_template as as_template
from ._families import get_template as get_template
from ._forward import ForwardModel as ForwardModel
from ._parse import check_equation_option as check_equation_option
from ._parse import display as display
from ._families import parse_equation as parse_equation
from ._record import derivatives_given as derivatives_given
from ._record import prepare_record as prepare_record
from ._record import read_record as read_record
from ._record import sticking_mask as sticking_mask
from ._record import ESTIMATED_STICK_TOL as ESTIMATED_STICK_TOL
from ._structure import FAMILY_ANCHORS as FAMILY_ANCHORS
from ._structure import FAMILY_EQUATIONS as FAMILY_EQUATIONS
from ._structure import EquationTemplate as EquationTemplate
from ._structure import evaluate_signal as evaluate_signal
from ._structure import record_columns as record_columns
from ._state_space import HiddenAnalysis as HiddenAnalysis
from ._state_space import StateSpace as StateSpace
from ._state_space import parse_measured as parse_measured
