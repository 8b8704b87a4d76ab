"""The self-check's residual tests (issue 46, item 5): their false-alarm rate on well-specified fits
and their detection rate on misspecified ones, over seeds.

Well specified (a flag is a false alarm): the parametric fit on the true basis of Duffing (20 dB on F,
derivatives given; and 40 dB and 30 dB on x only, derivatives estimated), of a drag system
x'' + 0.2 x' + 0.15 x'|x'| + 1.5 tanh(2 x) = 2 cos(t) and of an asymmetric spring
x'' + 0.3 x' + 4 x + 1.5 x^2 = 2 cos(1.3 t) (poly-cc, no prior). Misspecified (a flag is a detection):
a cubic basis for the drag, the Duffing basis (parametric without --basis) on the drag system, and an
odd prior on the asymmetric spring (poly-cc, f2 odd). Each fit also reports the loss over the noise
floor, the figure the self-check had before the residual tests (flagged above 10). The tests run at
the self-check's level (RESIDUAL_LEVEL per fit, Bonferroni over its tests); the share flagged at 1 %
is recomputed from the p-values.

    PYTHONPATH=src OMP_NUM_THREADS=1 python benchmarks/bench_self_check.py [--seeds 20] [--out FILE]

prints one row per case (the share of seeds flagged, by any residual test and by the binned test; the
median loss over floor) and writes the rows to benchmarks/results/self_check.json.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time

import numpy as np


def _drag_f1(v):
    return 0.2 * v + 0.15 * v * np.abs(v)


def _drag_f2(x):
    return 1.5 * np.tanh(2.0 * x)


def _asym_f1(v):
    return 0.3 * v


def _asym_f2(x):
    return 4.0 * x + 1.5 * x ** 2


SYSTEMS = {"drag": (_drag_f1, _drag_f2, 2.0, 1.0), "asym": (_asym_f1, _asym_f2, 2.0, 1.3)}


def simulate(name: str, t_end: float = 60.0, n: int = 1500):
    """x'' + f1(x') + f2(x) = A cos(W t) from x = 0.5, x' = -0.5, with exact derivative columns."""
    from scipy.integrate import solve_ivp

    from charcurves.data import Trajectory

    f1, f2, A, W = SYSTEMS[name]
    t = np.linspace(0.0, t_end, n)

    def rhs(s, y):
        return [y[1], A * math.cos(W * s) - f1(y[1]) - f2(y[0])]

    sol = solve_ivp(rhs, (0.0, t_end), [0.5, -0.5], t_eval=t, rtol=1e-10, atol=1e-12)
    x, v = sol.y
    F = A * np.cos(W * t)
    return Trajectory(t=t, x=x, F=F, v=v, a=F - f1(v) - f2(x), name=name)


# case: (record, noise ("force" dB or "state" dB), method, fit keywords, well specified?)
CASES = [
    ("duffing, true basis, 20 dB on F", "duffing", ("force", 20.0), "parametric", {}, True),
    ("duffing, true basis, 40 dB on x", "duffing", ("state", 40.0), "parametric", {}, True),
    ("duffing, true basis, 30 dB on x", "duffing", ("state", 30.0), "parametric", {}, True),
    ("drag, true basis, 20 dB on F", "drag", ("force", 20.0), "parametric",
     {"basis": "f1=z, z*Abs(z); f2=tanh(2*z)"}, True),
    ("asymmetric spring, poly-cc no prior, 20 dB on F", "asym", ("force", 20.0), "poly-cc", {"symmetry": "none"}, True),
    ("drag, cubic basis for f1, 20 dB on F", "drag", ("force", 20.0), "parametric",
     {"basis": "f1=z, z**3; f2=tanh(2*z)"}, False),
    ("drag, Duffing basis, 20 dB on F", "drag", ("force", 20.0), "parametric", {"basis": "f1=z; f2=z, z**3"}, False),
    ("asymmetric spring, odd prior on f2, 20 dB on F", "asym", ("force", 20.0), "poly-cc",
     {"symmetry": {"f1": "none", "f2": "odd"}}, False),
    ("drag, cubic basis for f1, 40 dB on x", "drag", ("state", 40.0), "parametric",
     {"basis": "f1=z, z**3; f2=tanh(2*z)"}, False),
    ("drag, Duffing basis, 40 dB on x", "drag", ("state", 40.0), "parametric", {"basis": "f1=z; f2=z, z**3"}, False),
    ("asymmetric spring, odd prior on f2, 40 dB on x", "asym", ("state", 40.0), "poly-cc",
     {"symmetry": {"f1": "none", "f2": "odd"}}, False),
]


def run_case(label, system, noise, method, kw, seeds):
    from charcurves.data import corrupt
    from charcurves.fitting import CharacteristicCurves
    from charcurves.systems import get_system

    clean = get_system("duffing").simulate() if system == "duffing" else simulate(system)
    flagged, binned, ratios, seconds, failed, pvalues = [], [], [], [], {}, []
    for seed in range(seeds):
        rec = corrupt(clean, noise[1], on=noise[0], seed=seed)
        started = time.perf_counter()
        model = CharacteristicCurves.from_method(method=method, threads=1, random_state=seed, **kw).fit(rec).model_
        seconds.append(time.perf_counter() - started)
        check = model.info["self_check"]
        tests = check["residual_tests"]["tests"]
        pvalues.append({(t["test"] + (f" {t['curve']}" if "curve" in t else "")): t["p_value"] for t in tests})
        bad = [t for t in tests if not t["passed"]]
        flagged.append(bool(bad))
        binned.append(any(t["test"] == "binned" for t in bad))
        for t in bad:
            key = t["test"] + (f" {t['curve']}" if "curve" in t else "")
            failed[key] = failed.get(key, 0) + 1
        ratios.append(float(max(check["loss_over_floor"])))
    return {"case": label, "well_specified": kw_ok(label), "seeds": seeds, "flagged": float(np.mean(flagged)),
            "flagged_binned": float(np.mean(binned)), "failed_tests": failed,
            "median_loss_over_floor": float(np.median(ratios)), "max_loss_over_floor": float(np.max(ratios)),
            "loss_check_flagged": float(np.mean([r > 10.0 for r in ratios])),
            "flagged_at_1pct": float(np.mean([any(p < 0.01 / len(s) for p in s.values()) for s in pvalues])),
            "self_check_flagged": float(np.mean([f or r > 10.0 for f, r in zip(flagged, ratios)])),
            "median_fit_seconds": float(np.median(seconds)), "loss_over_floor": ratios, "p_values": pvalues}


def kw_ok(label: str) -> bool:
    return next(c[5] for c in CASES if c[0] == label)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "results", "self_check.json"))
    ap.add_argument("--only", default=None, help="run the cases whose label contains this text")
    args = ap.parse_args(argv)
    rows = []
    for label, system, noise, method, kw, _ in CASES:
        if args.only and args.only not in label:
            continue
        row = run_case(label, system, noise, method, kw, args.seeds)
        rows.append(row)
        kind = "false alarms" if row["well_specified"] else "detections "
        print(f"{label:50s} {kind} {row['flagged']:4.0%} (binned {row['flagged_binned']:4.0%}, at 1 % "
              f"{row['flagged_at_1pct']:4.0%}); with the loss check {row['self_check_flagged']:4.0%}; loss/floor "
              f"median {row['median_loss_over_floor']:.3g}; failed {row['failed_tests']}", flush=True)
    from charcurves.fitting import RESIDUAL_LEVEL

    doc = {"level": RESIDUAL_LEVEL, "seeds": args.seeds, "rows": rows}
    if not args.only:
        with open(args.out, "w", encoding="utf-8") as fh:
            json.dump(doc, fh, indent=1)
            fh.write("\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
