"""The Silverbox benchmark (Wigren & Schoukens, ECC 2013) with the official split of the
benchmark's data loader (the ``nonlinear-benchmarks`` package, ``nonlinear_benchmarks.Silverbox()``):
estimation on samples [40650, 105712) of SNLS80mV (the first 75 % of the multisine part), tests on
the rest of the multisine part [105712, 127400), on the arrow [100, 40575) ("arrow full") and on its
first 32000 samples [100, 32100) ("arrow without extrapolation": the amplitudes the estimation
record visits); an initialisation window of 50 samples on every test."""

from __future__ import annotations

import os

import numpy as np

from .._errors import ConfigError, DataError
from ._base import BenchmarkData, data_folder

__all__ = ["silverbox", "SILVERBOX_SPLIT", "SILVERBOX_FS"]

#: sampling frequency of the Silverbox records, Hz (10 MHz / 2**14)
SILVERBOX_FS = 1e7 / 2**14
#: rows of SNLS80mV: the estimation record and the three official tests
SILVERBOX_SPLIT = {
    "estimation": (40650, 105712),
    "multisine": (105712, 127400),
    "arrow_full": (100, 40575),
    "arrow_no_extrapolation": (100, 32100),
}
#: initialisation window of every test (``state_initialization_window_length`` of the official loader)
SILVERBOX_INIT_WINDOW = 50

#: published test RMSE in mV (literature; see docs/real-benchmarks.md for the sources)
SILVERBOX_LITERATURE: dict = {}


def _from_columns(u, y, name: str):
    from ..data import Trajectory

    t = np.arange(len(u)) / SILVERBOX_FS
    return Trajectory(t=t, x=np.asarray(y, dtype=float), F=np.asarray(u, dtype=float), name=name)


def _read_local(path: str):
    from ..io import read_csv_columns

    cols = read_csv_columns(path)
    if "V1" not in cols or "V2" not in cols:
        raise DataError(f"{path} has no V1 (input) and V2 (output) columns; give the SNLS80mV.csv of the "
                        "benchmark's SilverboxFiles.zip")
    return np.asarray(cols["V1"], dtype=float), np.asarray(cols["V2"], dtype=float)


def _read_package():
    """V1, V2 through the nonlinear-benchmarks package (it downloads the files once); None without it."""
    try:
        import nonlinear_benchmarks  # optional: not a dependency of charcurves
    except ImportError:
        return None
    try:
        full = nonlinear_benchmarks.Silverbox(train_test_split=False)
    except Exception as exc:  # a download that fails: say so, in one line
        raise DataError(f"nonlinear_benchmarks.Silverbox() could not load the data ({type(exc).__name__}: "
                        f"{str(exc).splitlines()[0][:120] if str(exc) else ''}); give the folder of "
                        "silverbox/SNLS80mV.csv with --data-dir or CHARCURVES_DATA_DIR") from None
    full = full[0] if isinstance(full, tuple) else full
    return np.asarray(full.u, dtype=float).reshape(-1), np.asarray(full.y, dtype=float).reshape(-1)


def silverbox(data_dir=None) -> BenchmarkData:
    """The Silverbox's estimation record and its three official test records.

    Parameters
    ----------
    data_dir : str or path, optional
        The folder that holds ``silverbox/SNLS80mV.csv``; default $CHARCURVES_DATA_DIR, else the
        ``nonlinear-benchmarks`` package when it is installed (it fetches the benchmark's files).

    Returns
    -------
    BenchmarkData
        x is the output V2, F the input V1, in volts, sampled at 610.35 Hz; the tests
        "multisine", "arrow_full" and "arrow_no_extrapolation", each with a 50-sample
        initialisation window; RMSE in mV.

    Examples
    --------
    A folder without the record is refused with the fix (with the files, ``data.estimation`` is
    the record to fit and ``data.tests`` the three test records):

    >>> import tempfile
    >>> from charcurves.datasets import silverbox
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     silverbox(data_dir=folder)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    charcurves._errors.ConfigError: no Silverbox record at .../silverbox/SNLS80mV.csv; give the folder ...
    """
    folder = data_folder(data_dir, "silverbox")
    if folder is not None:
        path = os.path.join(folder, "SNLS80mV.csv")
        if os.path.exists(path) and not os.path.isfile(path):  # a FIFO or device: never read (it may block)
            raise ConfigError(f"{path} is not a regular file (a folder, named pipe or device); save the benchmark's "
                              "SNLS80mV.csv there as a file")
        if not os.path.isfile(path):
            raise ConfigError(f"no Silverbox record at {path}; give the folder that holds silverbox/SNLS80mV.csv "
                              "(--data-dir or CHARCURVES_DATA_DIR), the CSV of the benchmark's SilverboxFiles.zip")
        u, y = _read_local(path)
        source = path
    else:
        got = _read_package()
        if got is None:
            raise ConfigError("no Silverbox data: give the folder that holds silverbox/SNLS80mV.csv with --data-dir "
                              "(data_dir=) or CHARCURVES_DATA_DIR, or install nonlinear-benchmarks "
                              "(pip install nonlinear-benchmarks) to fetch it")
        u, y = got
        source = "nonlinear_benchmarks.Silverbox()"
    if u.size < SILVERBOX_SPLIT["multisine"][1]:
        raise DataError(f"the Silverbox record has {u.size} samples, the official split needs "
                        f"{SILVERBOX_SPLIT['multisine'][1]}; give the full SNLS80mV record")
    parts = {name: _from_columns(u[a:b], y[a:b], f"silverbox {name}") for name, (a, b) in SILVERBOX_SPLIT.items()}
    est = parts.pop("estimation")
    return BenchmarkData(name="silverbox", estimation=est, tests=parts, init_window=SILVERBOX_INIT_WINDOW,
                         unit="mV", literature=dict(SILVERBOX_LITERATURE), source=source)
