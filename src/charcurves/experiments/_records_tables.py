"""The tables of docs/measured-records.md, docs/training-defaults.md and docs/silverbox.md, rendered from the
committed ``benchmarks/results/state_noise.json`` (``benchmarks/bench_state_noise.py``: noise on x only) and
``benchmarks/results/long_records.json`` (``benchmarks/bench_long_records.py``), so that a rerun of either
benchmark updates the pages (``python benchmarks/render_docs.py``) and a figure on them cannot be typed.

:func:`records_tables` is merged into :func:`charcurves.experiments.docs_tables`; every statistic is the one
the benchmark prints in its ``summary`` (the mean over the noise seeds of each record's worst curve).
"""

from __future__ import annotations

import json
import os
from collections import OrderedDict

import numpy as np

from ..systems import get_system
from ._records_prose import records_prose

__all__ = ["records_tables"]

_LIMIT = "parametric (true basis) + output error: the limit"
_PEER = "PySINDy weak form (the peer)"
_LABELS = {_LIMIT: "limit: parametric, true basis, output error", _PEER: "peer: PySINDy weak form"}
_DIFFERENTIATORS = {"savgol": "savgol 31/3", "savgol (velocity state)": "savgol velocity"}


def _e(x: float | None) -> str:
    """Three significant digits in the pages' exponent form (7.81e-4, 1.16e-2); "–" without a value."""
    if x is None or not np.isfinite(x):
        return "–"
    mantissa, exponent = f"{x:.2e}".split("e")
    return f"{mantissa}e{int(exponent)}"


def _pct(x: float) -> str:
    """A normalised RMSE as a percentage, three significant digits (0.636 %, 7.26 %, 11.3 %)."""
    return f"{100 * x:#.3g}".rstrip(".") + " %"


