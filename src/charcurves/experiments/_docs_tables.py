"""The headline tables of docs/benchmark.md (and, through ``_records_tables``, of the measured-records,
training-defaults and Silverbox pages), rendered from the committed results folders, and the
page's table markers filled with them (``python benchmarks/render_docs.py``), so that a rerun updates
the page and a number on it cannot be typed.

A table lives on a page between ``<!-- table:NAME -->`` and ``<!-- /table -->``; :func:`docs_tables`
computes every NAME from ``benchmarks/results/`` as the benchmark report computes its Tables 2 and 3,
Figs. 9 and 13 and Appendix F (the same fits, masks and paper values), and :func:`fill_table_markers`
writes them into the page.
"""

from __future__ import annotations

import json
import math
import os
import re
from collections.abc import Mapping

from . import _paper_values as paper
from ._appendix_f import _a_rows, protocol_frames
from ._differentiator_tables import differentiator_tables
from ._records_tables import _table, records_tables
from ._selection_tables import selection_tables
from ._zoo_coverage_tables import zoo_coverage_tables
from ._report_inputs import committed_csv, read_results_csv
from ._tables import BIAS_LIMITED, a_fit_table, performance_table, tsep_failure_snr

__all__ = ["docs_tables", "fill_table_markers"]

_MARKER = re.compile(r"(<!-- table:([a-z0-9-]+) -->\n)(.*?)(<!-- /table -->)", re.S)


def _g(x: float | None) -> str:
    """Three significant digits, trailing zeros kept (0.0510, 0.190, 17.0); "–" without a value."""
    if x is None or not math.isfinite(float(x)):
        return "–"
    return f"{float(x):#.3g}".rstrip(".")


def _pair(a: tuple | None) -> str:
    return "–" if a is None else f"{_g(a[0])} / {_g(a[1])}"


def _bias(b: tuple) -> str:
    return f"({b[0]:.3f}, {_g(b[1])})"


def study_table(df, system: str, lyapunov_time: float | None = None) -> str:
    """One system's headline table of a main sweep (noise on the forcing): per method the slope-1 A of
    the mean ensemble (Duffing: the root-mean-square ensemble beside it), the paper's Table 2 / 3, the
    ratio paper / ours (above 1: ours more accurate), stick-slip's A of RMSE[x] beside Table 3's,
    performance % against Parametric beside Figs. 9 / 13, the mean seconds per job and, given the
    Lyapunov time, the highest SNR whose mean t_sep is below it beside the paper's (Fig. 8)."""
    df = df[(df["system"] == system) & (df["preset"] == "default")]
    fits = a_fit_table(df, "mean")
    rms = a_fit_table(df, "rms")
    perf = performance_table(fits)
    seconds = df[df["status"] == "ok"].groupby("method")["seconds"].mean()
    stick = system == "stick-slip"
    header = ["method", "A f1 / f2, mean"] + ([] if stick else ["(rms)"]) + ["paper", "paper / ours"]
    header += (["A x ours / paper (paper / ours)"] if stick else []) + ["performance (paper)"]
    tsep = tsep_failure_snr(df, lyapunov_time) if lyapunov_time else None
    header += (["⟨t_sep⟩ < T_L at SNR ≲ (paper)"] if tsep else []) + ["s / job"]
    rows = []
    for (_, preset, method), f in fits.items():
        table: Mapping[str, tuple] = paper.TABLE3_STICK_SLIP_A if stick else paper.TABLE2_DUFFING_A
        ref = table.get(method)
        if stick and method in BIAS_LIMITED:  # the paper fits these with sqrt(b² + (A η)²): Table 3
            label, ours = f"{method}, bias fit (b, A)", f"{_bias(f['bias']['f1'])} / {_bias(f['bias']['f2'])}"
            pb = paper.TABLE3_BIAS.get(method)
            theirs = "–" if ref is None or pb is None else f"{_bias((pb[0], ref[0]))} / {_bias((pb[1], ref[1]))}"
            ratio = "–" if ref is None else f"A: {_g(ref[0] / f['bias']['f1'][1])} / {_g(ref[1] / f['bias']['f2'][1])}"
        else:
            label, ours, theirs = method, _pair((f["A"]["f1"], f["A"]["f2"])), _pair(ref[:2] if ref else None)
            ratio = "–" if ref is None else _pair((ref[0] / f["A"]["f1"], ref[1] / f["A"]["f2"]))
        row = [label, ours]
        if not stick:
            r = rms[(system, preset, method)]["A"]
            row.append(f"({_pair((r['f1'], r['f2']))})")
        row += [theirs, ratio]
        if stick:
            ax, px = f["A"]["x"], ref[2] if ref and len(ref) > 2 else None
            row.append(f"{_g(ax)} / {_g(px)}" + (f" ({_g(px / ax)})" if px and math.isfinite(ax) and ax > 0 else ""))
        pp = paper.PERFORMANCE_PERCENT.get(system, {}).get(method)
        p = perf[(system, preset, method)]
        row.append(f"{p:.1f} %" + ("" if pp is None or method == "parametric" else f" ({pp:.1f} %)"))
        if tsep:
            ours_snr, theirs_snr = tsep.get((system, preset, method), math.nan), paper.TSEP_FAILURE_SNR.get(method)
            row.append(("–" if math.isnan(ours_snr) else "none" if math.isinf(ours_snr) else f"{ours_snr:g} dB")
                       + ("" if theirs_snr is None else f" ({theirs_snr:g} dB)"))
        row.append(f"{seconds.get(method, float('nan')):.2f}")
        rows.append(row)
    return _table(header, rows)


