"""Coverage of the posterior bands on the curve zoo's report half (issue 46 item 6, issue 48).

For every system of the report half of ``benchmarks/zoo.py`` (``SYSTEM_HALF``), the noise settings
F25 (noise on F, derivatives given) and x30 (noise on x only, derivatives estimated by the default
differentiator) and each seed, fits poly-cc, parametric on the true closed form's terms (the zoo's
limit) and, where every curve is odd, sindy-cc+sym, all by equation error (``objective=
"equation-error"``: the fits that have a posterior; the default objective refines x30 fits by output
error, whose posterior is not in this benchmark). Each scored curve's 95 % band
(``model.curve_band``) is evaluated on 200 points over the argument range of the clean record and
the share of points where the truth lies inside it is recorded, with the band's mean half-width
relative to the true curve's sd. Rows are appended to ``benchmarks/results/zoo-coverage/results.jsonl``
as they end; a rerun skips the jobs already there.

Run: ``python benchmarks/bench_zoo_coverage.py --seeds 0-9 [--report-only] [--markdown FILE]``.
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
from bench_zoo import _all_arguments, noisy_record  # noqa: E402

RESULTS = os.path.join(HERE, "results", "zoo-coverage", "results.jsonl")
SETTINGS = ("F25", "x30")
METHODS = ("poly-cc", "sindy-cc+sym", "parametric")
LEVEL = 0.95


def jobs(seeds) -> list[tuple[str, str, str, int]]:
    out = []
    for seed in seeds:
        for setting in SETTINGS:
            for name, half in zoo.SYSTEM_HALF.items():
                if half != "report":
                    continue
                for method in METHODS:
                    if method == "sindy-cc+sym" and not zoo.SYSTEMS[name].all_odd():
                        continue
                    out.append((name, method, setting, seed))
    return out


def run_job(job, clean_cache) -> dict:
    import charcurves as cc

    name, method, setting, seed = job
    system = zoo.SYSTEMS[name]
    clean = clean_cache.setdefault(name, system.simulate())
    record = noisy_record(system, setting, seed, clean)
    kw = {"method": "parametric", "basis": zoo.basis_option(system)} if method == "parametric" else {"method": method}
    row = {"key": "|".join(map(str, job)), "system": name, "method": method, "setting": setting, "seed": seed}
    t0 = time.perf_counter()
    try:
        model = cc.CharacteristicCurves.from_method(family=system.family, random_state=seed, threads=1,
                                                    objective="equation-error", **kw).fit(record).model_
    except Exception as exc:  # a failure of the library is a result too
        row["error"] = f"{type(exc).__name__}: {str(exc)[:200]}"
        return row
    row["fit_seconds"] = time.perf_counter() - t0
    truth, args = system.truth(), _all_arguments(system, clean)
    row["inside"], row["half_width"] = {}, {}
    for slot in system.scored:
        lo, hi = float(args[slot].min()), float(args[slot].max())
        z = np.linspace(lo, hi, 200)
        try:
            _, blo, bhi = model.curve_band(slot, z, level=LEVEL)
        except cc.ConfigError as exc:
            row["error"] = f"ConfigError: {str(exc)[:200]}"
            return row
        f = truth[slot](z)
        row["inside"][slot] = float(np.mean((f >= blo) & (f <= bhi)))
        row["half_width"][slot] = float(np.mean((bhi - blo) / 2) / np.std(f))
    return row


def load_rows(path=RESULTS) -> list[dict]:
    if not os.path.exists(path):
        return []
    with open(path, encoding="utf-8") as fh:
        return [json.loads(line) for line in fh if line.strip()]


def table(rows) -> str:
    """Per setting and method: the mean share of the grid inside the 95 % band over every report-half
    curve and seed, the share of fits whose band holds at least 90 % of the grid, the median half-width."""
    out = ["| setting | method | grid inside 95 % band (mean) | fits with >= 0.9 of the grid inside | "
           "half-width / sd(truth) (median) | curves x seeds | seeds | errors |", "|---|---|---|---|---|---|---|---|"]
    for setting in SETTINGS:
        for method in METHODS:
            sel = [r for r in rows if r["setting"] == setting and r["method"] == method]
            good = [r for r in sel if "inside" in r and "error" not in r]
            inside = [v for r in good for v in r["inside"].values()]
            width = [v for r in good for v in r["half_width"].values()]
            if not sel:
                continue
            seeds = len({r["seed"] for r in sel})
            out.append(f"| {setting} | {method} | {np.mean(inside):.3f} | {np.mean(np.array(inside) >= 0.9):.2f} | "
                       f"{np.median(width):.3g} | {len(inside)} | {seeds} | {len(sel) - len(good)} |"
                       if inside else f"| {setting} | {method} | – | – | – | 0 | {seeds} | {len(sel)} |")
    return "\n".join(out)


def per_curve(rows) -> str:
    """Mean share inside per (setting, method, system, slot): where the bands fail."""
    keys = sorted({(r["setting"], r["method"], r["system"], s) for r in rows if "inside" in r for s in r["inside"]})
    out = ["| setting | method | system | curve | grid inside (mean) | seeds |", "|---|---|---|---|---|---|"]
    for st, m, sy, s in keys:
        v = [r["inside"][s] for r in rows if (r["setting"], r["method"], r["system"]) == (st, m, sy) and "inside" in r]
        out.append(f"| {st} | {m} | {sy} | {s} | {np.mean(v):.3f} | {len(v)} |")
    return "\n".join(out)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", default="0-4", help="e.g. 0-9")
    p.add_argument("--report-only", action="store_true")
    p.add_argument("--per-curve", action="store_true")
    a = p.parse_args(argv)
    lo, _, hi = a.seeds.partition("-")
    seeds = range(int(lo), int(hi or lo) + 1)
    if not a.report_only:
        import torch

        torch.set_num_threads(1)
        os.makedirs(os.path.dirname(RESULTS), exist_ok=True)
        done = {r["key"] for r in load_rows()}
        cache: dict = {}
        for job in jobs(seeds):
            if "|".join(map(str, job)) in done:
                continue
            row = run_job(job, cache)
            with open(RESULTS, "a", encoding="utf-8") as fh:
                fh.write(json.dumps(row) + "\n")
            print(json.dumps(row), flush=True)
    rows = load_rows()
    print(table(rows))
    if a.per_curve:
        print(per_curve(rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
