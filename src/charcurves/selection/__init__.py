"""Model selection (the paper's appendix B): the three validation loops, the family search and
uncertainty bands. Ensembles and parity tests live in :mod:`charcurves.fitting` (``symmetry="auto"``
uses them while fitting) and are re-exported here."""

from ..fitting import ENSEMBLE_KINDS as ENSEMBLE_KINDS
from ..fitting import Ensemble as Ensemble
from ..fitting import bootstrap_records as bootstrap_records
from ..fitting import detect_symmetry as detect_symmetry
from ..fitting import fit_ensemble as fit_ensemble
from ..fitting import fit_ensembles as fit_ensembles
from ..fitting import parity_tests as parity_tests
from ._bands import attach_bands as attach_bands
from ._bands import band_coverage as band_coverage
from ._bands import curve_bands as curve_bands
from ._loops import LoopResult as LoopResult
from ..data import NoiseFloor as NoiseFloor
from ._family import SelectionReport as SelectionReport
from ._loops import inner_loop as inner_loop
from ._loops import middle_loop as middle_loop
from ..data import noise_floor as noise_floor
from ._loops import outer_loop as outer_loop
from ._family import select_family as select_family
from ._family import split_record as split_record
