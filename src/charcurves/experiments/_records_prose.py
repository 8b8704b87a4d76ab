"""The sentences under the tables of docs/measured-records.md, rendered from ``state_noise.json``.

Each figure of these sentences (the default's ratio to the limit, the peer's, equation error's against output
error, the learned friction jump, the other families' worst curve, the cost ratios) is computed from the same
rows as the tables above them, so a rerun of ``benchmarks/bench_state_noise.py`` rewrites them too
(``python benchmarks/render_docs.py``). :func:`records_prose` is merged into
:func:`charcurves.experiments.docs_tables`.
"""

from __future__ import annotations

from collections import OrderedDict

import numpy as np

__all__ = ["records_prose"]

_LIMIT = "parametric (true basis) + output error: the limit"
_PEER = "PySINDy weak form (the peer)"


def _means(rows: list[dict], system: str, key: str = "worst") -> OrderedDict:
    """``{(label, differentiator, snr, objective class): mean of key over the seeds}`` of one system."""
    cells: OrderedDict = OrderedDict()
    for r in rows:
        if r["system"] == system and "error" not in r and r.get(key) is not None:
            column = "equation-error" if r["objective"] == "equation-error" else "auto"
            cells.setdefault((r["label"], r["differentiator"], r["snr"], column), []).append(r[key])
    return OrderedDict((k, float(np.mean(v))) for k, v in cells.items())


def _span(values: list[float], digits: int = 2) -> str:
    lo, hi = min(values), max(values)
    return f"{lo:.{digits}g}×" if f"{lo:.{digits}g}" == f"{hi:.{digits}g}" else f"{lo:.{digits}g}–{hi:.{digits}g}×"


def duffing_text(data: dict) -> str:
    """The default against the limit and the peer per SNR; equation error against output error; the starts."""
    m = _means(data["rows"], "duffing")
    snrs = sorted({k[2] for k in m}, reverse=True)
    methods = [k for k in m if k[3] == "auto" and k[0] not in (_LIMIT, _PEER)]
    to_limit: list[str] = []
    peer: list[str] = []
    starts: list[str] = []
    for snr in snrs:
        limit = next(v for k, v in m.items() if k[0] == _LIMIT and k[2] == snr)
        own = [v for k, v in m.items() if k in methods and k[2] == snr]
        to_limit.append(f"{_span([v / limit for v in own])} the limit's at {snr:g} dB")
        peer_v = [v for k, v in m.items() if k[0] == _PEER and k[2] == snr]
        if peer_v:
            peer.append(f"{_span([peer_v[0] / v for v in own])}" + (" the methods'" if not peer else "")
                        + f" at {snr:g} dB")
        diffs = [v for k, v in m.items() if k in methods and k[0] == "nn-cc+sym" and k[2] == snr]
        if len(diffs) > 1:
            starts.append(f"{max(diffs) / min(diffs):.2f}× at {snr:g} dB")
    ee = [m[(k[0], k[1], k[2], "equation-error")] / v for k, v in m.items()
          if k in methods and (k[0], k[1], k[2], "equation-error") in m]
    text = ("With the default objective, every method's mean worst-curve RMSE is " + " and ".join(to_limit) + ".")
    if peer:
        text += " The peer's is " + " and ".join(peer) + "."
    text += (f" Equation error alone is {_span(ee)} the same method with output error (the same differentiator)."
             if ee else "")
    if starts:
        text += (" The start hardly matters once output error has run: nn-cc+sym's worst and best differentiator "
                 "end within " + " and ".join(starts) + " of each other.")
    return text + "\n"


def stick_slip_text(data: dict, true_jump: float | None) -> str:
    """The friction jump nn-cc+sym learns (the mean over the seeds of the default fit from spectral)."""
    jumps = [r["jump_height"] for r in data["rows"] if r["system"] == "stick-slip" and r["label"] == "nn-cc+sym"
             and r["objective"] != "equation-error" and r["differentiator"] == "spectral"
             and r.get("jump_height") is not None]
    if not jumps:
        return "The run stored no learned jump.\n"
    true = f"; true {true_jump:.3g}" if true_jump is not None else ""
    m = _means(data["rows"], "stick-slip", "f1")
    own = m.get(("nn-cc+sym", "spectral", 40.0, "auto"))
    limit = next((v for k, v in m.items() if k[0] == _LIMIT), None)
    than = ("" if own is None or limit is None else
            f" The limit's basis `z, sign(z)` ends with f1 {limit / own:.2g}× nn-cc+sym's (mean RMSE).")
    return (f"nn-cc+sym learns the jump μN = {np.mean(jumps):.3g} (mean of the {len(jumps)} seeds, spectral start{true})."
            f"{than}\n")


def families_text(data: dict) -> str:
    """The worst curve of every family record with the default objective."""
    auto = [r for r in data.get("family_rows") or [] if r["objective"] != "equation-error"]
    if not auto:
        return "The run has no family rows.\n"
    worst = max(auto, key=lambda r: r["worst"])
    return (f"The worst curve of any of these records is {100 * worst['worst']:.2g} % ({worst['system']}, "
            f"{worst['method']}, seed {worst['seed']}).\n")


def cost_text(data: dict) -> str:
    """The largest mean ratio of the output-error stage to the equation-error fit, and which row it is."""
    ratios: OrderedDict = OrderedDict()
    for r in data["rows"]:
        if r["objective"] == "auto" and r["differentiator"] == "spectral" and r.get("oe_seconds") and r.get("ee_seconds"):
            ratios.setdefault((r["system"], r["label"], r["snr"]), []).append(r["oe_seconds"] / r["ee_seconds"])
    for r in data.get("family_rows") or []:
        if r["objective"] == "auto" and r.get("oe_seconds"):
            ee = [q["seconds"] for q in data["family_rows"] if q["objective"] == "equation-error"
                  and (q["system"], q["method"], q["options"], q["seed"]) == (r["system"], r["method"], r["options"],
                                                                              r["seed"])]
            if ee:
                ratios.setdefault((r["system"], r["method"], 40.0), []).append(r["oe_seconds"] / ee[0])
    if not ratios:
        return "The run stored no timings.\n"
    (system, label, snr), worst = max(ratios.items(), key=lambda kv: np.mean(kv[1]))
    return (f"The largest mean ratio is {np.mean(worst):.1f}× ({system}, {label}, {snr:g} dB). The seconds are of "
            "that run, on that machine; the ratios are the figures to compare.\n")


def records_prose(data: dict, true_jump: float | None = None) -> dict[str, str]:
    """``{marker name: text}`` of the sentences under measured-records.md's tables, from ``state_noise.json``'s
    data; ``true_jump`` is the stick-slip system's μN (the page names it beside the learned one)."""
    return {"state-noise-duffing-text": duffing_text(data),
            "state-noise-stick-slip-text": stick_slip_text(data, true_jump),
            "state-noise-families-text": families_text(data),
            "state-noise-cost-text": cost_text(data)}
