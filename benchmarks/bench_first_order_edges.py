"""Where the first-order family's f2 error sits at 40 dB noise on x (docs/measured-records.md).

The first-order system ``f1(x) + f2(x) x' = F`` of ``get_system("first-order")`` (1000 samples), Gaussian
noise of 40 dB on x only (``corrupt(..., on="state", seed=s)``, v and a dropped), noise seeds 0, 1, 2, the
default objective ("auto": equation error, then output error). Printed per fit: the normalised RMSE of
each curve (RMSE over the curve's range / std of the true curve there, as bench_state_noise.py) and that
of f2 in ten equal bins of the range, for nn-cc (the benchmark's method), nn-cc+sym with f2 even, poly-cc
and the parametric fit on the true basis (f1 = z, z^3; f2 = 1, z^2) refined by output error; and, once,
the record's samples per bin and the information it carries about f2 there: f2 enters multiplied by x',
so a change of f2 in a bin moves the equation by x' times that change, and the sum of x'^2 over the
bin's samples (relative to its mean over the bins) measures how well the record determines f2 there.

    python benchmarks/bench_first_order_edges.py [--seeds 0,1,2] [--quick]

``--quick``: nn-cc and the parametric fit only.
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def _per_bin(curve, truth, bins: int = 10):
    z = np.linspace(*curve.domain, 1000)
    t = truth(z)
    e = curve(z) - t
    sd = float(np.std(t))
    idx = np.clip(np.digitize(z, np.linspace(*curve.domain, bins + 1)) - 1, 0, bins - 1)
    per = [float(np.sqrt(np.mean(e[idx == b] ** 2)) / sd) for b in range(bins)]
    bias = [float(np.mean(e[idx == b]) / sd) for b in range(bins)]
    return float(np.sqrt(np.mean(e**2)) / sd), per, bias


def main(argv=None) -> int:
    import torch

    torch.set_num_threads(1)
    import charcurves as cc
    from charcurves.data import corrupt
    from charcurves.systems import get_system

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="0,1,2")
    parser.add_argument("--quick", action="store_true")
    a = parser.parse_args(argv)
    system = get_system("first-order")
    truth = system.true_curves()
    clean = system.simulate()
    x, v = np.asarray(clean.x), np.asarray(clean.v)
    edges = np.linspace(x.min(), x.max(), 11)
    idx = np.clip(np.digitize(x, edges) - 1, 0, 9)
    info = np.bincount(idx, weights=v**2, minlength=10)
    print("samples per bin of x:        ", np.bincount(idx, minlength=10).tolist())
    print("information on f2 per bin:   ", [round(float(i), 2) for i in info / info.mean()], "(sum of x'^2, / mean)")
    runs = [("nn-cc", {"method": "nn-cc"}),
            ("nn-cc+sym f1=odd,f2=even", {"method": "nn-cc+sym", "symmetry": "f1=odd,f2=even"}),
            ("poly-cc", {"method": "poly-cc"}),
            ("parametric, true basis", {"method": "parametric", "basis": "f1=z, z**3; f2=1, z**2"})]
    if a.quick:
        runs = [runs[0], runs[3]]
    for s in (int(v) for v in a.seeds.split(",")):
        record = corrupt(clean, 40.0, on="state", seed=s)
        for label, kw in runs:
            t0 = time.perf_counter()
            model = cc.CharacteristicCurves.from_method(family="first-order", random_state=s, threads=1, **kw).fit(record).model_
            f1, _, _ = _per_bin(model.curves["f1"], truth["f1"])
            f2, per, bias = _per_bin(model.curves["f2"], truth["f2"])
            print(f"seed {s} {label:<26} f1 {100 * f1:5.2f} %  f2 {100 * f2:5.2f} %  f2 per bin (%): "
                  f"{[round(100 * p, 2) for p in per]}  mean error per bin (%): {[round(100 * b, 2) for b in bias]}  "
                  f"{time.perf_counter() - t0:.0f} s", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