def paper_preset_table(paper_df, full_df) -> str:
    """The `paper` preset's run (``paper-cpu/``) against Table 2 and against the default preset on the
    same records of the full study (the same dataset seeds), and over the full study's whole grid."""
    key = ["method", "snr_db", "realization"]
    default = full_df[(full_df["system"] == "duffing") & (full_df["preset"] == "default")]
    same = default.set_index(key).reindex(paper_df.set_index(key).index).dropna(subset=["rmse_f1"]).reset_index()
    fits = {name: {m: v["A"] for (_, _, m), v in a_fit_table(frame, "mean").items()}
            for name, frame in (("paper", paper_df), ("same", same), ("full", default))}
    rows = []
    for method, a in fits["paper"].items():
        t2, s, full = paper.TABLE2_DUFFING_A[method], fits["same"][method], fits["full"][method]
        rows.append([method, f"{a['f1']:.4f} / {a['f2']:.4f}",
                     f"{100 * (a['f1'] / t2[0] - 1):+.0f} % / {100 * (a['f2'] / t2[1] - 1):+.0f} %",
                     f"{s['f1']:.4f} / {s['f2']:.4f}", f"{full['f1']:.4f} / {full['f2']:.4f}",
                     f"{a['f1'] / s['f1']:#.2g} / {a['f2'] / s['f2']:#.2g}"])
    n = len(same) // max(1, len(fits["paper"]))
    return _table(["method", "A f1 / f2, `paper` preset", "vs Table 2", f"default, same {n} records",
                   "full study's default (61 × 10)", "paper preset / default"], rows)


def appendix_f_table(frames: dict) -> str:
    """Appendix F (noise on x): per system and method the slope-1 A of f1 and f2 with the paper's
    protocol and with the default, and their ratio (above 1: the default more accurate), as the report."""
    rows = [["Duffing" if s == "duffing" else s, m, _g(ap1), _g(ad1), _g(r1), _g(ap2), _g(ad2), _g(r2)]
            for s, m, _, ap1, ad1, r1, _, ap2, ad2, r2 in _a_rows(frames)]
    return _table(["system", "method", "A f1, paper protocol", "A f1, default", "ratio",
                   "A f2, paper protocol", "A f2, default", "ratio"], rows)