def _table(header: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return "\n".join(lines + ["| " + " | ".join(r) + " |" for r in rows]) + "\n"


def _groups(rows: list[dict], system: str) -> OrderedDict:
    """``{(label, differentiator): {(snr, objective class): [rows]}}`` of one system, in the run's order; the
    limit's output error and the peer's weak form count as the default column."""
    out: OrderedDict = OrderedDict()
    for r in rows:
        if r["system"] != system or "error" in r:
            continue
        column = "equation-error" if r["objective"] == "equation-error" else "auto"
        out.setdefault((r["label"], r["differentiator"]), {}).setdefault((r["snr"], column), []).append(r)
    return out


def _label(label: str, differentiator: str) -> list[str]:
    return [_LABELS.get(label, label), _DIFFERENTIATORS.get(differentiator, differentiator)]


def state_noise_table(data: dict, system: str = "duffing") -> str:
    """Per method and differentiator the mean over the seeds of the worst-curve RMSE, with equation error alone
    and with the default objective (equation error, then output error), at each SNR of the run."""
    groups = _groups(data["rows"], system)
    snrs = sorted({snr for cells in groups.values() for snr, _ in cells}, reverse=True)
    header = ["method", "derivatives"]
    for snr in snrs:
        header += [f"{snr:g} dB, equation error", f"{snr:g} dB, default (`auto`)"]
    rows = []
    for (label, diff), cells in groups.items():
        row = _label(label, diff)
        for snr in snrs:
            for column in ("equation-error", "auto"):
                rs = cells.get((snr, column))
                row.append(_e(float(np.mean([r["worst"] for r in rs]))) if rs else "")
        rows.append(row)
    return _table(header, rows)


def state_noise_curves_table(data: dict, system: str = "stick-slip") -> str:
    """Per method and differentiator the mean RMSE of each curve, equation error alone and the default."""
    groups = _groups(data["rows"], system)
    rows = []
    for (label, diff), cells in groups.items():
        row = _label(label, diff)
        for column in ("equation-error", "auto"):
            rs = [r for (_, c), v in cells.items() if c == column for r in v]
            row.append(f"{_e(float(np.mean([r['f1'] for r in rs])))} / {_e(float(np.mean([r['f2'] for r in rs])))}"
                       if rs else "")
        rows.append(row)
    return _table(["method", "derivatives", "RMSE f1 / f2, equation error", "RMSE f1 / f2, default (`auto`)"], rows)


def _family_groups(data: dict) -> OrderedDict:
    out: OrderedDict = OrderedDict()
    for r in data.get("family_rows") or []:
        key = (r["system"], r["family"], r["method"], json.dumps(r["options"], sort_keys=True))
        out.setdefault(key, {}).setdefault(r["objective"], []).append(r)
    return out


def families_table(data: dict) -> str:
    """The other families (normalised RMSE, the worst curve per seed): equation error's mean, the default's
    per seed and mean, and the default's mean per curve."""
    rows = []
    for (system, family, method, options), by in _family_groups(data).items():
        opts = json.loads(options)
        name = method + (f", `{opts['symmetry']}`" if opts.get("symmetry") else "")
        ee, auto = by.get("equation-error", []), sorted(by.get("auto", []), key=lambda r: r["seed"])
        per = {k: float(np.mean([r["nrmse"][k] for r in auto])) for k in auto[0]["nrmse"]} if auto else {}
        rows.append([system if family == system else f"{system} ({family})", name, _pct(float(np.mean([r["worst"] for r in ee]))) if ee else "–",
                     ", ".join(_pct(r["worst"]) for r in auto),
                     f"**{_pct(float(np.mean([r['worst'] for r in auto])))}**" if auto else "–",
                     ", ".join(f"{k} {_pct(v)}" for k, v in per.items())])
    seeds = sorted({r["seed"] for r in data.get("family_rows") or [] if r["objective"] == "auto"})
    return _table(["system (family)", "method", "worst curve, equation error (mean)",
                   "worst curve, default: seeds " + ", ".join(map(str, seeds)), "mean", "per curve, default (mean)"],
                  rows)


def _ratio_cell(ratios: list[float]) -> str:
    if not ratios:
        return "–"
    cell = f"{np.mean(ratios):.1f}×"
    return cell + (f" ({min(ratios):.1f}–{max(ratios):.1f}×)" if len(ratios) > 1 else "")


def cost_table(data: dict) -> str:
    """The output-error stage's seconds against the equation-error fit of the same record and method (the mean
    of the per-record ratios and their range), and both in seconds (means), per system, method and SNR."""
    rows = []
    cells: OrderedDict = OrderedDict()
    for r in data["rows"]:
        if r["objective"] == "auto" and r["differentiator"] == "spectral" and r.get("oe_seconds") and r.get("ee_seconds"):
            cells.setdefault((r["system"], r["label"], f"{r['snr']:g} dB"), []).append(
                (r["oe_seconds"], r["ee_seconds"]))
    for (system, family, method, options), by in _family_groups(data).items():
        ee = {r["seed"]: r["seconds"] for r in by.get("equation-error", [])}
        opts = json.loads(options)
        name = method + (f", `{opts['symmetry']}`" if opts.get("symmetry") else "")
        for r in by.get("auto", []):
            if r.get("oe_seconds") and r["seed"] in ee:
                cells.setdefault((system, name, "40 dB"), []).append((r["oe_seconds"], ee[r["seed"]]))
    for (system, method, level), pairs in cells.items():
        oe, ee = np.array(pairs).T
        rows.append([system, method, level, str(len(pairs)), _ratio_cell(list(oe / ee)),
                     f"{oe.mean():.3g}", f"{ee.mean():.3g}"])
    return _table(["system", "method", "noise on x", "records", "OE stage / EE fit, mean (range)",
                   "OE stage, s", "EE fit, s"], rows)


def long_records_table(data: dict) -> str:
    """Whole ``charcurves fit --method nn-cc+sym`` processes per record length: wall time (the short record's
    median of its runs), against the short record, peak memory, curve RMSE and the training stages; the paper's
    protocol timed in the same run as the last row."""
    records = sorted(data["records"], key=lambda r: r["samples"])
    base = records[0]["wall_s"]
    rows = []
    for r in records:
        wall = f"{r['wall_s']:.1f} s"
        if len(r.get("wall_s_runs") or []) > 1:
            wall += " (runs " + ", ".join(f"{w:.1f}" for w in r["wall_s_runs"]) + " s)"
        lr = r.get("long_record")
        stages = "one" if not lr else (f"{lr['subset_samples']}-sample subset, then {lr['refine_iterations']} LM "
                                       "iterations on all samples")
        rows.append([f"{r['samples']:,}".replace(",", " "), wall, f"{r['wall_s'] / base:.1f}×",
                     f"{r['peak_mib']:.0f} MiB", _e(r["rmse_f1"]), _e(r["rmse_f2"]), stages])
    paper = data.get("paper_protocol_seconds")
    if paper:
        rows.append([f"{records[0]['samples']:,}".replace(",", " ") + ", the paper's protocol", f"{paper:.0f} s",
                     f"{paper / base:.0f}×", "", "", "",
                     f"20 000 Adam epochs, timed on {data.get('paper_epochs_timed')} and scaled"])
    return _table(["samples", "wall time", "vs the shortest", "peak memory", "RMSE f1", "RMSE f2", "stages"], rows)


def silverbox_cost_table(data: dict) -> str:
    """The Silverbox command (NN-CC+sym + post-SR, output error) of the long-record run: wall, memory, stages."""
    s = data["silverbox"]
    t = s["timing"]
    return _table(["whole process", "peak memory", "training", "output error of the networks", "post-SR",
                   "output error of the closed forms"],
                  [[f"{s['wall_s']:.1f} s", f"{s['peak_mib']:.0f} MiB", f"{t['train_seconds']:.1f} s",
                    f"{t['output_error_before_post_sr.seconds']:.1f} s", f"{t['post_sr_seconds']:.1f} s",
                    f"{t['output_error.seconds']:.1f} s"]])


def records_tables(results_root: str | os.PathLike) -> dict[str, str]:
    """``{marker name: markdown table}`` from ``state_noise.json`` (``state-noise-duffing``,
    ``state-noise-stick-slip``, ``state-noise-families``, ``state-noise-cost``) and ``long_records.json``
    (``long-records``, ``silverbox-cost``) in ``results_root``; a missing file gives no table."""
    root = os.fspath(results_root)
    out = {}
    path = os.path.join(root, "state_noise.json")
    if os.path.isfile(path):
        with open(path, encoding="utf-8") as fh:
            data = json.load(fh)
        out["state-noise-duffing"] = state_noise_table(data, "duffing")
        out["state-noise-stick-slip"] = state_noise_curves_table(data, "stick-slip")
        out["state-noise-families"] = families_table(data)
        out["state-noise-cost"] = cost_table(data)
        out.update(records_prose(data, true_jump=getattr(get_system("stick-slip"), "mu_N", None)))
    path = os.path.join(root, "long_records.json")
    if os.path.isfile(path):
        with open(path, encoding="utf-8") as fh:
            data = json.load(fh)
        out["long-records"] = long_records_table(data)
        if data.get("silverbox"):
            out["silverbox-cost"] = silverbox_cost_table(data)
    return out
