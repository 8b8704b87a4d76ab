"""Coverage of the predictive band of free runs (charcurves.simulate.predictive_band, what
``charcurves validate`` reports): Duffing fits by equation error with a free gain on the training
record (1000 samples over 40 s; 20 dB on F with the derivatives given, or 40 dB on x only with
Savitzky-Golay derivatives), validated on a 10 s record (251 samples, 40 dB on x, clean F) started
from the true initial state; the share of the validation record inside the 95 % band, per seed.
Writes ``benchmarks/results/coverage/predictive.json``.

Run: ``python benchmarks/bench_predictive.py [--seeds 5]``.
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results", "coverage", "predictive.json")
SETTINGS = {"force": (20.0, "force", {}), "state": (40.0, "state", {"differentiator": "savgol"})}
METHODS = {"parametric": {"basis": "f1=z; f2=z, z**3"}, "poly-cc": {}}


def main(argv=None) -> int:
    import charcurves as cc
    from charcurves.simulate import predictive_band
    from charcurves.systems import get_system

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=5)
    a = p.parse_args(argv)
    system = get_system("duffing")
    clean, short = system.simulate(), system.simulate(t_end=10.0, n_points=251)
    rows = []
    for setting, (snr, on, extra) in SETTINGS.items():
        for method, kw in METHODS.items():
            for seed in range(a.seeds):
                rec = cc.corrupt(clean, snr, on=on, seed=seed)
                val = cc.corrupt(short, 40.0, on="state", seed=100 + seed)
                model = cc.CharacteristicCurves.from_method(method=method, objective="equation-error", free_gain=True,
                                                            random_state=seed, threads=1, **kw, **extra).fit(rec).model_
                t0 = time.perf_counter()
                band = predictive_band(model, val, system.x0, system.v0, substeps=4)
                row = {"setting": setting, "method": method, "seed": seed, "inside": band["inside"],
                       "diverged": band["diverged"], "noise_sd": band["noise_sd"],
                       "half_width_mean": float(np.mean(band["hi"] - band["lo"]) / 2),
                       "seconds": time.perf_counter() - t0}
                rows.append(row)
                print(json.dumps(row), flush=True)
    os.makedirs(os.path.dirname(OUT), exist_ok=True)
    with open(OUT, "w", encoding="utf-8") as fh:
        json.dump(rows, fh, indent=1)
    for setting in SETTINGS:
        for method in METHODS:
            v = [r["inside"] for r in rows if r["setting"] == setting and r["method"] == method]
            print(f"| {setting} | {method} | {np.mean(v):.3f} | {min(v):.3f} | {len(v)} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
