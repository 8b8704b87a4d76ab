"""The curve zoo (issue 46, item 1): every default method against the limit, on curves no polynomial guesses.

For each system of ``benchmarks/zoo.py`` (17 systems, 34 scored curves, every family), each noise
setting and seed, fits the record with ``CharacteristicCurves.from_method(method=...)`` and its defaults, and
with the LIMIT: ``method="parametric"`` on the true closed form's terms (``basis=``), same default
objective. Scores each curve by its normalised RMSE: the RMSE over the curve's argument range in
the clean record (1000 points) divided by the standard deviation of the true curve there (as
benchmarks/bench_state_noise.py), and by its ratio to the limit's.

Noise settings: ``F25`` (also ``F20``, ``F30``): Gaussian noise on F at that SNR, the record's
exact x, x', x'' given; ``x30`` (also ``x40``): noise on x only, derivatives estimated (the default
differentiator), the default objective (equation error, then output error). Methods: nn-cc,
poly-cc, and where every curve of the system is odd (the +sym default prior holds) nn-cc+sym and
sindy-cc+sym; nn-cc+post-sr on F25 seed 0 (``--grid first``; every pass with ``--post-sr``).

Every job, keyed by (system, method, setting, seed), is appended to
``benchmarks/results/zoo/results.jsonl`` as it ends (a failure of the library is recorded with its
error); a rerun skips the jobs already there, so an interrupted run resumes. The tables are
printed from that file (``--report-only`` prints them without fitting; ``--markdown FILE`` writes
the tables of docs/zoo.md between its markers; ``--out benchmarks/results/zoo/current.jsonl
--markdown-current docs/zoo.md`` its summary of the defaults as they are now).

Run: ``python benchmarks/bench_zoo.py [--grid quick|first|full] [--workers N] [--report-only]``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
if HERE not in sys.path:
    sys.path.insert(0, HERE)

import zoo  # noqa: E402

RESULTS = os.path.join(HERE, "results", "zoo", "results.jsonl")
#: The library as it is now: the ``seed0`` grid rerun on the code that docs/zoo.md describes.
CURRENT = os.path.join(HERE, "results", "zoo", "current.jsonl")
LIMIT = "limit"
#: The methods in table order; "limit" is the parametric fit on the true basis.
METHODS = ("nn-cc", "nn-cc+sym", "poly-cc", "sindy-cc+sym", "nn-cc+post-sr", LIMIT)
ODD_ONLY = ("nn-cc+sym", "sindy-cc+sym")
#: method labels "METHOD/VARIANT": the method with its default preset changed (issue 46, item 2):
#: "no-auto" without the automatic terms, "unchecked" with them but not checked, "checked" kept by
#: AIC, "heldout" chosen per term on the samples held out at the ends of the range
VARIANTS = {"no-auto": {"auto_terms": False}, "unchecked": {"check_auto_terms": False},
            "checked": {"check_auto_terms": True, "auto_terms_rule": "aic"},
            "heldout": {"check_auto_terms": True, "auto_terms_rule": "held-out"}}
#: every label a table may show, in table order (the variants after their method)
LABELS = tuple(x for m in METHODS for x in [m] + ([f"{m}/{v}" for v in VARIANTS] if m in ("nn-cc", "nn-cc+sym") else []))
#: setting -> (noise on, SNR in dB)
SETTINGS = {"F20": ("force", 20.0), "F25": ("force", 25.0), "F30": ("force", 30.0), "x30": ("state", 30.0),
            "x40": ("state", 40.0)}
#: the issue's nRMSE target per setting (the curve counts where the limit is below a third of it)
TARGET = {"F25": 0.01, "x30": 0.015}
#: a job whose scored curve is off by more than this (nRMSE) is a misfit the self-check should flag
MISFIT = 0.05
#: ratio targets of nn-cc(+sym): the half's median and worst ratio to the limit
RATIO_MEDIAN, RATIO_WORST = 1.5, 3.0


# ----------------------------------------------------------------------------- the grid
POST_SR = "nn-cc+post-sr"


def jobs_for(grid: str, post_sr: bool = False, methods=None) -> list[tuple[str, str, str, int]]:
    """The jobs of a grid, in run order: passes of (setting, seed), each over every system and method,
    so that a run cut short holds whole passes. ``quick``: 4 systems, F25 and x30, seed 0; ``first``
    (the committed run): F25 seeds 0-2, x30 seeds 0-1, F20 and F30 seed 0, nn-cc+post-sr on F25 seed
    0, then x40 seed 0; ``full``: every setting, seeds 0-4, nn-cc+post-sr with ``post_sr``.
    ``seed0``: the first two passes of ``first`` (F25 and x30, seed 0). ``methods``: these labels (``LABELS``, e.g. ``nn-cc/no-auto``) in place of the grid's methods."""
    plain = [m for m in METHODS if m != POST_SR]
    if grid == "quick":
        systems = ["sep-drag-tanh", "sep-atan-asym", "pd-gauss-tanh", "fo-tanh-tanh"]
        passes = [("F25", 0, plain), ("x30", 0, plain)]
    elif grid == "seed0":
        systems = list(zoo.SYSTEMS)
        passes = [("F25", 0, plain), ("x30", 0, plain)]
    elif grid == "first":
        systems = list(zoo.SYSTEMS)
        passes = [(s, k, plain) for s, k in (("F25", 0), ("x30", 0), ("F25", 1), ("x30", 1), ("F25", 2), ("F20", 0),
                                             ("F30", 0))] + [("F25", 0, [POST_SR]), ("x40", 0, plain)]
    elif grid == "full":
        systems = list(zoo.SYSTEMS)
        passes = [(s, seed, plain) for seed in range(5) for s in SETTINGS]
    else:
        raise SystemExit(f"unknown grid {grid!r}; choose quick, seed0, first or full")
    if post_sr and grid != "first":
        passes += [(s, k, [POST_SR]) for s, k, _ in passes]
    if methods is not None:
        passes = [(s, k, list(methods)) for s, k, ms in passes if POST_SR not in ms]
    out = []
    for setting, seed, pass_methods in passes:
        for name in systems:
            for m in pass_methods:
                if m.split("/")[0] in ODD_ONLY and not zoo.SYSTEMS[name].all_odd():
                    continue
                out.append((name, m, setting, seed))
    return out


