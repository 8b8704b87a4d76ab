"""Measured records (noise on x only): every objective and differentiator against the limit and the peer.

For the paper's Duffing (and stick-slip) records with Gaussian noise on x only (no v, a columns;
``corrupt(..., on="state")``), 5 noise seeds per level, in one run:

* charcurves' methods with the default objective ("auto": equation error, then output error)
  and with equation error alone, nn-cc+sym also from each differentiator (spectral = auto,
  Kalman/RTS smoother, Savitzky-Golay 31/3 as the paper's appendix F);
* the limit: Parametric on the true basis refined by output error;
* the peer: PySINDy's weak form run as a practitioner would (benchmarks/peers.py).

Printed: mean worst-curve RMSE (max over f1, f2 of curve_errors, then the mean over the seeds),
the mean seconds of the whole fit, and for output error the seconds of the output-error stage
against the equation-error fit of the same record (target: at most 10x). Results go to
benchmarks/results/state_noise.json. Run: ``python benchmarks/bench_state_noise.py [--quick]``
(``--quick``: 2 seeds, Duffing only). The other families (position-damping, two-DOF,
first-order) at 40 dB follow, 3 seeds each, as normalised curve RMSE.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

METHODS = ("nn-cc+sym", "nn-cc", "poly-cc", "sindy-cc+sym")
DIFFERENTIATORS = ("spectral", "kalman", "savgol")


def _guarded(fn, *args, **kw):
    """``fn(*args, **kw)`` -> (result, seconds), or (the exception, seconds) when it fails."""
    t0 = time.perf_counter()
    try:
        out = fn(*args, **kw)
    except Exception as exc:  # noqa: BLE001 - recorded in the results, never hidden
        return exc, time.perf_counter() - t0
    return out, time.perf_counter() - t0


def _fit(record, method, objective, differentiator, seed):
    import charcurves as cc

    kw = {"differentiator": differentiator} if differentiator != "spectral" else {}
    if differentiator == "savgol":
        kw = {"differentiator": cc.SavitzkyGolay(window=31, order=3)}
    est = cc.CharacteristicCurves.from_method(method=method, objective=objective, random_state=seed, threads=1, **kw)
    t0 = time.perf_counter()
    model = est.fit(record).model_
    return model, time.perf_counter() - t0


def run_record(job):
    """All fits of one record: ``job = (system, snr, seed)`` -> list of result rows."""
    import torch

    torch.set_num_threads(1)
    from peers import TRUE_BASIS, fit_parametric_oe, fit_pysindy_weak

    from charcurves.data import corrupt
    from charcurves.metrics import curve_errors
    from charcurves.systems import get_system

    system_name, snr, seed = job
    system = get_system(system_name)
    truth = system.true_curves()
    record = corrupt(system.simulate(), snr, on="state", seed=seed)
    rows = []

    def add(label, objective, differentiator, model, seconds, **extra):
        if isinstance(model, Exception):  # a failure is a result too: recorded, and the run goes on
            rows.append({"system": system_name, "snr": snr, "seed": seed, "label": label, "objective": objective,
                         "differentiator": differentiator, "error": f"{type(model).__name__}: {model}"})
            return
        errs = curve_errors(model, truth)
        oe = model.info.get("output_error", {}) if hasattr(model, "info") else {}
        rows.append({"system": system_name, "snr": snr, "seed": seed, "label": label, "objective": objective,
                     "differentiator": differentiator, "f1": errs["f1"], "f2": errs["f2"],
                     "worst": max(errs.values()), "seconds": seconds, "oe_seconds": oe.get("seconds"),
                     "oe_status": oe.get("status"), **extra})

    methods = METHODS if system_name == "duffing" else ("nn-cc+sym",)
    for method in methods:
        diffs = DIFFERENTIATORS if method == "nn-cc+sym" else ("spectral",)
        for diff in diffs:
            res, secs = _guarded(_fit, record, method, "equation-error", diff, seed)
            ee, t_ee = res if isinstance(res, tuple) else (res, secs)
            add(method, "equation-error", diff, ee, t_ee)
            res, secs = _guarded(_fit, record, method, "auto", diff, seed)
            oe, t_oe = res if isinstance(res, tuple) else (res, secs)
            extra = {"ee_seconds": t_ee}
            if system_name == "stick-slip" and not isinstance(oe, Exception):
                extra["jump_height"] = oe.curves["f1"].components().get("jump_height")
            add(method, "auto", diff, oe, t_oe, **extra)
    limit, t_limit = _guarded(fit_parametric_oe, record, TRUE_BASIS[system_name], seed=seed)
    add("parametric (true basis) + output error: the limit", "output-error", "spectral", limit, t_limit)
    peer, t_peer = _guarded(fit_pysindy_weak, record, seed=seed)
    add("PySINDy weak form (the peer)", "weak form", "savgol (velocity state)", peer, t_peer)
    return rows


FAMILY_RUNS = (("van-der-pol", "nn-cc", {}), ("van-der-pol", "nn-cc+sym", {"symmetry": "f1=even,f2=odd"}),
               ("two-dof", "nn-cc", {}), ("first-order", "nn-cc", {}))


def _family_record(system, seed):
    from charcurves.data import MultiTrajectory, add_noise, corrupt

    if system.family == "two-dof":
        clean = system.simulate(t_end=50.0, n_points=1000)
        rng = np.random.default_rng(seed)
        return MultiTrajectory(clean.t, {k: add_noise(v, 40.0, rng, "std") for k, v in clean.states.items()},
                               clean.forces)
    return corrupt(system.simulate(), 40.0, on="state", seed=seed)


def run_family(job):
    """The other families at 40 dB noise on x: ``job = (system, method, options, seed)``; every curve's
    normalised RMSE (RMSE over the curve's range / std of the true curve there)."""
    import torch

    torch.set_num_threads(1)
    import charcurves as cc
    from charcurves.systems import get_system

    name, method, options, seed = job
    system = get_system(name)
    truth = system.true_curves()
    record = _family_record(system, seed)
    rows = []
    for objective in ("equation-error", "auto"):
        est = cc.CharacteristicCurves.from_method(family=system.family, method=method, objective=objective, random_state=seed,
                                      threads=1, **options)
        t0 = time.perf_counter()
        model = est.fit(record).model_
        seconds = time.perf_counter() - t0
        nrmse = {}
        for k, c in model.curves.items():
            z = np.linspace(*c.domain, 1000)
            t = truth[k](z)
            nrmse[k] = float(np.sqrt(np.mean((c(z) - t) ** 2)) / np.std(t))
        oe = model.info.get("output_error", {})
        rows.append({"system": name, "family": system.family, "method": method, "options": options, "seed": seed,
                     "objective": objective, "nrmse": nrmse, "worst": max(nrmse.values()), "seconds": seconds,
                     "oe_status": oe.get("status"), "oe_seconds": oe.get("seconds")})
    return rows


def summarise_families(rows) -> list[str]:
    import collections

    groups = collections.OrderedDict()
    for r in rows:
        groups.setdefault((r["system"], r["method"], json.dumps(r["options"]), r["objective"]), []).append(r)
    lines = [f"{'system':<12} {'method':<10} {'options':<32} {'objective':<15} {'worst nRMSE':>11}  per curve "
             "(mean over seeds)   s/fit  output error"]
    for (system, method, opts, obj), rs in groups.items():
        per = {k: np.mean([r["nrmse"][k] for r in rs]) for k in rs[0]["nrmse"]}
        status = rs[0]["oe_status"] or "-"
        lines.append(f"{system:<12} {method:<10} {opts:<32} {obj:<15} {np.mean([r['worst'] for r in rs]):>11.3g}  "
                     + " ".join(f"{k} {v:.3g}" for k, v in per.items())
                     + f"  {np.mean([r['seconds'] for r in rs]):6.1f}  {status[:60]}")
    return lines


def summarise(rows) -> list[str]:
    import collections

    groups = collections.OrderedDict()
    failed = [r for r in rows if "error" in r]
    for r in rows:
        if "error" not in r:
            groups.setdefault((r["system"], r["snr"], r["label"], r["objective"], r["differentiator"]), []).append(r)
    lines = [f"{'system':<10} {'SNR':>4}  {'method':<52} {'objective':<15} {'derivatives':<24} "
             f"{'worst RMSE':>10} {'f1':>9} {'f2':>9} {'s/fit':>6} {'OE/EE':>6}"]
    for (system, snr, label, obj, diff), rs in groups.items():
        worst = np.mean([r["worst"] for r in rs])
        ratio = ""
        if rs[0].get("ee_seconds") and rs[0].get("oe_seconds"):
            ratio = f"{np.mean([r['oe_seconds'] / r['ee_seconds'] for r in rs]):.1f}"
        lines.append(f"{system:<10} {snr:>4g}  {label:<52} {obj:<15} {diff:<24} {worst:>10.3g} "
                     f"{np.mean([r['f1'] for r in rs]):>9.3g} {np.mean([r['f2'] for r in rs]):>9.3g} "
                     f"{np.mean([r['seconds'] for r in rs]):>6.1f} {ratio:>6}")
    for r in failed:
        lines.append(f"FAILED {r['system']} {r['snr']:g} dB seed {r['seed']} {r['label']} {r['objective']}: {r['error']}")
    return lines


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="2 seeds, Duffing only")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--no-families", action="store_true", help="skip the other families")
    parser.add_argument("--out", default=os.path.join(HERE, "results", "state_noise.json"))
    a = parser.parse_args(argv)
    seeds = range(2) if a.quick else range(5)
    jobs = [("duffing", snr, s) for snr in (40.0, 30.0) for s in seeds]
    if not a.quick:
        jobs += [("stick-slip", 40.0, s) for s in seeds]
    family_jobs = [] if a.quick or a.no_families else [
        (name, method, opts, s) for name, method, opts in FAMILY_RUNS for s in range(3)]
    t0 = time.perf_counter()
    load = os.getloadavg()[0]
    if a.workers > 1:
        import multiprocessing as mp

        with mp.get_context("spawn").Pool(a.workers) as pool:
            results = pool.map(run_record, jobs, chunksize=1)
            fam_results = pool.map(run_family, family_jobs, chunksize=1)
    else:
        results = [run_record(j) for j in jobs]
        fam_results = [run_family(j) for j in family_jobs]
    rows = [r for rs in results for r in rs]
    fam_rows = [r for rs in fam_results for r in rs]
    lines = summarise(rows)
    if fam_rows:
        lines += ["", "other families, 40 dB noise on x, 3 noise seeds; normalised RMSE = RMSE / std of the true curve",
                  *summarise_families(fam_rows)]
    lines.append(f"mean over {len(seeds)} noise seeds per level; {len(jobs)} records, {a.workers} worker processes, "
                 f"{time.perf_counter() - t0:.0f} s; load average {load:.2f} at the start, {os.getloadavg()[0]:.2f} "
                 "at the end")
    print("\n".join(lines))
    os.makedirs(os.path.dirname(a.out), exist_ok=True)
    with open(a.out, "w") as fh:
        json.dump({"rows": rows, "family_rows": fam_rows, "summary": lines}, fh, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
