"""What a benchmark loader returns, and the registry of loaders."""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable

from .._errors import ConfigError
from ..data import Trajectory

__all__ = ["BenchmarkData", "BENCHMARKS", "get_benchmark", "data_folder"]


@dataclasses.dataclass(frozen=True)
class BenchmarkData:
    """A benchmark's records with its official split.

    Attributes
    ----------
    name : str
    estimation : Trajectory
        The record to fit (x: the measured output, F: the input).
    tests : dict of str to Trajectory
        The official test records, by name, in the benchmark's order.
    init_window : int
        Samples at the start of each test record that only fit the initial state; the RMSE is
        counted after them (``validate --init-window``, ``free_run_error(init_window=...)``).
    unit : str
        The unit of x (the RMSE's unit).
    literature : dict
        Published test RMSE in ``unit`` by model and test name, each with its source.
    source : str
        Where the records were read from.
    """

    name: str
    estimation: Trajectory
    tests: dict
    init_window: int
    unit: str
    literature: dict
    source: str


def data_folder(data_dir, benchmark: str) -> str | None:
    """The folder holding ``<benchmark>/``: ``data_dir``, else $CHARCURVES_DATA_DIR; None when neither is set."""
    folder = data_dir if data_dir is not None else os.environ.get("CHARCURVES_DATA_DIR")
    if folder is None:
        return None
    return os.path.join(os.fspath(folder), benchmark)


def _loaders() -> dict[str, Callable]:
    from ._silverbox import silverbox

    # further benchmarks add their loader here (e.g. "bouc-wen": a simulation of its published definition)
    return {"silverbox": silverbox}


#: the benchmark names ``charcurves benchmark --real`` accepts
BENCHMARKS = ("silverbox",)


def get_benchmark(name: str, data_dir=None) -> BenchmarkData:
    """The benchmark ``name`` (one of :data:`BENCHMARKS`) loaded from ``data_dir``."""
    loaders = _loaders()
    key = str(name).strip().lower()
    if key not in loaders:
        raise ConfigError(f"unknown real benchmark {name!r}; choose one of {', '.join(BENCHMARKS)}")
    return loaders[key](data_dir=data_dir)