def job_key(job) -> str:
    return "|".join(map(str, job))


# ----------------------------------------------------------------------------- one job
def noisy_record(system: zoo.ZooSystem, setting: str, seed: int, clean=None):
    """The record of a job: the clean simulation with the setting's noise drawn from ``seed``."""
    from charcurves.data import add_noise, as_rng, corrupt
    from charcurves.systems import corrupt_forces

    clean = system.simulate() if clean is None else clean
    on, snr = SETTINGS[setting]
    if system.family != "two-dof":
        return corrupt(clean, snr, on=on, seed=seed)
    if on == "force":
        return corrupt_forces(clean, snr, seed=seed)
    rng = as_rng(seed)
    return clean.replace(states={k: add_noise(v, snr, rng, "std") for k, v in clean.states.items()},
                         velocities=None, accelerations=None)


def score(model_curves, system: zoo.ZooSystem, clean) -> dict[str, float]:
    """Normalised RMSE of every curve of the system that has a truth: RMSE over the argument's range in
    the clean record / std of the true curve on the same grid."""
    from charcurves.metrics import curve_rmse

    truth = system.truth()
    args = _all_arguments(system, clean)
    out = {}
    for slot, f in truth.items():
        if slot not in model_curves or slot not in args:
            continue
        lo, hi = float(args[slot].min()), float(args[slot].max())
        grid = np.linspace(lo, hi, 1000)
        out[slot] = curve_rmse(model_curves[slot], f, domain=(lo, hi)) / float(np.std(f(grid)))
    return out


