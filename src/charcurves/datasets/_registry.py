"""The registry of benchmark loaders: ``charcurves benchmark --real NAME``."""

from __future__ import annotations

from collections.abc import Callable

from .._errors import ConfigError
from ._base import BenchmarkData
from ._bouc_wen import bouc_wen
from ._silverbox import silverbox

__all__ = ["BENCHMARKS", "get_benchmark"]


def _loaders() -> dict[str, Callable]:
    # further benchmarks add their loader here
    return {"silverbox": silverbox, "bouc-wen": bouc_wen}


#: the benchmark names ``charcurves benchmark --real`` accepts
BENCHMARKS = ("silverbox", "bouc-wen")


def get_benchmark(name: str, data_dir=None) -> BenchmarkData:
    """The benchmark ``name`` (one of :data:`BENCHMARKS`) loaded from ``data_dir``.

    Examples
    --------
    >>> from charcurves.datasets import BENCHMARKS, get_benchmark
    >>> BENCHMARKS
    ('silverbox', 'bouc-wen')
    >>> get_benchmark("wiener-hammerstein")
    Traceback (most recent call last):
    ...
    charcurves._errors.ConfigError: unknown real benchmark 'wiener-hammerstein'; choose one of silverbox, bouc-wen
    """
    loaders = _loaders()
    key = str(name).strip().lower()
    if key not in loaders:
        raise ConfigError(f"unknown real benchmark {name!r}; choose one of {', '.join(BENCHMARKS)}")
    return loaders[key](data_dir=data_dir)
