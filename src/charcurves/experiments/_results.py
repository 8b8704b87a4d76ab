"""The benchmark's results as data: the columns of ``results.csv``, the frame of a results store,
reading and writing the CSV files (plain or gzipped) that the report is rebuilt from.

Below the modules that run the study (``_benchmark``, ``_appendix_f``, ``_side_studies``) and
those that write its report (``_report_inputs``, ``_report_sections``), which all read these.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

from .._errors import ConfigError
from ..io import atomic_write_bytes
from ._tables import _eta

__all__ = ["RESULT_COLUMNS", "BENCHMARK_TAG", "MIW_METHODS", "METHOD_GROUPS", "empty_results_frame", "results_frame",
           "read_results_csv", "committed_csv"]

#: Columns of results.csv, in order (one row per (system, method, snr_db, realization[, preset]) job).
RESULT_COLUMNS = ("system", "method", "snr_db", "realization", "rmse_f1", "rmse_f2", "status", "preset",
                  "variant", "noise_on", "eta", "rmse_x", "t_sep", "n_cases", "n_failed_cases", "n_censored",
                  "seconds", "fit_seconds", "gain", "loss", "error", "mixed_terms")
BENCHMARK_TAG = "benchmark"
MIW_METHODS = ("nn-cc", "nn-cc+sym", "nn-cc+sym+post-sr")
#: The order of the paper's figures: increasing prior knowledge within each family.
METHOD_GROUPS = {
    "NN-CC variants": ("nn-cc", "nn-cc+post-sr", "nn-cc+sym", "nn-cc+sym+post-sr"),
    "sparse regression / polynomial": ("sindy", "sindy-cc", "poly-cc", "sindy-cc+sym", "sindy-cc+sym+post-sr"),
    "symbolic regression": ("sr", "sr-cc", "sr-cc+refit", "parametric"),
}

#: Columns every release's results CSV has (the newer ones are filled in when missing).
_REQUIRED = ("system", "method", "snr_db", "realization", "rmse_f1", "rmse_f2", "status")


def empty_results_frame():
    """A results frame without rows (a `--noise-on state` run has no main sweep)."""
    import pandas as pd

    return pd.DataFrame(columns=list(RESULT_COLUMNS))


def results_frame(store_path: str | os.PathLike, *, noise_on: str = "force", tag: str = BENCHMARK_TAG):
    """The rows of a benchmark store as a DataFrame with :data:`RESULT_COLUMNS`.

    Only rows with the benchmark's tag and the given noise target are kept; should a store hold
    several configurations of one (system, method, SNR, realisation, preset) job (e.g. runs with
    different numbers of validation cases), the most recently finished row wins, so the frame
    has one row per job.
    """
    import pandas as pd

    from ._store import ResultsStore

    with ResultsStore(store_path) as store:
        rows = store.rows()
    recs = []
    for r in rows:
        if r.get("tag") != tag or r.get("noise_on") != noise_on:
            continue
        ex = r.get("extra") or {}
        recs.append({
            "system": r["system"], "method": r["method"], "snr_db": float(r["snr_db"]),
            "realization": int(r["realization"]), "rmse_f1": r.get("rmse_f1"), "rmse_f2": r.get("rmse_f2"),
            "status": r["status"], "preset": r["preset"], "variant": r["variant"], "noise_on": r["noise_on"],
            "eta": r.get("eta") if r.get("eta") is not None else _eta(float(r["snr_db"])),
            "rmse_x": r.get("rmse_x_mean"), "t_sep": r.get("t_sep_mean"), "n_cases": r.get("n_cases"),
            "n_failed_cases": r.get("n_failed_cases"), "n_censored": r.get("n_censored"),
            "seconds": r.get("seconds"), "fit_seconds": ex.get("fit_seconds"), "gain": r.get("gain"),
            "loss": r.get("loss"), "error": r.get("error"), "mixed_terms": _mixed_terms(ex),
            "_finished": r.get("finished_at") or "",
            "_model_path": _model_path(ex.get("model_path"), store_path),
        })
    df = pd.DataFrame(recs, columns=list(RESULT_COLUMNS) + ["_finished", "_model_path"])
    if len(df):
        df = df.sort_values("_finished").drop_duplicates(
            ["system", "method", "snr_db", "realization", "preset"], keep="last")
        order = {m: i for i, m in enumerate(_all_methods())}
        df = df.assign(_o=df["method"].map(lambda m: order.get(m, 99))).sort_values(
            ["system", "preset", "_o", "snr_db", "realization"], ascending=[True, True, True, False, True])
        df = df.drop(columns="_o").reset_index(drop=True)
    for c in ("snr_db", "eta", "rmse_f1", "rmse_f2", "rmse_x", "t_sep", "seconds", "fit_seconds", "gain", "loss",
              "mixed_terms"):
        df[c] = pd.to_numeric(df[c], errors="coerce").astype(float)
    return df


def _mixed_terms(extra: Mapping[str, Any]) -> float:
    """How many terms mixing the curves' arguments (x and x') the symbolic expression of a job held
    (SR: its bivariate search; they are dropped and the separable terms refitted); NaN for methods
    without such an expression and for rows of older stores."""
    terms = (extra.get("model_info") or {}).get("mixed_terms")
    return float(len(terms)) if isinstance(terms, list) else float("nan")


def _model_path(path: str | None, store_path) -> str | None:
    """A row's saved model folder: relative to the store's folder (absolute in older stores)."""
    if not path:
        return None
    return os.path.join(os.path.dirname(os.path.abspath(os.fspath(store_path))), path)


def _all_methods() -> tuple[str, ...]:
    from ..fitting import METHODS

    return tuple(METHODS)


def _write_csv(df, path: str) -> None:
    cols = [c for c in RESULT_COLUMNS if c in df.columns]
    atomic_write_bytes(path, df[cols].to_csv(index=False).encode("utf-8"))


def read_results_csv(path: str | os.PathLike):
    """``results.csv`` (or ``appendix_f.csv``, either gzipped as ``.csv.gz``) as the DataFrame the
    report's tables take.

    Examples
    --------
    >>> import pandas as pd, tempfile, os
    >>> d = tempfile.mkdtemp(); p = os.path.join(d, "results.csv")
    >>> pd.DataFrame({"system": ["duffing"], "method": ["sr"], "snr_db": [float("inf")], "realization": [0],
    ...               "rmse_f1": [1e-3], "rmse_f2": [2e-3], "status": ["ok"]}).to_csv(p, index=False)
    >>> df = read_results_csv(p)
    >>> float(df["snr_db"][0]), df["preset"][0], float(df["eta"][0])
    (inf, 'default', 0.0)

    A file that is not such a CSV (truncated, another table) is a ConfigError naming it and what is wrong.
    """
    import pandas as pd


    try:
        df = pd.read_csv(path)
    except (OSError, EOFError, ValueError, UnicodeDecodeError) as exc:  # truncated gzip, not a CSV, ...
        raise ConfigError(f"cannot rebuild the report: {os.fspath(path)} is not a readable results CSV "
                          f"({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else 'unreadable'}); restore "
                          "the file from the run or the repository") from None
    missing = [c for c in _REQUIRED if c not in df.columns]
    if missing:
        raise ConfigError(f"cannot rebuild the report: {os.fspath(path)} lacks the column(s) {', '.join(missing)} "
                          "of a benchmark results CSV; restore the file written by `charcurves benchmark`")
    for c in RESULT_COLUMNS:
        if c not in df.columns:  # files of older releases lack the newer columns
            df[c] = {"preset": "default", "variant": "paper", "noise_on": "force"}.get(c, float("nan"))
    for c in ("snr_db", "eta", "rmse_f1", "rmse_f2", "rmse_x", "t_sep", "seconds", "fit_seconds", "gain", "loss",
              "n_cases", "n_failed_cases", "n_censored", "mixed_terms"):
        df[c] = pd.to_numeric(df[c], errors="coerce").astype(float)
    if df["eta"].isna().any():
        df["eta"] = [_eta(s) for s in df["snr_db"]]
    df["realization"] = df["realization"].astype(int)
    for c in ("system", "method", "status", "preset", "variant", "noise_on"):
        df[c] = df[c].astype(str)
    df["error"] = df["error"].where(df["error"].notna(), None)
    return df[list(RESULT_COLUMNS)]


def committed_csv(out_dir: str, name: str) -> str | None:
    """The path of ``name`` (a ``.csv``) in ``out_dir``, or of its gzipped copy ``name + ".gz"`` when
    only that is there (a large committed file); None when neither is. The plain file wins: a run
    into the folder rewrites it from the store.

    >>> import tempfile, gzip, os
    >>> d = tempfile.mkdtemp(); committed_csv(d, "results.csv") is None
    True
    >>> with gzip.open(os.path.join(d, "results.csv.gz"), "wb") as fh: _ = fh.write(b"a\n1\n")
    >>> os.path.basename(committed_csv(d, "results.csv"))
    'results.csv.gz'
    """
    for path in (os.path.join(out_dir, name), os.path.join(out_dir, name + ".gz")):
        if os.path.isfile(path):
            return path
    return None