def _all_arguments(system, clean):
    if system.family == "two-dof":
        s, v = clean.states, clean.velocities
        return {"f1": v["x1"], "f2": s["x1"] - s["x2"], "f3": v["x2"], "f4": s["x2"] - s["x1"]}
    if system.family == "separable":
        return {"f1": clean.v, "f2": clean.x}
    return {"f1": clean.x, "f2": clean.x}


_CLEAN: dict[str, object] = {}


def run_job(job) -> dict:
    """Fit one job and return its result row (a library error is a row with ``error``)."""
    import torch

    torch.set_num_threads(1)
    import charcurves as cc

    name, method, setting, seed = job
    system = zoo.SYSTEMS[name]
    if name not in _CLEAN:
        _CLEAN[name] = system.simulate()
    clean = _CLEAN[name]
    record = noisy_record(system, setting, seed, clean)
    base, _, variant = method.partition("/")
    kw = {"method": "parametric", "basis": zoo.basis_option(system)} if method == LIMIT else {"method": base}
    if variant:
        kw["preset"] = cc.PRESETS["default"].replace(**VARIANTS[variant])
    row = {"key": job_key(job), "system": name, "family": system.family, "method": method, "setting": setting,
           "seed": seed, "load_start": round(os.getloadavg()[0], 2)}
    t0 = time.perf_counter()
    try:
        model = cc.CharacteristicCurves.from_method(family=system.family, random_state=seed, threads=1, **kw).fit(record).model_
        row["nrmse"] = score(model.curves, system, clean)
        info = getattr(model, "info", {}) or {}
        check = info.get("self_check")
        if isinstance(check, dict):
            row["self_check"] = check.get("passed")
            residual = check.get("residual_tests")
            if isinstance(residual, dict):  # the residual tests (issue 46, item 5), besides the loss check
                row["residual_tests_passed"] = residual.get("passed")
            row["loss_over_floor"] = check.get("loss_over_floor")
        for k in ("n_sticking_samples",):
            if k in info:
                row[k] = info[k]
        jumps = {k: c.components().get("jump_height") for k, c in model.curves.items() if hasattr(c, "components")}
        if any(v is not None for v in jumps.values()):
            row["jump_height"] = {k: v for k, v in jumps.items() if v is not None}
        auto = info.get("automatic_terms")
        if isinstance(auto, dict):  # the held-out check of the automatic terms (issue 46, item 2)
            row["automatic_terms"] = auto
        oe = info.get("output_error")
        if isinstance(oe, dict):
            row["oe_status"] = oe.get("status")
            row["oe_iterations"] = oe.get("iterations")
            if oe.get("networks_revived"):  # networks equation error pruned, reopened by output error
                row["oe_networks_revived"] = oe["networks_revived"]
        sym = info.get("symmetry")
        if sym is not None:
            row["symmetry"] = sym if isinstance(sym, (str, dict)) else str(sym)
        if method.endswith("post-sr"):
            row["closed_forms"] = {k: (str(e) if (e := c.expression()) is not None else None)
                                   for k, c in model.curves.items()}
    except Exception as exc:  # noqa: BLE001 - a failure of the library is a result, recorded
        row["error"] = f"{type(exc).__name__}: {str(exc)[:300]}"
    row["seconds"] = round(time.perf_counter() - t0, 2)
    row["load_end"] = round(os.getloadavg()[0], 2)
    return json.loads(json.dumps(row, default=str))


# ----------------------------------------------------------------------------- the store
def read_results(path: str) -> list[dict]:
    """The rows of the store (a line cut short by an interruption is skipped); the last row of a key wins."""
    if not os.path.exists(path):
        return []
    rows = {}
    with open(path, encoding="utf-8") as fh:
        for line in fh:
            line = line.strip()
            if not line:
                continue
            try:
                row = json.loads(line)
            except json.JSONDecodeError:
                continue
            rows[row["key"]] = row
    return list(rows.values())


def append_result(path: str, row: dict) -> None:
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "a", encoding="utf-8") as fh:
        fh.write(json.dumps(row, sort_keys=True) + "\n")
        fh.flush()
        os.fsync(fh.fileno())


