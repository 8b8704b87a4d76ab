"""The tables of docs/differentiators.md, rendered from the committed ``benchmarks/results/differentiators.json``
(``benchmarks/bench_differentiators.py``), so that a rerun of the benchmark updates the page
(``python benchmarks/render_docs.py``) and a figure on it cannot be typed.

:func:`differentiator_tables` is merged into :func:`charcurves.experiments.docs_tables`; every statistic is the
one the benchmark prints from its ``summary`` (the mean over the noise seeds), the best entry of each row in bold.
"""

from __future__ import annotations

import json
import os

import numpy as np

from ._records_tables import _e, _table

__all__ = ["differentiator_tables"]

#: the benchmark's labels as the page's column heads
_HEADS = {"kalman-acc": "kalman (acc.)"}
_REFERENCES = {"pysindy-weak": "PySINDy weak form (the peer)", "parametric-oe": "parametric, output error (the limit)"}


def _record(tag: str) -> str:
    """``duffing 40 dB`` as the page writes it: ``Duffing 40 dB``."""
    return tag.replace("duffing", "Duffing", 1)


def _f(x: float) -> str:
    """A relative derivative error: three decimals below 10 (0.055, 1.098), three significant digits above (18.3)."""
    return f"{x:.3f}" if x < 10 else f"{x:#.3g}".rstrip(".")


def _bold(text: str, on: bool) -> str:
    return f"**{text}**" if on else text


def derivative_table(summary: dict, which: str = "a") -> str:
    """Per record and differentiator the relative RMSE of x'' (``which="a"``) or x' (``"v"``), interior 90 %
    [whole record], mean over the seeds; the best interior and the best whole-record value of a row in bold."""
    tags = list(summary["derivatives"])
    labels = list(summary["derivatives"][tags[0]])
    rows = []
    for tag in tags:
        d = summary["derivatives"][tag]
        inner = {lab: d[lab][f"{which}_interior"] for lab in labels}
        whole = {lab: d[lab][f"{which}_whole"] for lab in labels}
        best_in, best_whole = min(inner, key=inner.__getitem__), min(whole, key=whole.__getitem__)
        cells = []
        for lab in labels:
            a, b = _f(inner[lab]), _f(whole[lab])
            if lab == best_in and lab == best_whole:
                cells.append(f"**{a} [{b}]**")
            else:
                cells.append(f"{_bold(a, lab == best_in)} [{_bold(b, lab == best_whole)}]")
        rows.append([_record(tag)] + cells)
    return _table(["record"] + [_HEADS.get(lab, lab) for lab in labels], rows)


def seconds_table(data: dict) -> str:
    """Per differentiator the seconds per record (1000 samples, mean over the seeds), lowest and highest over
    the records, with the run's load average (timings are the machine's at that load)."""
    derivatives = data["summary"]["derivatives"]
    labels = list(next(iter(derivatives.values())))
    rows = []
    for lab in labels:
        s = [derivatives[tag][lab]["seconds"] for tag in derivatives]
        rows.append([f"`{lab}`", f"{min(s):.2g}–{max(s):.2g}"])
    load = data.get("load_average") or {}
    start, end = load.get("start"), load.get("end")
    head = "s per record of 1000 samples (lowest–highest record)"
    text = _table(["differentiator", head], rows)
    if start and end:
        text += (f"\nMean over {data['settings']['seeds']} noise seeds; {data.get('cpu_count', '?')} cores, load "
                 f"average (1 min) {start[0]:.1f} at the start of the run and {end[0]:.1f} at its end.\n")
    return text


def _method_label(method: str, objective: str, objectives: set[str]) -> str:
    return method if len(objectives) == 1 else f"{method}, {objective}"


def fits_table(summary: dict) -> str:
    """Per record and method the worst-curve RMSE of each differentiator, mean over the seeds, the best of a
    row in bold, and a line counting the fits that failed."""
    rows, n_fits, failed = [], 0, 0
    for tag, fits in summary["fits"].items():
        cells: dict[tuple[str, str], dict[str, dict]] = {}
        for key, value in fits.items():
            method, objective, diff = (part.strip() for part in key.split("|"))
            cells.setdefault((method, objective), {})[diff] = value
            n_fits += value["n"]
            failed += value["failed"]
        objectives = {objective for _, objective in cells}
        diffs = list(next(iter(cells.values())))
        for i, (method, objective) in enumerate(sorted(cells)):
            by_diff = cells[(method, objective)]
            best = min(diffs, key=lambda d: by_diff[d]["worst_mean"] if np.isfinite(by_diff[d]["worst_mean"]) else np.inf)
            rows.append([_record(tag) if i == 0 else "", _method_label(method, objective, objectives)]
                        + [_bold(_e(by_diff[d]["worst_mean"]), d == best) for d in diffs])
    first = next(iter(summary["fits"].values()))
    diffs = list(dict.fromkeys(key.split("|")[2].strip() for key in first))
    text = _table(["record", "method"] + [_HEADS.get(d, d) for d in diffs], rows)
    text += "\n" + ("No fit failed" if failed == 0 else f"{failed} fits failed") + f" (of {n_fits}).\n"
    return text


def references_table(summary: dict) -> str:
    """Per record the worst-curve RMSE of the peer and of the limit (mean over the seeds) and their seconds
    per fit."""
    rows = []
    for tag, refs in summary["references"].items():
        rows.append([_record(tag)] + [_e(refs[name]["worst_mean"]) for name in _REFERENCES]
                    + [f"{refs[name]['seconds_mean']:.1f}" for name in _REFERENCES])
    return _table(["record", *_REFERENCES.values(), "peer s / fit", "limit s / fit"], rows)


def differentiator_tables(results_root: str | os.PathLike) -> dict[str, str]:
    """``{marker name: markdown table}`` of docs/differentiators.md from ``differentiators.json`` in
    ``results_root``: ``differentiators-seconds``, ``differentiators-acceleration``,
    ``differentiators-velocity``, ``differentiators-fits`` and ``differentiators-references`` (none without
    the file).

    Examples
    --------
    >>> import tempfile
    >>> from charcurves.experiments._differentiator_tables import differentiator_tables
    >>> differentiator_tables(tempfile.mkdtemp())
    {}
    """
    path = os.path.join(os.fspath(results_root), "differentiators.json")
    if not os.path.isfile(path):
        return {}
    with open(path, encoding="utf-8") as fh:
        data = json.load(fh)
    summary = data["summary"]
    out = {}
    if summary.get("derivatives"):
        out["differentiators-seconds"] = seconds_table(data)
        out["differentiators-acceleration"] = derivative_table(summary, "a")
        out["differentiators-velocity"] = derivative_table(summary, "v")
    if any(summary.get("fits", {}).values()):
        out["differentiators-fits"] = fits_table(summary)
    if summary.get("references"):
        out["differentiators-references"] = references_table(summary)
    return out
