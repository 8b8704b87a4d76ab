"""The output-error gain's bias from the input's hold, on a nearly clean Duffing record.

The output-error rows of bench_coverage.py (40 dB on x only) have a gain error of about +0.0003
on average over 100 realisations, against a posterior sd of 0.0009. This script fits the same
record at 120 dB on x (noise seed 0), so that what is left is a bias of the model and not noise. It
uses each of the default ``"linear"`` hold of F between its samples and the ``"bandlimited"`` one.
The linear interpolant of a sampled sinusoid of frequency W has a fundamental smaller by the
factor ``sinc(W dt / 2)^2``, so the free gain grows by ``1 / sinc^2 - 1``; the script prints that
prediction beside the measured errors.

Results: benchmarks/results/coverage/hold_bias.json. Run: ``python benchmarks/bench_oe_hold.py``.
"""

from __future__ import annotations

import json
import os
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "results", "coverage", "hold_bias.json")
METHODS = {"parametric": {"basis": "f1=z; f2=z, z**3"}, "nn-cc": {}, "nn-cc+sym": {}}
HOLDS = ("linear", "bandlimited")
SNR = 120.0


def run() -> dict:
    import charcurves as cc
    from charcurves.systems import get_system

    system = get_system("duffing")
    clean = system.simulate()
    dt = float(clean.t[1] - clean.t[0])
    record = cc.corrupt(clean, SNR, on="state", seed=0)
    out = {"snr_db": SNR, "dt": dt, "omega": float(system.Omega),
           "predicted_linear": float(1.0 / np.sinc(system.Omega * dt / (2 * np.pi)) ** 2 - 1.0), "rows": []}
    for method, kw in METHODS.items():
        for hold in HOLDS:
            est = cc.CharacteristicCurves.from_method(method=method, objective=cc.OutputError(hold=hold), random_state=0,
                                                      threads=1, free_gain=True, **kw)
            t0 = time.perf_counter()
            model = est.fit(record).model_
            stats = model.posterior.scalar_stats()
            row = {"method": method, "hold": hold, "gain_error": float(model.gain - 1.0),
                   "gain_sd": float(stats["sd"]["gain"]), "seconds": time.perf_counter() - t0}
            out["rows"].append(row)
            print(json.dumps(row), flush=True)
    return out


def main() -> None:
    out = run()
    with open(OUT, "w", encoding="utf-8") as fh:
        json.dump(out, fh, indent=1)
        fh.write("\n")
    print(f"predicted by the linear hold: {out['predicted_linear']:+.3e}")


if __name__ == "__main__":
    main()