# ----------------------------------------------------------------------------- the tables
def summarise(rows: list[dict]) -> dict:
    """Per (half, setting, method): the rows scored, their nRMSE and ratio to the limit.

    For each zoo row (system, slot) and seed the ratio is nRMSE(method) / nRMSE(limit) of the same
    record; a row's figure is the median over its seeds. Returns
    ``{(half, setting, method): {"rows": [(system, slot, nrmse, ratio, limit_nrmse)], "failed": n,
    "seconds": [...], "load": [...]}}``.
    """
    by_job = {(r["system"], r["method"], r["setting"], r["seed"]): r for r in rows}
    groups: dict = {}
    for (system, method, setting, seed), r in sorted(by_job.items()):
        half = zoo.SYSTEM_HALF.get(system)
        if half is None:
            continue
        g = groups.setdefault((half, setting, method), {"per_row": {}, "failed": [], "seconds": [], "load": [],
                                                        "misfit": [0, 0]})
        g["seconds"].append(r.get("seconds", float("nan")))
        g["load"].append(r.get("load_start", float("nan")))
        if "error" in r:
            g["failed"].append(f"{system} seed {seed}: {r['error']}")
            continue
        if any(r["nrmse"].get(slot, 0.0) > MISFIT for slot in zoo.SYSTEMS[system].scored):
            g["misfit"][1] += 1
            g["misfit"][0] += r.get("self_check") is False or r.get("residual_tests_passed") is False
        lim = by_job.get((system, LIMIT, setting, seed))
        for slot in zoo.SYSTEMS[system].scored:
            e = r["nrmse"].get(slot)
            le = lim["nrmse"].get(slot) if lim and "nrmse" in lim else None
            ratio = e / le if (e is not None and le) else float("nan")
            g["per_row"].setdefault((system, slot), []).append((e, ratio, le))
    out = {}
    for key, g in groups.items():
        rws = []
        for (system, slot), vals in sorted(g["per_row"].items(), key=lambda kv: zoo.ROWS.index(kv[0])):
            e = float(np.median([v[0] for v in vals]))
            ratios = [v[1] for v in vals if np.isfinite(v[1])]
            lims = [v[2] for v in vals if v[2] is not None]
            rws.append((system, slot, e, float(np.median(ratios)) if ratios else float("nan"),
                        float(np.median(lims)) if lims else float("nan"), len(vals)))
        out[key] = {"rows": rws, "failed": g["failed"], "seconds": g["seconds"], "load": g["load"],
                    "misfit": tuple(g["misfit"])}
    return out


def _fmt(x, pct=True):
    if x is None or not np.isfinite(x):
        return "-"
    return f"{100 * x:.2f} %" if pct else f"{x:.2f}"


