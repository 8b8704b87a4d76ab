"""Differentiators on records with noise on x: derivative accuracy, and as equation-error methods.

On the paper's Duffing and stick-slip records (1000 samples on [0, 40]) with Gaussian noise on x
at each SNR (``corrupt(traj, snr, on="state", seed=s)``, seeds 0..N-1):

(a) relative RMSE of x' and x'' against the clean record (RMSE / std of the clean derivative),
    interior 90 % and whole record, and seconds per record, for every differentiator;
(b) each differentiator as the derivative estimate of an equation-error fit,
    ``CharacteristicCurves.from_method(method=..., differentiator=<differentiator>)`` for ``parametric`` (true
    basis), ``poly-cc`` and ``nn-cc+sym``: worst-curve RMSE (max over f1, f2 of
    ``curve_errors(model, system.true_curves())``);
(c) in the same run, the references: PySINDy's weak form run as a practitioner would (the peer,
    ``peers.fit_pysindy_weak``) and the parametric output-error fit on the true basis (the limit,
    ``peers.fit_parametric_oe``).

Every table states its statistic (mean over the seeds); timings are printed with the load
average. The figures go to ``benchmarks/results/differentiators.json``.

    OMP_NUM_THREADS=1 python benchmarks/bench_differentiators.py [--seeds 5] [--snr 40,30,20]
        [--systems duffing,stick-slip] [--methods parametric,poly-cc,nn-cc+sym]
        [--differentiators savgol,spline,...] [--objectives equation-error] [--workers 2]
        [--skip-fits] [--skip-references] [--out FILE]

To add an objective (e.g. output error) as one more column: extend :func:`fit_record`'s
``objective`` handling (one place) and pass ``--objectives equation-error,output-error``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from peers import TRUE_BASIS, fit_parametric_oe, fit_pysindy_weak  # noqa: E402

SYSTEMS = ("duffing", "stick-slip")
SNRS = (40.0, 30.0, 20.0)
METHODS = ("parametric", "poly-cc", "nn-cc+sym")
#: label -> (registry name, parameters); the labels are the table columns.
DIFFERENTIATORS: dict[str, tuple[str, dict[str, Any]]] = {
    "savgol 31/3": ("savgol", {}),
    "spline": ("spline", {}),
    "spectral": ("spectral", {}),
    "kalman": ("kalman", {}),
    "kalman-acc": ("kalman", {"model": "acceleration"}),
    "tvr": ("tvr", {}),
    "fd": ("fd", {}),
}
#: differentiators fitted in part (b) by default (fd's x'' is 5-60x std(x''): no fit survives it)
FIT_DIFFERENTIATORS = ("savgol 31/3", "spline", "spectral", "kalman", "kalman-acc", "tvr")
OBJECTIVES = ("equation-error",)


# ------------------------------------------------------------------ records and scores
def make_record(system_name: str, snr: float, seed: int):
    """``(clean, noisy)``: the paper's record of ``system_name`` and a copy with noise on x."""
    from charcurves.data import corrupt
    from charcurves.systems import get_system

    clean = get_system(system_name).simulate()
    return clean, corrupt(clean, snr, on="state", seed=seed)


def make_differentiator(label: str):
    """The differentiator instance behind a table label of :data:`DIFFERENTIATORS`."""
    from charcurves.data import make_differentiator as make

    name, params = DIFFERENTIATORS[label]
    return make(name, **params)


def _rel_rmse(err: np.ndarray, ref: np.ndarray, trim: float) -> float:
    k = int(trim * err.shape[0])
    return float(np.sqrt(np.mean(err[k:err.shape[0] - k] ** 2)) / np.std(ref))


def derivative_errors(clean, record, label: str) -> dict[str, float]:
    """Relative RMSE of x', x'' (interior 90 %, whole record) and the seconds taken."""
    diff = make_differentiator(label)
    t0 = time.perf_counter()
    _, v, a = diff(record.t, record.x)
    sec = time.perf_counter() - t0
    return {
        "v_interior": _rel_rmse(v - clean.v, clean.v, 0.05),
        "v_whole": _rel_rmse(v - clean.v, clean.v, 0.0),
        "a_interior": _rel_rmse(a - clean.a, clean.a, 0.05),
        "a_whole": _rel_rmse(a - clean.a, clean.a, 0.0),
        "seconds": sec,
    }


def _score(model, system_name: str) -> dict[str, float]:
    from charcurves.metrics import curve_errors
    from charcurves.systems import get_system

    err = curve_errors(model, get_system(system_name).true_curves())
    return {**{k: float(v) for k, v in err.items()}, "worst": float(max(err.values()))}


