"""The GPU path: CPU-vs-CUDA agreement, and the paper's protocol batched over the full Duffing grid.

Run on a machine with a CUDA device (never needed by CI):

    python benchmarks/bench_gpu.py --check            # default preset, a few fits on cpu and cuda, compared
    python benchmarks/bench_gpu.py --grid full --preset paper --methods nn-cc,nn-cc+sym

The grid datasets are exactly the benchmark's (``Sweep(...).jobs()`` seeds: same noise, same
training seeds), fitted with ``CharacteristicCurves(device="cuda").fit_many`` in one batched pass
per method. Prints the wall time, the ensemble RMSE at 20 dB and the slope-1 A coefficients, and
writes a JSON summary (``--json``).
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np


def _datasets(snr, realizations, method, preset):
    from charcurves.data import corrupt
    from charcurves.experiments import Sweep
    from charcurves.systems import get_system

    sweep = Sweep(systems=("duffing",), methods=(method,), snr_db=snr, realizations=realizations, preset=preset)
    jobs = sweep.jobs()
    clean = get_system("duffing", "paper").simulate(jobs[0].t_end, jobs[0].n_points)
    trajs = [corrupt(clean, j.snr_db, on=j.noise_on, seed=j.noise_seed) for j in jobs]
    return jobs, trajs


def _errors(models):
    from charcurves import curve_errors
    from charcurves.systems import get_system

    truth = get_system("duffing", "paper").true_curves()
    return [curve_errors(m, truth) for m in models]


def check(device: str, n: int) -> dict:
    """Default preset on cpu and on the device: the same seeds give the same curves (float64)."""
    import charcurves as cc

    jobs, trajs = _datasets((20.0,), n, "nn-cc+sym", "default")
    seeds = [j.fit_seed for j in jobs]
    out = {}
    for dev in ("cpu", device):
        t0 = time.perf_counter()
        models = cc.CharacteristicCurves.from_method(method="nn-cc+sym", device=dev, threads=1).fit_many(trajs, seeds=seeds)
        out[dev] = {"seconds": time.perf_counter() - t0, "models": models}
    z = np.linspace(-1, 1, 201)
    diff = max(float(np.max(np.abs(a.curves[c](z) - b.curves[c](z))))
               for a, b in zip(out["cpu"]["models"], out[device]["models"]) for c in ("f1", "f2"))
    errs = {dev: _errors(out[dev]["models"]) for dev in out}
    res = {
        "n_models": n,
        "seconds": {dev: round(out[dev]["seconds"], 2) for dev in out},
        "max_abs_curve_difference_cpu_vs_device": diff,
        "mean_rmse": {dev: {c: float(np.mean([e[c] for e in errs[dev]])) for c in ("f1", "f2")} for dev in errs},
    }
    print(json.dumps(res, indent=1))
    return res


def grid(device: str, methods, preset: str, full: bool, realizations=None) -> dict:
    import charcurves as cc
    from charcurves.experiments import paper_grid
    from charcurves.metrics import ensemble_by_level, fit_slope_one

    snr = paper_grid()["snr_db"] if full else (40.0, 20.0, 0.0)
    reals = realizations if realizations is not None else (10 if full else 2)
    results = {}
    for method in methods:
        jobs, trajs = _datasets(snr, reals, method, preset)
        est = cc.CharacteristicCurves.from_method(method=method, preset=preset, device=device, threads=1)
        t0 = time.perf_counter()
        models = est.fit_many(trajs, seeds=[j.fit_seed for j in jobs])
        if device.startswith("cuda"):
            import torch

            torch.cuda.synchronize()
        seconds = time.perf_counter() - t0
        errs = _errors(models)
        snrs = np.array([j.snr_db for j in jobs])
        at20 = snrs == 20.0
        row = {"n_models": len(models), "seconds": round(seconds, 1),
               "rmse_20db": {c: float(np.sqrt(np.mean([e[c] ** 2 for e, k in zip(errs, at20) if k])))
                             for c in ("f1", "f2")}}
        eta = np.array([0.0 if math.isinf(s) else 10 ** (-s / 20) for s in snrs])
        for c in ("f1", "f2"):
            lv, ens, _ = ensemble_by_level(eta, [e[c] for e in errs])
            row[f"A_{c}"] = fit_slope_one(lv, ens)
        row["runs"] = [[j.snr_db, j.realization, e["f1"], e["f2"]] for j, e in zip(jobs, errs)]
        results[method] = row
        print(method, json.dumps({k: v for k, v in row.items() if k != "runs"}), flush=True)
    return results


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--device", default="cuda")
    ap.add_argument("--check", action="store_true", help="compare cpu and device fits (default preset)")
    ap.add_argument("--n-check", type=int, default=4)
    ap.add_argument("--grid", choices=["quick", "full"], default=None)
    ap.add_argument("--preset", default="paper")
    ap.add_argument("--methods", default="nn-cc,nn-cc+sym")
    ap.add_argument("--realizations", default=None, help="realisation indices, e.g. 0-4 (default: all of the grid)")
    ap.add_argument("--json", default=None, help="write the summary here")
    args = ap.parse_args()
    import torch

    print("torch", torch.__version__, "device", args.device,
          torch.cuda.get_device_name(0) if torch.cuda.is_available() else "(no cuda)", flush=True)
    summary = {}
    if args.check:
        summary["check"] = check(args.device, args.n_check)
    reals = None
    if args.realizations:
        lo, _, hi = args.realizations.partition("-")
        reals = list(range(int(lo), int(hi or lo) + 1))
    if args.grid:
        summary["grid"] = {"preset": args.preset, "full": args.grid == "full",
                           "results": grid(args.device, args.methods.split(","), args.preset, args.grid == "full",
                                               reals)}
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(summary, fh, indent=1)


if __name__ == "__main__":
    main()