def table_lines(rows: list[dict], *, markdown: bool = False) -> list[str]:
    """The summary tables, one per half: per setting and method, the median nRMSE, the median and worst
    ratio to the limit (with the worst row named), the count of rows within ratio 3, the count within
    the issue's nRMSE target among the rows where the limit is below a third of it, and of the jobs with
    a curve off by more than MISFIT (5 %) those whose self-check failed (the loss check,
    ``info["self_check"]["passed"]``, or the residual tests, ``["residual_tests"]["passed"]``)."""
    summ = summarise(rows)
    lines: list[str] = []
    head = ["setting", "method", "rows", "seeds", "median nRMSE", "median ratio", "worst ratio (row)",
            "ratio <= 3", "nRMSE target", "misfits flagged", "failed", "s/fit", "load"]
    for half in ("tuning", "report"):
        title = f"{half} half ({sum(1 for r in zoo.ROWS if zoo.HALF[r] == half)} curves, "\
                f"{sum(1 for h in zoo.SYSTEM_HALF.values() if h == half)} systems)"
        lines += ["", f"### {title}" if markdown else f"== {title} ==", ""]
        body = []
        for setting in SETTINGS:
            for method in LABELS:
                g = summ.get((half, setting, method))
                if g is None:
                    continue
                rws = g["rows"]
                es = [r[2] for r in rws]
                ratios = [r[3] for r in rws if np.isfinite(r[3])]
                seeds = max((r[5] for r in rws), default=0)
                if method == LIMIT:
                    med_r = worst = within3 = "-"
                elif ratios:
                    i = int(np.nanargmax([r[3] if np.isfinite(r[3]) else -1 for r in rws]))
                    med_r = _fmt(float(np.median(ratios)), False)
                    worst = f"{rws[i][3]:.2f} ({rws[i][0]} {rws[i][1]})"
                    within3 = f"{sum(r <= RATIO_WORST for r in ratios)}/{len(ratios)}"
                else:
                    med_r = worst = within3 = "-"
                tgt = TARGET.get(setting)
                if tgt is not None:
                    elig = [r for r in rws if np.isfinite(r[4]) and r[4] < tgt / 3]
                    target = f"{sum(r[2] <= tgt for r in elig)}/{len(elig)} <= {100 * tgt:g} %"
                else:
                    target = "-"
                secs = [s for s in g["seconds"] if np.isfinite(s)]
                loads = [x for x in g["load"] if np.isfinite(x)]
                body.append([setting, method, str(len(rws)), str(seeds), _fmt(float(np.median(es)) if es else None),
                             med_r, worst, within3, target, "{}/{}".format(*g["misfit"]), str(len(g["failed"])),
                             f"{np.median(secs):.1f}" if secs else "-", f"{np.median(loads):.2f}" if loads else "-"])
        if markdown:
            lines += ["| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"]
            lines += ["| " + " | ".join(b) + " |" for b in body]
        else:
            widths = [max(len(x) for x in col) for col in zip(head, *body)]
            lines += ["  ".join(h.ljust(w) for h, w in zip(head, widths))]
            lines += ["  ".join(x.ljust(w) for x, w in zip(b, widths)) for b in body]
    failed = [(k, f) for k, g in summ.items() for f in g["failed"]]
    if failed:
        lines += ["", "failures (library errors, recorded):" if not markdown else "Failures (library errors, recorded):",
                  ""]
        lines += [f"- {k[1]} {k[2]} {f}" for k, f in failed]
    return lines


def curve_lines(rows: list[dict], setting: str, *, markdown: bool = False) -> list[str]:
    """Per zoo row, the nRMSE of every method at ``setting`` (median over seeds) and the limit's."""
    summ = summarise(rows)
    methods = [m for m in LABELS if any(k[1] == setting and k[2] == m for k in summ)]
    table = {}
    for (half, s, m), g in summ.items():
        if s == setting:
            for system, slot, e, _ratio, _lim, _n in g["rows"]:
                table[(system, slot, m)] = e
    head = ["half", "system", "slot", "curve", "parity"] + methods
    body = []
    for system, slot in zoo.ROWS:
        if not any((system, slot, m) in table for m in methods):
            continue
        c = zoo.SYSTEMS[system].curve(slot)
        body.append([zoo.HALF[(system, slot)], system, slot, c.key, c.parity]
                    + [_fmt(table.get((system, slot, m))) for m in methods])
    return _render(head, body, markdown)


def _render(head: list[str], body: list[list[str]], markdown: bool) -> list[str]:
    """A table's lines: Markdown, or columns padded to their widths; no lines for an empty body."""
    if not body:
        return []
    if markdown:
        return ["| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"] + \
            ["| " + " | ".join(b) + " |" for b in body]
    widths = [max(len(x) for x in col) for col in zip(head, *body)]
    return ["  ".join(h.ljust(w) for h, w in zip(head, widths))] + \
        ["  ".join(x.ljust(w) for x, w in zip(b, widths)) for b in body]


