"""Throughput of a 100-model NN-CC sweep (10 SNR levels x 10 noise realisations) and peak memory.

charcurves trains the 100 models as one batched computation (``CharacteristicCurves.fit_many``);
the baseline is the paper's protocol run one fit after another, timed on a prefix of epochs of
one fit (--paper-epochs) and scaled to 20 000 epochs x 100 fits, in the same run. Peak memory is
read from the process's resource usage (ru_maxrss) in fresh subprocesses: one single fit and the
100-model batch.

    python benchmarks/bench_batch.py [--paper-epochs 1000] [--method nn-cc]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys


_CHILD = r"""
import json, resource, sys, time, numpy as np, torch
torch.set_num_threads(1)
import charcurves as cc
from charcurves.data import corrupt
from charcurves.systems import get_system
n, method = int(sys.argv[1]), sys.argv[2]
system = get_system("duffing"); clean = system.simulate(); truth = system.true_curves()
snrs = np.linspace(40, -5, 10) if n > 1 else np.array([20.0])
trajs, seeds = [], []
for i, snr in enumerate(snrs):
    for r in range(max(1, n // len(snrs))):
        trajs.append(corrupt(clean, float(snr), seed=1000 * i + r)); seeds.append(1000 * i + r)
t0 = time.perf_counter()
models = cc.CharacteristicCurves.from_method(method=method, threads=1).fit_many(trajs, seeds=seeds)
sec = time.perf_counter() - t0
errs = [cc.curve_errors(m, truth) for m in models]
at20 = [e for e, s in zip(errs, np.repeat(snrs, max(1, n // len(snrs)))) if abs(s - 20) < 3]
print(json.dumps({"n": len(models), "seconds": sec, "maxrss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                  "rmse_f1_near_20db": float(np.mean([e["f1"] for e in at20])) if at20 else None}))
"""


def child(n: int, method: str) -> dict:
    r = subprocess.run([sys.executable, "-c", _CHILD, str(n), method], capture_output=True, text=True,
                       env={"OMP_NUM_THREADS": "1", "PATH": "/usr/bin:/bin"})
    if r.returncode != 0:
        raise RuntimeError(r.stderr)
    return json.loads(r.stdout.strip().splitlines()[-1])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--paper-epochs", type=int, default=1000)
    ap.add_argument("--method", default="nn-cc")
    args = ap.parse_args()
    sys.path.insert(0, __file__.rsplit("/", 1)[0])
    import torch

    torch.set_num_threads(1)
    from bench_nncc import paper_protocol

    from charcurves.data import corrupt
    from charcurves.systems import get_system

    noisy = corrupt(get_system("duffing").simulate(), 20.0, seed=0)
    sec, *_ = paper_protocol(noisy, args.method.endswith("+sym"), args.paper_epochs)
    paper_per_fit = sec * 20000 / args.paper_epochs
    single = child(1, args.method)
    batch = child(100, args.method)
    print(f"paper protocol, one fit (scaled from {args.paper_epochs} epochs): {paper_per_fit:8.1f} s"
          f" -> 100 fits one by one: {100 * paper_per_fit / 3600:.2f} h")
    print(f"charcurves {args.method}, single fit:   {single['seconds']:8.2f} s, peak memory {single['maxrss_mb']:.0f} MiB")
    print(f"charcurves {args.method}, 100-model batch: {batch['seconds']:8.2f} s "
          f"({batch['seconds'] / batch['n']:.3f} s per model), peak memory {batch['maxrss_mb']:.0f} MiB")
    print(f"throughput ratio (paper one by one / our batch): {100 * paper_per_fit / batch['seconds']:.0f}x")
    print(f"mean RMSE[f1] of the batch's models near 20 dB: {batch['rmse_f1_near_20db']:.2e}")


if __name__ == "__main__":
    main()
