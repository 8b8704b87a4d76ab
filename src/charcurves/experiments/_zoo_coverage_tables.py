"""The tables and figures of docs/uncertainty-zoo.md, rendered from the committed
``benchmarks/results/zoo-coverage/results-level-fix.jsonl`` (``benchmarks/bench_zoo_coverage.py``), whose
sindy-cc+sym rows ``results-sparse.jsonl`` replaces (the sparse fit's rule, issue 48), and
``duffing-level-fix.txt`` (``benchmarks/bench_lack_of_fit_duffing.py``; its sindy-cc rows replaced by those of
``duffing-sparse.txt``), so that a rerun updates the page
(``python benchmarks/render_docs.py``). :func:`zoo_coverage_tables` is merged into
:func:`charcurves.experiments.docs_tables`; the benchmark prints the same tables (``--report-only``).
"""

from __future__ import annotations

import json
import os

import numpy as np

__all__ = ["zoo_coverage_tables", "gated_rows", "coverage_table", "per_curve_table", "ZOO_SETTINGS",
           "ZOO_METHODS"]

ZOO_SETTINGS = ("F25", "x30")
ZOO_METHODS = ("poly-cc", "sindy-cc+sym", "parametric")
_ALL_METHODS = ("poly-cc", "sindy-cc+sym", "parametric", "nn-cc", "nn-cc+sym")
_RESULTS = os.path.join("zoo-coverage", "results-level-fix.jsonl")
#: rows that replace those of :data:`_RESULTS` for their methods (sindy-cc+sym under the sparse fit's rule)
_SPARSE = os.path.join("zoo-coverage", "results-sparse.jsonl")
_DUFFING = os.path.join("zoo-coverage", "duffing-level-fix.txt")
#: rows that replace those of :data:`_DUFFING` for their setting and method (sindy-cc under the sparse fit's rule)
_DUFFING_SPARSE = os.path.join("zoo-coverage", "duffing-sparse.txt")


def _jsonl(path: str) -> list[dict]:
    with open(path, encoding="utf-8") as fh:
        return [json.loads(line) for line in fh if line.strip()]


def gated_rows(rows: list[dict], level: float) -> list[dict]:
    """The rows with the lack-of-fit band ("inside") only for curves whose binned test's p-value is
    below ``level``, the plain band otherwise: exact for rows recorded at ``level`` or a laxer
    ``--lof-level``. Rows of a sparse regression's fit (``lof_every_curve``: the term on every curve,
    :data:`charcurves.fitting.SPARSE_LACK_OF_FIT`) are kept as they are.

    Examples
    --------
    >>> from charcurves.experiments import gated_rows
    >>> row = {"inside": {"f1": 0.9, "f2": 0.8}, "inside_plain": {"f1": 0.5, "f2": 0.7}, "binned_p": {"f1": 1e-6, "f2": 0.4},
    ...        "half_width": {"f1": 0.2, "f2": 0.1}, "half_width_plain": {"f1": 0.1, "f2": 0.05}}
    >>> gated_rows([row], 1e-3)[0]["inside"]  # the term on f1 only, whose test rejects
    {'f1': 0.9, 'f2': 0.7}
    """
    out = []
    for r in rows:
        if "inside_plain" not in r or "binned_p" not in r or r.get("lof_every_curve"):
            out.append(r)
            continue
        r = dict(r)
        use = {s: r["binned_p"].get(s, 1.0) < level for s in r["inside"]}
        r["inside"] = {s: r["inside"][s] if use[s] else r["inside_plain"][s] for s in r["inside"]}
        r["half_width"] = {s: r["half_width"][s] if use[s] else r["half_width_plain"][s] for s in r["half_width"]}
        out.append(r)
    return out