def jump_lines(rows: list[dict], *, markdown: bool = False) -> list[str]:
    """Dry friction where there is none: per setting and method (zoo curves are smooth, none has a jump),
    the jobs that learned a jump at 0 (``jump_height`` of a curve), how many of those jumps are negative
    (friction that feeds energy in), and the jobs that left sticking samples out (``n_sticking_samples``).
    Counted over the jobs that recorded these fields."""
    groups: dict = {}
    for r in rows:
        if "error" in r or r["method"] == LIMIT or "n_sticking_samples" not in r:
            continue
        g = groups.setdefault((r["setting"], r["method"]), [0, 0, 0, 0])
        jumps = list((r.get("jump_height") or {}).values())
        g[0] += 1
        g[1] += bool(jumps)
        g[2] += any(j < 0 for j in jumps)
        g[3] += r["n_sticking_samples"] > 0
    head = ["setting", "method", "jobs", "jump learned", "negative jump", "sticking samples dropped"]
    body = [[s, m, *map(str, groups[(s, m)])] for s in SETTINGS for m in LABELS if (s, m) in groups]
    return _render(head, body, markdown)


BEGIN, END = "<!-- zoo-tables:begin (written by benchmarks/bench_zoo.py --markdown) -->", "<!-- zoo-tables:end -->"
CURRENT_BEGIN = "<!-- zoo-current:begin (written by benchmarks/bench_zoo.py --out CURRENT --markdown-current) -->"
CURRENT_END = "<!-- zoo-current:end -->"


def zoo_lines() -> list[str]:
    """The zoo's rows as a Markdown table: half, system, family, slot, closed form, parity, range."""
    head = ["half", "system", "family", "slot", "curve", "closed form", "parity", "range excited"]
    body = []
    for system, slot in zoo.ROWS:
        s = zoo.SYSTEMS[system]
        c = s.curve(slot)
        body.append([zoo.HALF[(system, slot)], system, s.family, slot, c.kind.replace("|", "\\|"), f"`{c.text()}`", c.parity,
                     f"{c.span[0]:g} .. {c.span[1]:g}"])
    return ["| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"] + \
        ["| " + " | ".join(b) + " |" for b in body]


def _source_line(rows: list[dict], source: str) -> str:
    """"From `benchmarks/results/zoo/SOURCE`: N jobs (F25 seed 0, ...)." for a page's block."""
    passes = ", ".join(f"{s} seed {k}" for s, k in sorted({(r["setting"], r["seed"]) for r in rows}))
    return f"From `benchmarks/results/zoo/{source}`: {len(rows)} jobs ({passes})."


def markdown_block(rows: list[dict]) -> str:
    """The generated part of docs/zoo.md: the zoo's curves, the summary per half and the per-curve tables."""
    out = [BEGIN, "", "## The curves", "", *zoo_lines(), "", "## Results", "", _source_line(rows, "results.jsonl"),
           *table_lines(rows, markdown=True)]
    jl = jump_lines(rows, markdown=True)
    if jl:
        out += ["", "### Jumps and sticking on smooth curves (both halves)", "", *jl]
    for setting in SETTINGS:
        lines = curve_lines(rows, setting, markdown=True)
        if lines:
            out += ["", f"### Per curve, {setting} (normalised RMSE, median over seeds)", "", *lines]
    out += ["", END]
    return "\n".join(out) + "\n"


def current_block(rows: list[dict], source: str = "current.jsonl") -> str:
    """The generated part of docs/zoo.md on today's defaults: the summary per half of ``source``."""
    out = [CURRENT_BEGIN, "", _source_line(rows, source), *table_lines(rows, markdown=True), "", CURRENT_END]
    return "\n".join(out) + "\n"


def write_markdown(path: str, rows: list[dict], *, current: bool = False) -> None:
    """Replace the text between the markers of ``path`` (or append the block) with the tables:
    the committed grid's (``markdown_block``) or, with ``current``, today's defaults' (``current_block``)."""
    text = open(path, encoding="utf-8").read() if os.path.exists(path) else ""
    begin, end = (CURRENT_BEGIN, CURRENT_END) if current else (BEGIN, END)
    block = current_block(rows) if current else markdown_block(rows)
    if begin in text and end in text:
        head, rest = text.split(begin, 1)
        tail = rest.split(end, 1)[1].lstrip("\n")
        text = head + block + ("\n" + tail if tail else "")
    else:
        text = text + ("\n" if text and not text.endswith("\n") else "") + block
    tmp = path + ".tmp"
    with open(tmp, "w", encoding="utf-8") as fh:
        fh.write(text)
    os.replace(tmp, path)


