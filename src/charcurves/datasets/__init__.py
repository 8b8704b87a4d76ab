"""Benchmark records with their official splits: the estimation record, the test records and the
initialisation window of each test (the samples that only fit the initial state).

Public API
----------
silverbox(data_dir=None)        the Silverbox (Wigren & Schoukens 2013): estimation + three test sets
bouc_wen(seed=0, ...)           the Bouc-Wen benchmark (Noel & Schoukens 2016), generated from its definition
bouc_wen_output(u_fine)         the Bouc-Wen system's noise-free response to a force
BenchmarkData                   what a loader returns
BENCHMARKS                      the names get_benchmark and `benchmark --real` take (silverbox, bouc-wen)
"""

from ._base import BenchmarkData as BenchmarkData
from ._bouc_wen import BOUC_WEN_FS as BOUC_WEN_FS
from ._bouc_wen import BOUC_WEN_PARAMETERS as BOUC_WEN_PARAMETERS
from ._bouc_wen import bouc_wen as bouc_wen
from ._bouc_wen import bouc_wen_output as bouc_wen_output
from ._registry import BENCHMARKS as BENCHMARKS
from ._registry import get_benchmark as get_benchmark
from ._silverbox import silverbox as silverbox

__all__ = ["BENCHMARKS", "BOUC_WEN_FS", "BOUC_WEN_PARAMETERS", "BenchmarkData", "bouc_wen", "bouc_wen_output",
           "get_benchmark", "silverbox"]
