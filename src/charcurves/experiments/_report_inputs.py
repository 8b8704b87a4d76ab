"""What the benchmark report is built from: small files in the output folder, nothing else.

A benchmark run writes, besides its resumable stores (``results.sqlite``, ``appendix_f.sqlite``,
``models/``, large and not meant to be committed):

* ``results.csv``: one row per job of the main sweep (every table and figure of the noise sweep);
  a large one may be committed gzipped as ``results.csv.gz`` (``gzip -n``), read the same way;
* ``appendix_f.csv`` and ``appendix_f_default.csv``: the same for Appendix F (noise on x; the paper's
  protocol and charcurves' default), when that section ran;
* ``extras.json``: the side studies (Lyapunov time, Table 1's MIW, Appendix C) and the data of the
  figures that simulate (forward panels of Fig. 6, validation trajectories of Fig. 7);
* ``run.json``: what the last invocation ran (grid sizes, systems and their variants, the sections
  run, the stage times shown in the report).

:func:`build_report` reads only these, so ``charcurves benchmark --report-only`` rebuilds
``report.md``, ``report.html`` and ``figures/`` from a committed folder without running a job;
a missing file is a :class:`ConfigError` naming it.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from typing import Any

from .._errors import ConfigError
from ._results import committed_csv as committed_csv
from ._results import read_results_csv as read_results_csv

__all__ = ["RUN_FILE", "COMMITTED_FILES", "write_run_file", "read_results_csv", "committed_csv", "load_report_inputs", "build_report",
           "write_report"]

RUN_FILE = "run.json"
#: The files a report is rebuilt from (commit these with the report; appendix_f.csv when Appendix F ran).
COMMITTED_FILES = ("results.csv", "appendix_f.csv", "appendix_f_default.csv", "extras.json", RUN_FILE)
_WHAT = {
    "results.csv": "one row per job of the main sweep",
    "appendix_f.csv": "the Appendix F jobs, which run.json says were run",
    "extras.json": "the side studies and the data of the simulated figures",
    RUN_FILE: "the grid and sections of the run",
}


def write_run_file(out_dir: str, run: Mapping[str, Any]) -> str:
    """Write ``run.json`` (atomically) and return its path.

    The folder's earlier invocations (another preset's rows, a resumed run) are kept under
    ``"previous"``, oldest first, each with what it ran and its stage times, so that the report
    can show every invocation's cost and not only the last one's.
    """
    from ..io import atomic_write_bytes
    from ._store import _jsonable

    path = os.path.join(out_dir, RUN_FILE)
    record = dict(run)
    try:
        with open(path, encoding="utf-8") as fh:
            old = json.load(fh)
    except (OSError, ValueError):
        old = None
    if isinstance(old, dict):
        earlier = list(old.pop("previous", []) or [])
        earlier.append({k: old[k] for k in ("preset", "systems", "methods", "full", "sections", "timing", "sizes")
                        if k in old})
        record["previous"] = earlier
    atomic_write_bytes(path, json.dumps(_jsonable(record), indent=1, sort_keys=True).encode("utf-8"))
    return path


def _need(out_dir: str, name: str) -> str:
    path = os.path.join(out_dir, name)
    if name.endswith(".csv"):
        path = committed_csv(out_dir, name) or path
    if not os.path.isfile(path):
        raise ConfigError(f"cannot rebuild the report: {path} is missing ({_WHAT[name]}); restore the file, or run "
                          "`charcurves benchmark` into this folder to write it")
    return path


def load_report_inputs(out_dir: str | os.PathLike) -> tuple[Any, dict, Any, Any]:
    """``(results frame, run dict, extras, {Appendix F protocol: frame})`` from ``out_dir``'s files.

    Raises
    ------
    ConfigError
        When ``out_dir`` is not a folder, or lacks ``results.csv``, ``run.json``, ``extras.json``
        or (when run.json says Appendix F ran) ``appendix_f.csv``; the message names the file.
    """

    from ._appendix_f import protocol_frames
    from ._run_files import _Extras

    out_dir = os.fspath(out_dir)
    if not os.path.isdir(out_dir):
        raise ConfigError(f"cannot rebuild the report: {out_dir!r} is not a folder; give the --out of a benchmark run")
    run_path = _need(out_dir, RUN_FILE)  # its own message when missing (a ConfigError is a ValueError too)
    try:
        with open(run_path, encoding="utf-8") as fh:
            run = json.load(fh)
    except ValueError as exc:
        raise ConfigError(f"cannot rebuild the report: {run_path} is not valid JSON ({exc}); "
                          "restore the file or rerun the benchmark") from None
    if not isinstance(run, dict):
        raise ConfigError(f"cannot rebuild the report: {run_path} holds a JSON {type(run).__name__}, not the object "
                          "a benchmark writes; restore the file or rerun the benchmark")
    if run.get("noise_on") == "state":  # Appendix F alone: no main sweep, no results.csv
        from ._results import empty_results_frame

        df = empty_results_frame()
    else:
        df = read_results_csv(_need(out_dir, "results.csv"))
    extras = _Extras(_need(out_dir, "extras.json"))
    af = protocol_frames(out_dir, required_for=run.get("preset", "default") if "appendix-f" in run.get("sections", ())
                         else None)
    return df, run, extras, af


def build_report(out_dir: str | os.PathLike, *, timing: Mapping[str, float] | None = None) -> tuple[str, str]:
    """Write ``report.md``, ``report.html`` and ``figures/`` from ``out_dir``'s files alone.

    Reads ``results.csv``, ``run.json``, ``extras.json`` and ``appendix_f.csv`` (when Appendix F
    ran); runs no job and no simulation. ``timing``: stage times to show instead of run.json's.
    Returns the two paths.

    Examples
    --------
    ``build_report("bench")`` rewrites bench/report.md and bench/report.html. A folder without the
    files is refused, naming the first one missing:

    >>> import tempfile
    >>> from charcurves.experiments import build_report
    >>> try:
    ...     build_report(tempfile.mkdtemp())
    ... except Exception as exc:
    ...     print(type(exc).__name__, str(exc).split(" is missing")[0].endswith("run.json"))
    ConfigError True
    """
    return write_report(out_dir, load_report_inputs(out_dir), timing=timing)


def write_report(out_dir: str | os.PathLike, inputs: tuple, *, timing: Mapping[str, float] | None = None
                 ) -> tuple[str, str]:
    """Write the report from ``inputs``, the tuple :func:`load_report_inputs` read from ``out_dir``."""
    from ..report import Report
    from . import _report_sections as sections

    df, run, extras, af = inputs
    rep = Report("charcurves benchmark: the paper's study")
    sections.write_all(rep, df=df, run=run, extras=extras, appendix_f=af,
                       timing=dict(timing if timing is not None else run.get("timing", {})))
    return rep.write(os.fspath(out_dir), "report")


def run_record(*, systems: Sequence[str], methods: Sequence[str], preset: str, full: bool, sizes: Mapping,
               variants: Mapping[str, str], skip: Sequence[str], sections: Sequence[str], timing: Mapping,
               t_end: float, n_points: int, base_seed: int, noise_on: str = "force") -> dict[str, Any]:
    """The content of ``run.json``."""
    return {"noise_on": noise_on, "systems": list(systems), "methods": list(methods), "preset": preset, "full": bool(full),
            "sizes": dict(sizes), "variants": dict(variants), "skip": list(skip), "sections": list(sections),
            "timing": dict(timing), "t_end": float(t_end), "n_points": int(n_points), "base_seed": int(base_seed)}