def coverage_table(rows: list[dict], methods=ZOO_METHODS, key: str = "inside") -> str:
    """Per setting and method: the mean share of the grid inside the 95 % band over every report-half
    curve and seed, the share of fits whose band holds at least 90 % of the grid, the median half-width.

    Examples
    --------
    >>> from charcurves.experiments import coverage_table
    >>> rows = [{"setting": "F25", "method": "poly-cc", "seed": 0, "inside": {"f1": 0.9, "f2": 0.8},
    ...          "half_width": {"f1": 0.02, "f2": 0.04}}]
    >>> print(coverage_table(rows, ["poly-cc"]).splitlines()[2])
    | F25 | poly-cc | 0.850 | 0.50 | 0.03 | 2 | 1 | 0 |
    """
    out = ["| setting | method | grid inside 95 % band (mean) | fits with >= 0.9 of the grid inside | "
           "half-width / sd(truth) (median) | curves x seeds | seeds | errors |", "|---|---|---|---|---|---|---|---|"]
    for setting in ZOO_SETTINGS:
        for method in methods:
            sel = [r for r in rows if r["setting"] == setting and r["method"] == method]
            good = [r for r in sel if key in r and "error" not in r]
            inside = [v for r in good for v in r[key].values()]
            width = [v for r in good for v in r[key.replace("inside", "half_width")].values()]
            if not sel:
                continue
            seeds = len({r["seed"] for r in sel})
            out.append(f"| {setting} | {method} | {np.mean(inside):.3f} | {np.mean(np.array(inside) >= 0.9):.2f} | "
                       f"{np.median(width):.3g} | {len(inside)} | {seeds} | {len(sel) - len(good)} |"
                       if inside else f"| {setting} | {method} | – | – | – | 0 | {seeds} | {len(sel)} |")
    return "\n".join(out)


def _per_curve(rows: list[dict]) -> dict[tuple[str, str, str, str], tuple[float, float | None, float | None, int]]:
    """``{(setting, method, system, slot): (mean inside, mean plain inside, mean plain |error| / half-width,
    seeds)}``; None where the rows lack the plain band."""
    keys = sorted({(r["setting"], r["method"], r["system"], s) for r in rows if "inside" in r for s in r["inside"]})
    out = {}
    for st, m, sy, s in keys:
        sel = [r for r in rows if (r["setting"], r["method"], r["system"]) == (st, m, sy) and "inside" in r]
        p = [r["inside_plain"][s] for r in sel if "inside_plain" in r]
        e = [r["error_over_half_width"][s] for r in sel if "error_over_half_width" in r]
        out[(st, m, sy, s)] = (float(np.mean([r["inside"][s] for r in sel])), float(np.mean(p)) if p else None,
                               float(np.mean(e)) if e else None, len(sel))
    return out


def per_curve_table(rows: list[dict]) -> str:
    """Mean share inside per (setting, method, system, slot): where the bands fail; where the rows
    have them, the plain Laplace band's share and its mean |error| / half-width (bias or spread).

    Examples
    --------
    >>> from charcurves.experiments import per_curve_table
    >>> rows = [{"setting": "F25", "method": "poly-cc", "system": "s", "seed": 0, "inside": {"f1": 0.9}}]
    >>> print(per_curve_table(rows).splitlines()[2])
    | F25 | poly-cc | s | f1 | 0.900 | – | – | 1 |
    """
    out = ["| setting | method | system | curve | grid inside (mean) | plain Laplace band | "
           "plain: mean abs error / half-width | seeds |", "|---|---|---|---|---|---|---|---|"]
    for (st, m, sy, s), (v, p, e, n) in _per_curve(rows).items():
        out.append(f"| {st} | {m} | {sy} | {s} | {v:.3f} | {'–' if p is None else f'{p:.3f}'} | "
                   f"{'–' if e is None else f'{e:.2f}'} | {n} |")
    return "\n".join(out)


def _mean(rows: list[dict], setting: str, method: str, key: str) -> float:
    return float(np.mean([v for r in rows if (r["setting"], r["method"]) == (setting, method) and "error" not in r
                          for v in r[key].values()]))


def _span(values: list[float], digits: int) -> str:
    lo, hi = f"{min(values):.{digits}f}", f"{max(values):.{digits}f}"
    return lo if lo == hi else f"{lo}–{hi}"