def fit_record(record, method: str, differentiator: str, objective: str | None = None, *,
               system_name: str, seed: int = 0) -> dict[str, float]:
    """One fit of ``record`` and its curve errors: the single place that builds the estimator.

    Parameters
    ----------
    record : Trajectory
        Noisy record without v, a.
    method : str
        ``parametric`` (with the system's true basis, :data:`peers.TRUE_BASIS`), ``poly-cc``,
        ``nn-cc+sym`` or any other method name.
    differentiator : str
        A label of :data:`DIFFERENTIATORS` (passed as ``differentiator=`` instance).
    objective : str or None
        ``None`` or ``"equation-error"``: today's fit. Any other value is handed to the estimator
        as ``objective=...`` (the output-error objective of issue 26, once it exists).
    system_name : str
        For the true basis and the true curves.

    Returns
    -------
    dict
        ``f1``, ``f2``, ``worst`` (RMSE against the true curves) and ``seconds``.
    """
    import charcurves as cc

    kw: dict[str, Any] = {}
    if method == "parametric":
        kw["basis"] = TRUE_BASIS[system_name]
    if objective not in (None, "equation-error"):
        kw["objective"] = objective
    est = cc.CharacteristicCurves.from_method(method=method, differentiator=make_differentiator(differentiator),
                                  random_state=seed, threads=1, **kw)
    t0 = time.perf_counter()
    model = est.fit(record).model_
    return {**_score(model, system_name), "seconds": time.perf_counter() - t0}


def reference_fits(record, system_name: str, seed: int = 0) -> dict[str, dict[str, float]]:
    """The peer (PySINDy weak form) and the limit (parametric output error) on ``record``."""
    out = {}
    t0 = time.perf_counter()
    peer = fit_pysindy_weak(record, seed=seed)
    out["pysindy-weak"] = {**_score(peer, system_name), "seconds": time.perf_counter() - t0,
                           "gain": float(peer.info["gain"])}
    t0 = time.perf_counter()
    limit = fit_parametric_oe(record, TRUE_BASIS[system_name], seed=seed)
    out["parametric-oe"] = {**_score(limit, system_name), "seconds": time.perf_counter() - t0}
    return out


# ------------------------------------------------------------------ one job = one record
def run_record(job: dict[str, Any]) -> dict[str, Any]:
    """Everything measured on one (system, SNR, seed) record."""
    import warnings

    warnings.simplefilter("ignore")
    import torch

    torch.set_num_threads(1)
    clean, record = make_record(job["system"], job["snr"], job["seed"])
    out: dict[str, Any] = {k: job[k] for k in ("system", "snr", "seed")}
    for lab in job["differentiators"]:  # warm-up: imports and first-call costs out of the timings
        make_differentiator(lab)(record.t[:200], record.x[:200])
    out["derivatives"] = {lab: derivative_errors(clean, record, lab) for lab in job["differentiators"]}
    out["fits"] = []
    for lab in job["fit_differentiators"]:
        for method in job["methods"]:
            for obj in job["objectives"]:
                try:
                    res = fit_record(record, method, lab, obj, system_name=job["system"], seed=job["seed"])
                except Exception as exc:  # a failed fit is a result too
                    res = {"error": f"{type(exc).__name__}: {exc}"}
                out["fits"].append({"differentiator": lab, "method": method, "objective": obj, **res})
    if job["references"]:
        out["references"] = reference_fits(record, job["system"], seed=job["seed"])
    return out


# ------------------------------------------------------------------ tables
def _mean(values: list[float]) -> float:
    vals = [v for v in values if v is not None and np.isfinite(v)]
    return float(np.mean(vals)) if vals else float("nan")


