"""The tables of docs/selection.md (the default parity test on the curve zoo) and docs/several-records.md
(Duffing from three records), rendered from the committed ``benchmarks/results/parity/zoo.json``
(``benchmarks/bench_parity.py``) and ``benchmarks/results/records/duffing.json``
(``benchmarks/bench_records.py --duffing``), and the units table of docs/zoo.md from
``benchmarks/results/units/linear.jsonl`` beside ``linear-before.jsonl`` (``benchmarks/bench_units.py``),
so that a rerun updates the pages (``python benchmarks/render_docs.py``). :func:`selection_tables` is merged into
:func:`charcurves.experiments.docs_tables`.
"""

from __future__ import annotations

import json
import os

from ._records_tables import _table

__all__ = ["selection_tables", "parity_table", "records_joint_table", "records_outside_table", "units_table"]

_RULES = {"1": "one sign per sample", "auto": "one sign per block (default)"}
_SETTINGS = {"F25": "25 dB on F, derivatives given", "x30": "30 dB on x only"}


def _g(x: float | None) -> str:
    return "-" if x is None else f"{x:.3g}"


def parity_table(doc: dict) -> str:
    """One row per (zoo half, noise setting, bootstrap block rule) of ``bench_parity.py``'s summary:
    the decisions and how many imposed a wrong prior, missed a true one, or were right.

    Examples
    --------
    >>> from charcurves.experiments import parity_table
    >>> doc = {"seeds": [0, 1], "summary": [{"half": "report", "setting": "x30", "rule": "1", "tested": 8,
    ...        "right": 5, "wrong_prior": 0, "missed": 3, "untestable": 0, "median_odd_stat_of_odd_curves": 2.3}]}
    >>> print(parity_table(doc).splitlines()[2])
    | report | 30 dB on x only | one sign per sample | 8 | 5 | 0 | 3 | 2.3 |
    """
    rows = []
    order = {"tuning": 0, "report": 1, "-": 2}
    for s in sorted(doc["summary"], key=lambda s: (order.get(s["half"], 3), s["setting"], s["rule"] != "1")):
        half = "Duffing, 3 records together" if s["half"] == "-" else s["half"]
        rows.append([half, _SETTINGS.get(s["setting"], s["setting"]), _RULES.get(s["rule"], s["rule"]),
                     str(s["tested"]), str(s["right"]), str(s["wrong_prior"]), str(s["missed"]),
                     _g(s["median_odd_stat_of_odd_curves"])])
    return _table(["zoo half", "noise", "bootstrap", "decisions", "right", "wrong prior", "missed",
                   "median odd statistic of odd curves"], rows)


def _runs(root: str) -> list[dict]:
    path = os.path.join(root, "records", "duffing.json")
    if not os.path.isfile(path):
        return []
    with open(path, encoding="utf-8") as fh:
        return sorted(json.load(fh)["duffing"]["runs"], key=lambda run: int(run["seed"]))


def records_joint_table(runs: list[dict]) -> str:
    """Per seed: each curve's RMSE of the joint fit, of the parametric fit on the same records, the ratio."""
    rows = []
    for run in runs:
        row = [str(run["seed"])]
        for name in ("f1", "f2"):
            c = run["curves"][name]
            row += [_g(c["joint_rmse"]), _g(c["parametric_pooled_rmse"]), f"{c['ratio_to_parametric']:.3g}"]
        rows.append(row)
    return _table(["seed", "f1 joint", "f1 parametric", "ratio", "f2 joint", "f2 parametric", "ratio"], rows)


def records_outside_table(runs: list[dict]) -> str:
    """Per seed: outside each of the two smaller records' range, that record's own fit / the joint fit."""
    rows = []
    for run in runs:
        row = [str(run["seed"])]
        for name in ("f1", "f2"):
            for out in run["curves"][name]["outside"][:2]:
                row.append(f"{_g(out['alone_rmse'])} / {_g(out['joint_rmse'])}")
        rows.append(row)
    return _table(["seed", "f1, A = 0.25", "f1, A = 0.5", "f2, A = 0.25", "f2, A = 0.5"], rows)


_CASES = ("x", "x+10", "1e-3x", "1e3x", "1e3(x+10)")


def _jsonl(path: str) -> list[dict]:
    with open(path, encoding="utf-8") as fh:
        return [json.loads(line) for line in fh if line.strip()]


def units_table(now: list[dict], before: list[dict]) -> str:
    """Per method and setting of ``bench_units.py``: f1 / f2 normalised RMSE (%) in each unit case, now and,
    where it differs by more than 1 %, the earlier run's figure after an arrow; "refused" for a fit the
    library refuses (a parity prior on a range without 0).

    Examples
    --------
    >>> from charcurves.experiments import units_table
    >>> row = {"setting": "X40", "method": "poly-cc", "case": "x", "nrmse": {"f1": 0.0003, "f2": 0.002}}
    >>> old = dict(row, nrmse={"f1": 0.0003, "f2": 0.03})
    >>> print(units_table([row], [old]).splitlines()[2])
    | poly-cc | 40 dB on x only | 0.03 / 3 → 0.2 | - | - | - | - |
    """
    def key(r):
        return r["setting"], r["method"], r["case"]

    old = {key(r): r for r in before}
    cells: dict = {}
    for r in now:
        if "nrmse" not in r:
            cells[key(r)] = "refused"
            continue
        parts = []
        for name in ("f1", "f2"):
            v = 100 * r["nrmse"][name]
            b = old.get(key(r), {}).get("nrmse", {}).get(name)
            parts.append(f"{v:.3g}" if b is None or abs(100 * b - v) <= 0.01 * v else f"{100 * b:.3g} → {v:.3g}")
        cells[key(r)] = " / ".join(parts)
    settings = {"F20": "20 dB on F, derivatives given", "X40": "40 dB on x only"}
    rows = []
    for setting in sorted({r["setting"] for r in now}):
        for method in dict.fromkeys(r["method"] for r in now if r["setting"] == setting):
            rows.append([method, settings.get(setting, setting)]
                        + [cells.get((setting, method, c), "-") for c in _CASES])
    return _table(["method", "noise", "x", "x + 10", "1e-3 x", "1e3 x", "1e3 (x + 10)"], rows)


def selection_tables(results_root: str | os.PathLike) -> dict[str, str]:
    """``{"parity-zoo", "records-joint", "records-outside", "units-linear"}`` where their committed results exist.

    Examples
    --------
    >>> import tempfile
    >>> from charcurves.experiments import selection_tables
    >>> selection_tables(tempfile.mkdtemp())  # a folder without committed runs has no table
    {}
    """
    root = os.fspath(results_root)
    out = {}
    path = os.path.join(root, "parity", "zoo.json")
    if os.path.isfile(path):
        with open(path, encoding="utf-8") as fh:
            out["parity-zoo"] = parity_table(json.load(fh))
    runs = _runs(root)
    if runs:
        out["records-joint"] = records_joint_table(runs)
        out["records-outside"] = records_outside_table(runs)
    now, before = (os.path.join(root, "units", f) for f in ("linear.jsonl", "linear-before.jsonl"))
    if os.path.isfile(now):
        out["units-linear"] = units_table(_jsonl(now), _jsonl(before) if os.path.isfile(before) else [])
    return out
