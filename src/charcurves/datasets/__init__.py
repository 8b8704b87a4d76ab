"""Benchmark records with their official splits: the estimation record, the test records and the
initialisation window of each test (the samples that only fit the initial state).

Public API
----------
silverbox(data_dir=None)        the Silverbox (Wigren & Schoukens 2013): estimation + three test sets
BenchmarkData                   what a loader returns
BENCHMARKS                      name -> loader (the hook for further benchmarks, e.g. Bouc-Wen)
"""

from ._base import BenchmarkData as BenchmarkData
from ._registry import BENCHMARKS as BENCHMARKS
from ._registry import get_benchmark as get_benchmark
from ._silverbox import silverbox as silverbox

__all__ = ["BENCHMARKS", "BenchmarkData", "get_benchmark", "silverbox"]