# ----------------------------------------------------------------------------- main
def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grid", default="first", choices=("quick", "seed0", "first", "full"))
    parser.add_argument("--post-sr", action="store_true", help="nn-cc+post-sr on every pass (Operon; slower)")
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--out", default=RESULTS, help="the JSONL store (default %(default)s)")
    parser.add_argument("--report-only", action="store_true", help="print the tables of the store; fit nothing")
    parser.add_argument("--markdown", metavar="FILE", help="write the tables into FILE (docs/zoo.md)")
    parser.add_argument("--markdown-current", metavar="FILE",
                        help="write the summary of --out (today's defaults: results/zoo/current.jsonl) into FILE")
    parser.add_argument("--limit-jobs", type=int, default=None, help="run at most this many new jobs")
    parser.add_argument("--methods", default=None,
                        help="comma-separated labels to run in place of the grid's methods, e.g. "
                             "nn-cc,nn-cc/no-auto,limit (METHOD/no-auto: without the automatic terms)")
    parser.add_argument("--half", choices=("tuning", "report"), default=None,
                        help="run only the systems of this half of the zoo")
    parser.add_argument("--settings", default=None, help="comma-separated noise settings to run (e.g. x30)")
    a = parser.parse_args(argv)
    if not a.report_only:
        done = {r["key"] for r in read_results(a.out)}
        methods = None if a.methods is None else [m.strip() for m in a.methods.split(",") if m.strip()]
        unknown = [m for m in methods or () if m not in LABELS]
        if unknown:
            parser.error(f"unknown method label(s) {', '.join(unknown)}; choose from {', '.join(LABELS)}")
        todo = [j for j in jobs_for(a.grid, a.post_sr, methods) if job_key(j) not in done
                and a.half in (None, zoo.SYSTEM_HALF[j[0]]) and (a.settings is None or j[2] in a.settings.split(","))]
        if a.limit_jobs is not None:
            todo = todo[:a.limit_jobs]
        t0 = time.perf_counter()
        print(f"{len(todo)} jobs to run ({len(done)} in the store); load average {os.getloadavg()[0]:.2f}", flush=True)
        if a.workers > 1:
            import multiprocessing as mp

            with mp.get_context("spawn").Pool(a.workers) as pool:
                for i, row in enumerate(pool.imap_unordered(run_job, todo, chunksize=1), 1):
                    append_result(a.out, row)
                    _progress(i, len(todo), row, t0)
        else:
            for i, job in enumerate(todo, 1):
                row = run_job(job)
                append_result(a.out, row)
                _progress(i, len(todo), row, t0)
    rows = read_results(a.out)
    print("\n".join(table_lines(rows)))
    jl = jump_lines(rows)
    if jl:
        print("\njumps and sticking on smooth curves (both halves)\n" + "\n".join(jl))
    for setting in SETTINGS:
        lines = curve_lines(rows, setting)
        if lines:
            print(f"\nper curve, {setting} (normalised RMSE, median over seeds)")
            print("\n".join(lines))
    if a.markdown:
        write_markdown(a.markdown, rows)
    if a.markdown_current:
        write_markdown(a.markdown_current, rows, current=True)
    return 0


def _progress(i, n, row, t0):
    res = row.get("error") or " ".join(f"{k} {100 * v:.2f}%" for k, v in row.get("nrmse", {}).items())
    print(f"[{i}/{n}] {row['key']}: {res}  {row['seconds']:.1f} s, load {row['load_start']:.2f}; "
          f"{time.perf_counter() - t0:.0f} s elapsed", flush=True)


if __name__ == "__main__":
    raise SystemExit(main())