def _text(rows: list[dict], default: list[dict], duffing: list[dict]) -> str:
    """The sentences under the tables: each figure computed from the same rows (``default``: as
    :func:`gated` gives them, the term where the test rejects)."""
    curves = _per_curve(default)
    basis = [(k, v) for k, v in curves.items() if k[0] == "F25" and k[1] in ("poly-cc", "sindy-cc+sym")]
    biased = [(k, v) for k, v in basis if v[2] is not None and v[2] > 1]  # mean |error| over the half-width
    limit = [v[2] for k, v in curves.items() if k[:2] == ("F25", "parametric") and v[2] is not None]
    helped = sorted((v[0], k) for k, v in biased if v[0] != v[1])  # the curves where the term applies
    lowest = helped[0]
    cosine = curves.get(("F25", "nn-cc+sym", "fo-sinh-cos", "f2"))
    by = {(d["setting"], d["method"]): d for d in duffing}
    force = [by[("force", m)] for m in ("parametric", "poly-cc", "sindy-cc", "sindy-cc+sym") if ("force", m) in by]
    text = (f"- **F25:** the limit's bands are calibrated ({_mean(rows, 'F25', 'parametric', 'inside_plain'):.3f} "
            f"plain, {_mean(default, 'F25', 'parametric', 'inside'):.3f} with the term, which rarely applies).\n"
            f"  poly-cc and sindy-cc+sym are short because of bias, not spread: without the term the mean |error| /\n"
            f"  half-width is {_span([v[2] for _, v in biased if v[2] is not None], 1)} where the basis cannot take the curve (stops, "
            f"soft clips, tanh friction,\n  Stribeck, a Gaussian damping), against {_span(limit, 1)} for the limit. "
            f"The term brings {len(helped) - 1} of these curves\n  to {_span([v for v, _ in helped[1:]], 2)}; it "
            f"stays short where the bias is below what the test detects, and on {lowest[1][2]}'s {lowest[1][3]}\n"
            f"  ({lowest[1][1]}, {lowest[0]:.2f}).")
    if cosine is not None and cosine[1] is not None:
        text += (" nn-cc+sym runs on every system here, also where its odd prior is wrong\n"
                 f"  (fo-sinh-cos f2, the cosine spring, {cosine[1]:.1f} without the term).")
    x30 = ", ".join(f"{m} {_mean(rows, 'x30', m, 'inside_plain'):.3f} to {_mean(default, 'x30', m, 'inside'):.3f}"
                    for m in ("poly-cc", "sindy-cc+sym", "parametric") if any(r["setting"] == "x30" and r["method"] == m
                                                                           for r in rows))
    text += ("\n- **x30:** the derivatives of a noisy x bias every equation-error fit (errors in variables, as with\n"
             "  the Duffing gain above); that bias is mostly not a function of one curve's argument, so the term\n"
             f"  catches only part of it ({x30}).\n")
    if force:
        realisations = force[0]["realisations"]
        state = {m: by[("state", m)] for m in ("poly-cc", "sindy-cc", "sindy-cc+sym") if ("state", m) in by}
        text += (f"\nOn Duffing (`benchmarks/bench_lack_of_fit_duffing.py`, realisations 0–{realisations - 1}) the term "
                 "changes nothing\nwith noise on F (" if all(d["with_term"] == d["plain"] for d in force) else
                 f"\nOn Duffing (`benchmarks/bench_lack_of_fit_duffing.py`, realisations 0–{realisations - 1}), "
                 "with noise on F\n(")
        text += ", ".join(f"{d['method']} {d['with_term']:.3f}" for d in force)
        text += (" both ways; added in " if all(d["with_term"] == d["plain"] for d in force) else "; added in ")
        text += ", ".join(str(d["fits_with_term"]) for d in force[:-1]) + f" and {force[-1]['fits_with_term']} of\n"
        text += f"{realisations} fits)"
        if state:
            text += "; with 40 dB on x the term takes " + ", ".join(f"{m} from {d['plain']:.3f} to {d['with_term']:.3f}"
                                                    for m, d in state.items())
        par = by.get(("state", "parametric"))
        if par is not None and "half_width_plain" in par:
            text += (f";\nit also widens parametric there, which covers {par['plain']:.3f} without it, in "
                     f"{par['fits_with_term']} of {realisations} fits (mean half-width / sd {par['half_width_plain']:.3f} "
                     f"to {par['half_width_with_term']:.3f}: the noisy x's bias, not a shape misfit)")
        text += ".\n"
    before = gated_rows(_previous(rows), _gate_level())
    if before:
        text += ("\nBefore issue 48's level fix the estimate held every curve's bias at 0 at 0 and dropped the residual's\n"
                 "constant (the offset of the curve that carries it); on the same fits that gave with noise on F\n"
                 + ", ".join(f"{m} {_mean(before, 'F25', m, 'inside'):.3f} (mean half-width / sd "
                             f"{_mean(before, 'F25', m, 'half_width'):.3f}, now {_mean(default, 'F25', m, 'half_width'):.3f})"
                             for m in ("poly-cc", "sindy-cc+sym")) + ".\n")
    sparse = [r for r in rows if "inside_before" in r and r["setting"] == "F25"]
    if sparse:
        from ..fitting import SPARSE_LACK_OF_FIT

        m, shrink = sparse[0]["method"], SPARSE_LACK_OF_FIT["shrink"]
        before_rows = [{**r, "inside": r["inside_before"], "half_width": r["half_width_before"]} for r in sparse]
        text += (f"\n{m} is a sparse regression's fit: its bands are conditioned on the terms it kept (here "
                 f"{_span([r['n_active_terms'] for r in sparse], 0)} of {sparse[0]['library_size'] - 1}), and its\n"
                 f"curves whose test passes now get a coarser term too ({SPARSE_LACK_OF_FIT['bins']} bins, {shrink:g} of the "
                 "estimate's variance taken out;\nchosen on the tuning half). With noise on F that takes it from "
                 f"{_mean(before_rows, 'F25', m, 'inside'):.3f} (the term only where the test rejects) to "
                 f"{_mean(sparse, 'F25', m, 'inside'):.3f} of the grid (mean\nhalf-width / sd "
                 f"{_mean(before_rows, 'F25', m, 'half_width'):.3f} to {_mean(sparse, 'F25', m, 'half_width'):.3f}).\n")
    short = [(m, _mean(default, "F25", m, "inside")) for m in ("poly-cc", "sindy-cc+sym")]
    short = [(m, v) for m, v in short if v < 0.9]
    text += "\nStill under-covered: equation-error fits with noise on x"
    text += (", and, with noise on F, " + " and ".join(f"{m} at {v:.2f}" for m, v in short) + " (target 0.90–0.98)."
             if short else ".")
    return text + "\n"


