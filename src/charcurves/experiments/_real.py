"""``charcurves benchmark --real NAME``: fit a real benchmark's estimation record and report the
free-run RMSE on each official test record after its initialisation window."""

from __future__ import annotations

import os
import time

import numpy as np

__all__ = ["run_real_benchmark"]


def run_real_benchmark(name: str, out_dir, *, data_dir=None, seed: int = 0, threads: int = 1,
                       max_samples: int | None = None, estimator=None, quiet: bool = True) -> dict:
    """Fit ``name``'s estimation record (default: the separable template with a free gain, the
    default method) and free-run the fitted model on each test record: the initial state fitted to
    the test's initialisation window, the RMSE counted after it (in the benchmark's unit, and as a
    percentage of the standard deviation of the counted output, the NRMSE many papers give). Writes ``real.json`` and ``real.md`` in ``out_dir`` and returns the document.

    ``max_samples`` keeps the first samples of every record only (a quick run; not the benchmark).

    Examples
    --------
    The example is not run here: it needs the Silverbox files (``data_dir``) and about a quarter
    of an hour.

    >>> sorted(run_real_benchmark("silverbox", "out/real", data_dir="data")["tests"])  # doctest: +SKIP
    ['arrow_full', 'arrow_no_extrapolation', 'multisine']
    """
    from ..datasets import get_benchmark
    from ..fitting import CharacteristicCurves
    from ..io import atomic_write_bytes, json_bytes, non_finite_paths
    from ..simulate import free_run_error

    data = get_benchmark(name, data_dir=data_dir)
    est_rec = data.estimation
    tests = dict(data.tests)
    if max_samples is not None:
        est_rec = est_rec.slice(slice(0, int(max_samples)))
        tests = {k: v.slice(slice(0, int(max_samples))) for k, v in tests.items()}
    est = estimator if estimator is not None else CharacteristicCurves.from_method(free_gain=True, random_state=seed,
                                                                       threads=threads)
    t0 = time.perf_counter()
    model = est.fit(est_rec).model_
    fit_seconds = time.perf_counter() - t0
    oe = model.info.get("output_error") or {}
    hold, substeps = oe.get("hold", "linear"), int(oe.get("substeps", 4))
    scale = {"mV": 1e3}.get(data.unit, 1.0)
    rows = {}
    for test_name, rec in tests.items():
        rmse, res = free_run_error(model, rec, hold=hold, substeps=substeps, init_window=data.init_window,
                                   time_budget=1800.0)
        std = float(np.std(np.asarray(rec.x)[data.init_window:]))
        rows[test_name] = {"rmse": rmse, f"rmse_{data.unit}": rmse * scale, "status": res.status,
                           "nrmse_percent": 100.0 * rmse / std if std > 0 else None,
                           "n_samples": rec.n_samples, "counted_samples": rec.n_samples - data.init_window,
                           "std_x": std}
    doc = {"benchmark": data.name, "source": os.path.basename(str(data.source)), "method": model.method,
           "template": model.template.equation, "estimation_samples": est_rec.n_samples,
           "init_window": data.init_window, "unit": data.unit, "hold": hold, "substeps": substeps,
           "quick": max_samples is not None, "seed": int(seed), "tests": rows,
           "objective": model.info.get("objective"), "gain": float(model.gain), "offset": float(model.offset),
           "fit_seconds": fit_seconds, "literature": data.literature}
    doc["non_finite"] = non_finite_paths(doc)
    os.makedirs(out_dir, exist_ok=True)
    atomic_write_bytes(os.path.join(out_dir, "real.json"), json_bytes(doc))
    model.save(os.path.join(out_dir, "model"))
    lines = [f"# {data.name}: {model.method} on {model.template.equation}", "",
             f"Free-run RMSE after the {data.init_window}-sample initialisation window (initial state fitted "
             f"to it), hold {hold}, {substeps} RK4 steps per sample" + ("; QUICK run (first samples only)"
                                                                         if doc["quick"] else ""), "",
             f"| test | samples | RMSE [{data.unit}] | NRMSE [% of std x] | status |", "|---|---|---|---|---|"]
    for test_name, r in rows.items():
        nrmse = "" if r["nrmse_percent"] is None else f"{r['nrmse_percent']:.3g}"
        lines.append(f"| {test_name} | {r['n_samples']} | {r[f'rmse_{data.unit}']:.4g} | {nrmse} | {r['status']} |")
    atomic_write_bytes(os.path.join(out_dir, "real.md"), ("\n".join(lines) + "\n").encode())
    return doc
