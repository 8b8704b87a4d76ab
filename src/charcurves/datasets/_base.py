"""What a benchmark loader returns, and where its files are."""

from __future__ import annotations

import dataclasses
import os

from ..data import Trajectory

__all__ = ["BenchmarkData", "data_folder"]


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

    Examples
    --------
    >>> from charcurves.datasets import BenchmarkData
    >>> from charcurves.systems import get_system
    >>> record = get_system("duffing").simulate(t_end=20.0, n_points=401)
    >>> data = BenchmarkData(name="mine", estimation=record.slice(slice(0, 300)),
    ...                      tests={"tail": record.slice(slice(300, 401))}, init_window=20, unit="m",
    ...                      literature={}, source="simulated")
    >>> list(data.tests), data.tests["tail"].t.size
    (['tail'], 101)
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
