"""Several records in one fit: the cost against one record of the same length, and the Duffing target.

Speed (``--speed``): the separable fast paths -- batched networks (NN-CC+sym, equation error) and
linear least squares (parametric, equation error) -- on one Duffing record of N samples (its own
derivative columns) against its three thirds fitted together (the same samples, so the ratio is the
cost of the bookkeeping: per-record residual tests and free runs); the median of ``--repeat`` runs each, in
one process, the ratio printed with the load average (absolute times hold on this machine only).

Accuracy (``--duffing``): the paper's Duffing at forcing amplitudes 0.5x, 1x and 1.5x of A = 0.5,
one record each (1000 samples, t = 0..40, noise on x at ``--snr`` dB, seeds ``--seeds``). Fitted:
the default method on the three records together (the joint fit), the parametric fit (f1 = z;
f2 = z, z^3) on the three records pooled the same way, and the default method on each record
alone. Each curve's RMSE against the truth over the union of the records' ranges; and, per record,
over the part of the union outside that record's range, for the fit of that record alone and for
the joint fit.

    python benchmarks/bench_records.py --speed [--n 3000] [--repeat 3]
    python benchmarks/bench_records.py --duffing [--seeds 0,1,2] [--snr 30] [--json benchmarks/results/records/duffing.json]
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np

import charcurves as cc
from charcurves.systems import get_system

PARAM = dict(method="parametric", basis="f1=z; f2=z, z**3")
AMPLITUDES = (0.25, 0.5, 0.75)  # 0.5x, 1x, 1.5x of the paper's A = 0.5


def _timed(est, data, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        est.fit(data)
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def speed(n: int, repeat: int) -> dict:
    system = get_system("duffing")
    dt = 0.04
    one = system.simulate(t_end=(n - 1) * dt, n_points=n)
    m = n // 3
    three = [one.slice(slice(k * m, (k + 1) * m)) for k in range(3)]  # the same samples, cut in three
    out = {"n": n, "repeat": repeat, "load_average_before": os.getloadavg()}
    for label, kw in (("linear least squares (parametric)", dict(**PARAM, objective="equation-error")),
                      ("batched networks (nn-cc+sym)", dict(method="nn-cc+sym", objective="equation-error",
                                                            threads=1))):
        est = cc.CharacteristicCurves.from_method(**kw)
        est.fit(one)  # warm-up (imports, first torch call)
        t1 = _timed(est, one, repeat)
        t3 = _timed(est, three, repeat)
        out[label] = {"one_record_s": t1, "three_records_s": t3, "ratio": t3 / t1}
    out["load_average_after"] = os.getloadavg()
    return out


def _grid(lo: float, hi: float, n: int = 400) -> np.ndarray:
    return np.linspace(lo, hi, n)


def _rmse_on(curve, truth, z) -> float | None:
    if z.size == 0:
        return None
    d = np.asarray(curve(z), dtype=float) - np.asarray(truth(z), dtype=float)
    return float(np.sqrt(np.mean(d * d)))


def _outside(z_union: np.ndarray, lo: float, hi: float) -> np.ndarray:
    return z_union[(z_union < lo) | (z_union > hi)]


def duffing(seeds, snr: float) -> dict:
    base = get_system("duffing")
    truth = base.true_curves()
    runs = []
    for seed in seeds:
        records = []
        for k, A in enumerate(AMPLITUDES):
            system = get_system("duffing", A=A)
            records.append(cc.corrupt(system.simulate(), snr, on="state", seed=1000 * seed + k))
        t0 = time.perf_counter()
        joint = cc.CharacteristicCurves(random_state=seed, threads=1).fit(records).model_
        t_joint = time.perf_counter() - t0
        pooled = cc.CharacteristicCurves.from_method(**PARAM, random_state=seed).fit(records).model_
        alone = [cc.CharacteristicCurves(random_state=seed, threads=1).fit(r).model_ for r in records]
        run: dict = {"seed": seed, "joint_seconds": t_joint, "curves": {}}
        for name in ("f1", "f2"):
            lo = min(m.curves[name].domain[0] for m in alone)
            hi = max(m.curves[name].domain[1] for m in alone)
            z = _grid(lo, hi)
            entry = {"union": [lo, hi], "joint_domain": list(joint.curves[name].domain),
                     "joint_rmse": _rmse_on(joint.curves[name], truth[name], z),
                     "parametric_pooled_rmse": _rmse_on(pooled.curves[name], truth[name], z), "outside": []}
            entry["ratio_to_parametric"] = entry["joint_rmse"] / entry["parametric_pooled_rmse"]
            for k, m in enumerate(alone):
                rlo, rhi = m.curves[name].domain
                zo = _outside(z, rlo, rhi)
                entry["outside"].append({"record": k, "A": AMPLITUDES[k], "range": [rlo, rhi],
                                         "points": int(zo.size),
                                         "alone_rmse": _rmse_on(m.curves[name], truth[name], zo),
                                         "joint_rmse": _rmse_on(joint.curves[name], truth[name], zo)})
            run["curves"][name] = entry
        run["records"] = joint.info["records"]
        runs.append(run)
        print(json.dumps(_brief(run)), flush=True)
    return {"snr_db_on_x": snr, "amplitudes": list(AMPLITUDES), "seeds": list(seeds), "runs": runs,
            "load_average": os.getloadavg()}


def _brief(run: dict) -> dict:
    out = {"seed": run["seed"]}
    for name, e in run["curves"].items():
        out[name] = {"joint": round(e["joint_rmse"], 5), "param": round(e["parametric_pooled_rmse"], 5),
                     "ratio": round(e["ratio_to_parametric"], 3),
                     "outside alone/joint": [(None if o["alone_rmse"] is None else round(o["alone_rmse"], 4),
                                              None if o["joint_rmse"] is None else round(o["joint_rmse"], 4))
                                             for o in e["outside"]]}
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--speed", action="store_true")
    p.add_argument("--duffing", action="store_true")
    p.add_argument("--n", type=int, default=3000)
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--seeds", default="0,1,2")
    p.add_argument("--snr", type=float, default=30.0)
    p.add_argument("--json", default=None)
    a = p.parse_args()
    doc = {}
    if a.speed:
        doc["speed"] = speed(a.n, a.repeat)
        print(json.dumps(doc["speed"], indent=1), flush=True)
    if a.duffing:
        doc["duffing"] = duffing([int(s) for s in a.seeds.split(",")], a.snr)
    if a.json:
        os.makedirs(os.path.dirname(a.json) or ".", exist_ok=True)
        with open(a.json, "w", encoding="utf-8") as fh:
            json.dump(doc, fh, indent=1)


if __name__ == "__main__":
    main()