def _previous(rows: list[dict]) -> list[dict]:
    """The rows with the band of the estimate before issue 48's level fix (``--previous``), where they have it."""
    return [{**r, "inside": r["inside_prev"], "half_width": r["half_width_prev"], "binned_p": r["binned_p_prev"],
             "lof_every_curve": False} for r in rows if "inside_prev" in r]


def _gate_level() -> float:
    from ..fitting import LACK_OF_FIT_LEVEL

    return LACK_OF_FIT_LEVEL


def gated(rows: list[dict]) -> list[dict]:
    """The rows as a default fit gives them: the term only where the library's test rejects."""
    from ..fitting import LACK_OF_FIT_LEVEL

    return gated_rows(rows, LACK_OF_FIT_LEVEL)


def zoo_coverage_tables(results_root: str | os.PathLike) -> dict[str, str]:
    """``{marker: text}`` of docs/uncertainty-zoo.md: ``zoo-coverage-term`` (the default band, with the
    lack-of-fit term where the bias test rejects), ``zoo-coverage-plain`` (the plain Laplace band of the
    same fits) and ``zoo-coverage-text`` (the sentences under them, with the Duffing check); empty without
    the committed results.

    Examples
    --------
    >>> import tempfile
    >>> from charcurves.experiments import zoo_coverage_tables
    >>> zoo_coverage_tables(tempfile.mkdtemp())
    {}
    """
    root = os.fspath(results_root)
    path = os.path.join(root, _RESULTS)
    if not os.path.exists(path):
        return {}
    rows = _jsonl(path)
    sparse_path = os.path.join(root, _SPARSE)
    sparse = _jsonl(sparse_path) if os.path.exists(sparse_path) else []
    rows = [r for r in rows if r["method"] not in {s["method"] for s in sparse}] + sparse
    default = gated(rows)
    duffing_path = os.path.join(root, _DUFFING)
    duffing = _jsonl(duffing_path) if os.path.exists(duffing_path) else []
    newer_path = os.path.join(root, _DUFFING_SPARSE)
    newer = _jsonl(newer_path) if os.path.exists(newer_path) else []
    ran = {(d["setting"], d["method"]) for d in newer}
    duffing = [d for d in duffing if (d["setting"], d["method"]) not in ran] + newer
    return {"zoo-coverage-term": coverage_table(default, _ALL_METHODS) + "\n",
            "zoo-coverage-plain": coverage_table(default, _ALL_METHODS, key="inside_plain") + "\n",
            "zoo-coverage-text": _text(rows, default, duffing)}