def summarise(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Means over seeds: derivative errors, worst-curve RMSE per fit, references."""
    summary: dict[str, Any] = {"derivatives": {}, "fits": {}, "references": {}}
    keys = sorted({(r["system"], r["snr"]) for r in rows}, key=lambda k: (k[0], -k[1]))
    for system, snr in keys:
        group = [r for r in rows if r["system"] == system and r["snr"] == snr]
        tag = f"{system} {snr:g} dB"
        summary["derivatives"][tag] = {
            lab: {m: _mean([g["derivatives"][lab][m] for g in group]) for m in group[0]["derivatives"][lab]}
            for lab in group[0]["derivatives"]
        }
        fits: dict[str, dict[str, float]] = {}
        for g in group:
            for f in g["fits"]:
                key = f"{f['method']} | {f['objective']} | {f['differentiator']}"
                fits.setdefault(key, []).append(f.get("worst", float("nan")))  # type: ignore[arg-type]
        summary["fits"][tag] = {k: {"worst_mean": _mean(v), "n": len(v),
                                    "failed": int(sum(not np.isfinite(x) for x in v))}
                                for k, v in fits.items()}
        if all("references" in g for g in group):
            summary["references"][tag] = {
                name: {"worst_mean": _mean([g["references"][name]["worst"] for g in group]),
                       "seconds_mean": _mean([g["references"][name]["seconds"] for g in group])}
                for name in group[0]["references"]
            }
    return summary


def print_tables(summary: dict[str, Any], n_seeds: int, load: tuple[float, float, float]) -> None:
    load_txt = f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}"
    tags = list(summary["derivatives"])
    if tags:
        labels = list(summary["derivatives"][tags[0]])
        print(f"\n(a) relative RMSE of x'' (RMSE / std x''), interior 90 % [whole record]; "
              f"mean over {n_seeds} noise seeds")
        print(f"{'record':<18}" + "".join(f"{lab:>18}" for lab in labels))
        for tag in tags:
            d = summary["derivatives"][tag]
            print(f"{tag:<18}" + "".join(f"{d[lab]['a_interior']:>9.3f} [{d[lab]['a_whole']:.3f}]" for lab in labels))
        print(f"\n(a) relative RMSE of x', interior 90 % [whole record]; mean over {n_seeds} seeds")
        for tag in tags:
            d = summary["derivatives"][tag]
            print(f"{tag:<18}" + "".join(f"{d[lab]['v_interior']:>9.3f} [{d[lab]['v_whole']:.3f}]" for lab in labels))
        print(f"\n(a) seconds per record (1000 samples), mean over {n_seeds} seeds; {load_txt}")
        for tag in tags:
            d = summary["derivatives"][tag]
            print(f"{tag:<18}" + "".join(f"{d[lab]['seconds']:>18.3f}" for lab in labels))
    if any(summary["fits"].values()):
        print(f"\n(b) worst-curve RMSE (max over f1, f2), mean over {n_seeds} noise seeds; "
              "rows: method | objective, columns: differentiator")
        for tag, fits in summary["fits"].items():
            rows = sorted({k.rsplit(" | ", 1)[0] for k in fits})
            cols = list(dict.fromkeys(k.rsplit(" | ", 1)[1] for k in fits))
            print(f"{tag:<34}" + "".join(f"{c:>13}" for c in cols))
            for r in rows:
                cells = []
                for c in cols:
                    f = fits.get(f"{r} | {c}")
                    cells.append(f"{f['worst_mean']:>13.2e}" if f else f"{'':>13}")
                print(f"  {r:<32}" + "".join(cells))
    if summary["references"]:
        print(f"\n(c) references, worst-curve RMSE, mean over {n_seeds} noise seeds (seconds per fit; {load_txt})")
        for tag, refs in summary["references"].items():
            print(f"{tag:<18}" + "".join(f"  {n}: {r['worst_mean']:.2e} ({r['seconds_mean']:.1f} s)" for n, r in refs.items()))


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--systems", default=",".join(SYSTEMS))
    ap.add_argument("--snr", default="40,30,20")
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--differentiators", default=",".join(DIFFERENTIATORS))
    ap.add_argument("--fit-differentiators", default=",".join(FIT_DIFFERENTIATORS))
    ap.add_argument("--objectives", default=",".join(OBJECTIVES))
    ap.add_argument("--skip-fits", action="store_true")
    ap.add_argument("--skip-references", action="store_true")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--out", default=str(Path(__file__).resolve().parent / "results" / "differentiators.json"))
    args = ap.parse_args(argv)
    split = lambda s: [p.strip() for p in s.split(",") if p.strip()]  # noqa: E731
    for lab in split(args.differentiators) + split(args.fit_differentiators):
        if lab not in DIFFERENTIATORS:
            ap.error(f"unknown differentiator label {lab!r}; choose from {', '.join(DIFFERENTIATORS)}")
    jobs = [
        {"system": s, "snr": float(snr), "seed": seed, "differentiators": split(args.differentiators),
         "fit_differentiators": [] if args.skip_fits else split(args.fit_differentiators),
         "methods": split(args.methods), "objectives": split(args.objectives),
         "references": not args.skip_references}
        for s in split(args.systems) for snr in split(args.snr) for seed in range(args.seeds)
    ]
    load0 = os.getloadavg()
    t0 = time.perf_counter()
    rows = []
    if args.workers > 1:
        with ProcessPoolExecutor(args.workers) as pool:
            for i, r in enumerate(pool.map(run_record, jobs)):
                rows.append(r)
                print(f"[{i + 1}/{len(jobs)}] {r['system']} {r['snr']:g} dB seed {r['seed']}", file=sys.stderr, flush=True)
    else:
        for i, job in enumerate(jobs):
            rows.append(run_record(job))
            print(f"[{i + 1}/{len(jobs)}] {job['system']} {job['snr']:g} dB seed {job['seed']}", file=sys.stderr, flush=True)
    wall = time.perf_counter() - t0
    load1 = os.getloadavg()
    summary = summarise(rows)
    print_tables(summary, args.seeds, load1)
    print(f"\nwall {wall:.0f} s with {args.workers} worker(s); load average at start {load0[0]:.2f}, at end {load1[0]:.2f}")
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    repo = Path(__file__).resolve().parents[1]
    shown = str(out.resolve().relative_to(repo)) if out.resolve().is_relative_to(repo) else str(out)  # no machine path
    payload = {"settings": {**vars(args), "out": shown, "statistic": f"mean over {args.seeds} noise seeds"},
               "load_average": {"start": load0, "end": load1}, "wall_seconds": wall, "cpu_count": os.cpu_count(),
               "summary": summary, "rows": rows}
    tmp = out.with_suffix(".tmp")
    tmp.write_text(json.dumps(payload, indent=1, default=float))
    os.replace(tmp, out)
    print(f"wrote {shown}")


if __name__ == "__main__":
    main()