def _lyapunov_time(root: str, folder: str) -> float | None:
    """T_L of the Duffing of a results folder, from its ``extras.json`` (None without one)."""
    path = os.path.join(root, folder, "extras.json")
    if not os.path.isfile(path):
        return None
    with open(path, encoding="utf-8") as fh:
        entry = json.load(fh).get("lyapunov") or {}
    value = (entry.get("value") or {}).get("T_L")
    return float(value) if value else None


def docs_tables(results_root: str | os.PathLike) -> dict[str, str]:
    """``{marker name: markdown table}`` for every table whose committed results are in ``results_root``
    (``benchmarks/results``): ``full-duffing``, ``full-stick-slip``, ``scripts-duffing``,
    ``scripts-stick-slip`` (the main sweeps' A, performance and cost), ``paper-cpu`` (the `paper`
    preset against the default) and ``appendix-f`` (noise on x, both protocols); and those of the measured-records,
    training-defaults and Silverbox pages from ``state_noise.json`` and ``long_records.json``
    (``state-noise-duffing``, ``state-noise-stick-slip``, ``state-noise-families``, ``state-noise-cost``,
    ``long-records``, ``silverbox-cost``) and those of the differentiators page from ``differentiators.json``
    (``differentiators-seconds``, ``-acceleration``, ``-velocity``, ``-fits``, ``-references``), and those of
    the selection and several-records pages from ``parity/zoo.json`` and ``records/duffing.json``
    (``parity-zoo``, ``records-joint``, ``records-outside``).

    Examples
    --------
    >>> import tempfile
    >>> from charcurves.experiments import docs_tables
    >>> docs_tables(tempfile.mkdtemp())  # a folder without committed runs has no table
    {}
    """
    root = os.fspath(results_root)
    frames = {}
    for folder in ("full", "scripts-duffing", "scripts-stick-slip", "paper-cpu"):
        path = committed_csv(os.path.join(root, folder), "results.csv")
        if path is not None:
            frames[folder] = read_results_csv(path)
    out = {}
    if "full" in frames:
        out["full-duffing"] = study_table(frames["full"], "duffing", _lyapunov_time(root, "full"))
        out["full-stick-slip"] = study_table(frames["full"], "stick-slip")
    for system in ("duffing", "stick-slip"):
        if f"scripts-{system}" in frames:
            out[f"scripts-{system}"] = study_table(frames[f"scripts-{system}"], system,
                                                   _lyapunov_time(root, f"scripts-{system}"))
    if "paper-cpu" in frames and "full" in frames:
        out["paper-cpu"] = paper_preset_table(frames["paper-cpu"], frames["full"])
    appendix = os.path.join(root, "appendix-f")
    if os.path.isdir(appendix):
        protocols = protocol_frames(appendix)
        if protocols:
            out["appendix-f"] = appendix_f_table(protocols)
    out.update(records_tables(root))
    out.update(differentiator_tables(root))
    out.update(zoo_coverage_tables(root))
    out.update(selection_tables(root))
    return out


def fill_table_markers(text: str, tables: Mapping[str, str]) -> str:
    """``text`` with the block between each ``<!-- table:NAME -->`` line and the next ``<!-- /table -->``
    replaced by ``tables[NAME]``. A marker without a table is a ValueError naming it.

    Examples
    --------
    >>> from charcurves.experiments import fill_table_markers
    >>> page = "A\\n<!-- table:t -->\\nold\\n<!-- /table -->\\nB\\n"
    >>> print(fill_table_markers(page, {"t": "| x |\\n|---|\\n| 1 |\\n"}), end="")
    A
    <!-- table:t -->
    | x |
    |---|
    | 1 |
    <!-- /table -->
    B
    """
    def fill(m: re.Match) -> str:
        name = m.group(2)
        if name not in tables:
            raise ValueError(f"no table named {name!r} for its marker (known: {', '.join(sorted(tables)) or 'none'})")
        return m.group(1) + tables[name] + m.group(4)

    return _MARKER.sub(fill, text)
