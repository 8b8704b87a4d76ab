"""The default parity test on the curve zoo: which prior a plain fit imposes, against each curve's truth.

A fit that asks for no method and no prior (``CharacteristicCurves()``, a plain ``charcurves fit``)
tests each curve's parity first (``charcurves.fitting.detect_symmetry`` with poly-cc curves by
equation error and a residual bootstrap of 8 members) and imposes only what the record supports.
This benchmark runs that test on every system of the curve zoo (``benchmarks/zoo.py``), in the
zoo's noise settings (``F25``: 25 dB on F, derivatives given; ``x30``: 30 dB on x only,
derivatives estimated), for several noise seeds, with each bootstrap block rule of ``--blocks``
in the same run (``1``: one sign per sample, the rule before the block bootstrap; ``auto``: the
residual's correlation length, ``charcurves.fitting.residual_block``). Every (curve, seed) gives
one decision, scored against the curve's true parity:

* **wrong prior**: a parity imposed that the truth does not have (the silent science issue 46 forbids);
* **missed**: none imposed on a curve that is odd (or even), the accuracy a prior would have bought;
* **right**: the truth's parity, or none on a curve that has none.

A curve whose argument's range is (nearly) one-sided is not testable: it is counted apart. The
zoo's two halves are reported apart (``tuning``: where a threshold may be chosen; ``report``).
Also ``--pooled``: the Duffing of ``bench_records.py`` at three forcing amplitudes, one test of
the three records together, per seed. Prints a table; ``--json`` writes every decision.

    python benchmarks/bench_parity.py --seeds 0-9 --pooled --json benchmarks/results/parity/zoo.json
    python benchmarks/bench_parity.py --rescore benchmarks/results/parity/zoo.json   # the threshold sweep
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
import warnings

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import numpy as np  # noqa: E402

import zoo  # noqa: E402
from bench_zoo import SETTINGS, noisy_record  # noqa: E402

#: the default fit's detector: poly-cc by equation error (charcurves.fitting._symmetry.DEFAULT_DETECTOR)
DETECTOR = {"method": "poly-cc", "objective": "equation-error"}
POOLED_AMPLITUDES = (0.25, 0.5, 0.75)


def _block(rule: str):
    return None if rule == "auto" else int(rule)


def _decide(record, rule: str, seed: int, family: str) -> dict[str, dict]:
    import charcurves as cc
    from charcurves.fitting import detect_symmetry

    est = cc.CharacteristicCurves(family=family, random_state=seed, threads=1)
    return detect_symmetry(record, estimator=est, random_state=seed, block=_block(rule), **DETECTOR)


def _score(truth: str, proposal: str, testable: bool) -> str:
    if not testable:
        return "untestable"
    if proposal == truth:
        return "right"
    if proposal != "none":
        return "wrong prior"
    return "missed"


def zoo_rows(seeds, settings, rules) -> list[dict]:
    rows = []
    for name, system in zoo.SYSTEMS.items():
        clean = system.simulate()
        for setting in settings:
            for seed in seeds:
                record = noisy_record(system, setting, seed, clean)
                for rule in rules:
                    t0 = time.process_time()
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore")
                        tests = _decide(record, rule, seed, system.family)
                    cpu = time.process_time() - t0
                    for slot, key in system.slots.items():
                        if slot not in tests:
                            continue
                        t = tests[slot]
                        truth = zoo.CURVES[key].parity
                        testable = t.get("odd_stat") is not None
                        rows.append({"system": name, "half": zoo.SYSTEM_HALF[name], "setting": setting, "seed": seed,
                                     "rule": rule, "slot": slot, "curve": key, "truth": truth,
                                     "proposal": t["proposal"], "odd_stat": t.get("odd_stat"),
                                     "even_stat": t.get("even_stat"), "outcome": _score(truth, t["proposal"], testable),
                                     "cpu_seconds": round(cpu, 3)})
                print(f"{name} {setting} seed {seed}: " + ", ".join(
                    f"{r['rule']}:{r['slot']}={r['proposal']}" for r in rows[-len(rules) * len(system.slots):]),
                    flush=True)
    return rows


def pooled_rows(seeds, rules, snr: float = 30.0) -> list[dict]:
    import charcurves as cc
    from charcurves.fitting import RecordSet
    from charcurves.systems import get_system

    rows = []
    for seed in seeds:
        records = [cc.corrupt(get_system("duffing", A=A).simulate(), snr, on="state", seed=1000 * seed + k)
                   for k, A in enumerate(POOLED_AMPLITUDES)]
        group = RecordSet(records)
        for rule in rules:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                tests = _decide(group, rule, seed, "separable")
            for slot in ("f1", "f2"):
                t = tests[slot]
                rows.append({"system": "duffing x3 records", "half": "-", "setting": f"x{snr:g}", "seed": seed,
                             "rule": rule, "slot": slot, "curve": slot, "truth": "odd", "proposal": t["proposal"],
                             "odd_stat": t.get("odd_stat"), "even_stat": t.get("even_stat"),
                             "outcome": _score("odd", t["proposal"], t.get("odd_stat") is not None)})
    return rows


def summary(rows) -> list[dict]:
    groups: dict = {}
    for r in rows:
        g = groups.setdefault((r["half"], r["setting"], r["rule"]), {"right": 0, "wrong prior": 0, "missed": 0,
                                                                    "untestable": 0, "odd_stats_of_odd": []})
        g[r["outcome"]] += 1
        if r["truth"] == "odd" and r["odd_stat"] is not None:
            g["odd_stats_of_odd"].append(r["odd_stat"])
    out = []
    for (half, setting, rule), g in sorted(groups.items()):
        tested = g["right"] + g["wrong prior"] + g["missed"]
        out.append({"half": half, "setting": setting, "rule": rule, "tested": tested, "right": g["right"],
                    "wrong_prior": g["wrong prior"], "missed": g["missed"], "untestable": g["untestable"],
                    "median_odd_stat_of_odd_curves": float(np.median(g["odd_stats_of_odd"]))
                    if g["odd_stats_of_odd"] else None})
    return out


#: thresholds of the odd/even statistic re-scored from the stored statistics (the fit's is 3)
SWEEP = (2.0, 2.5, 3.0, 3.5, 4.0)


def threshold_sweep(rows, thresholds=SWEEP) -> list[dict]:
    """The decisions the stored statistics give at other thresholds (a parity is proposed when its
    statistic is at most the threshold and the other's is not), per half and block rule."""
    out = []
    for half in sorted({r["half"] for r in rows}):
        for rule in sorted({r["rule"] for r in rows}):
            for th in thresholds:
                n = {"right": 0, "wrong prior": 0, "missed": 0}
                for r in rows:
                    if r["half"] != half or r["rule"] != rule or r["odd_stat"] is None:
                        continue
                    odd, even = r["odd_stat"] <= th, r["even_stat"] <= th
                    proposal = "odd" if odd and not even else "even" if even and not odd else "none"
                    n[_score(r["truth"], proposal, True)] += 1
                out.append({"half": half, "rule": rule, "threshold": th, "right": n["right"],
                            "wrong_prior": n["wrong prior"], "missed": n["missed"]})
    return out


def _print(summ) -> None:
    print("\n| half | setting | block rule | decisions | right | wrong prior | missed | untestable | "
          "median odd statistic, odd curves |")
    print("|---|---|---|---|---|---|---|---|---|")
    for s in summ:
        med = "-" if s["median_odd_stat_of_odd_curves"] is None else f"{s['median_odd_stat_of_odd_curves']:.2f}"
        print(f"| {s['half']} | {s['setting']} | {s['rule']} | {s['tested']} | {s['right']} | {s['wrong_prior']} | "
              f"{s['missed']} | {s['untestable']} | {med} |")


def _write(path: str, doc: dict) -> None:
    """The document with its summary indented and one decision per line."""
    head = json.dumps({k: v for k, v in doc.items() if k != "rows"}, indent=1)
    rows = ",\n".join(json.dumps(r) for r in doc.get("rows", []))
    with open(path, "w") as fh:
        fh.write(head[:-2] + ',\n "rows": [\n' + rows + "\n ]\n}\n")


def _seeds(text: str) -> list[int]:
    if "-" in text:
        a, b = text.split("-")
        return list(range(int(a), int(b) + 1))
    return [int(s) for s in text.split(",")]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", default="0-4", help="noise seeds: 0-9 or 0,3,5 (default %(default)s)")
    p.add_argument("--settings", default="F25,x30")
    p.add_argument("--blocks", default="1,auto", help="bootstrap block rules compared in this run")
    p.add_argument("--pooled", action="store_true", help="also the three-record Duffing of bench_records.py")
    p.add_argument("--no-zoo", action="store_true")
    p.add_argument("--json", default=None)
    p.add_argument("--rescore", default=None, metavar="FILE",
                   help="add the threshold sweep to a stored --json file (no fits) and print it")
    a = p.parse_args()
    if a.rescore:
        with open(a.rescore) as fh:
            doc = json.load(fh)
        doc["threshold_sweep"] = threshold_sweep(doc["rows"])
        for s in doc["threshold_sweep"]:
            print(s)
        _write(a.rescore, doc)
        return
    import torch

    torch.set_num_threads(1)
    seeds, rules = _seeds(a.seeds), a.blocks.split(",")
    settings = [s for s in a.settings.split(",") if s]
    for s in settings:
        if s not in SETTINGS:
            p.error(f"unknown setting {s!r}; choose from {', '.join(SETTINGS)}")
    t0 = time.time()
    rows = [] if a.no_zoo else zoo_rows(seeds, settings, rules)
    if a.pooled:
        rows += pooled_rows(seeds, rules)
    summ = summary(rows)
    _print(summ)
    print(f"\n{len(rows)} decisions in {time.time() - t0:.0f} s (load average {os.getloadavg()[0]:.1f})")
    if a.json:
        os.makedirs(os.path.dirname(a.json) or ".", exist_ok=True)
        _write(a.json, {"seeds": seeds, "settings": settings, "rules": rules, "detector": DETECTOR,
                        "load_average": os.getloadavg()[0], "summary": summ,
                        "threshold_sweep": threshold_sweep(rows), "rows": rows})


if __name__ == "__main__":
    main()
