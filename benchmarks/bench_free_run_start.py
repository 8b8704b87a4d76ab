"""Where a hidden-state model's free run starts (issue 47, D2): the window length of the default start.

Fits the grey-box models of benchmarks/bench_greybox.py (seed 0, 4 starts, its settings: two-tank
start growing; two-DOF with x1 only, four curves and one coupling curve, start linear; Bouc-Wen
with the kink basis, degree 3, start growing) and scores, on the training and test records, the
free-run RMSE of every sample divided by the noise's own (the true model's) from several starts:
``first8`` (``start="first-samples"``, the former default), ``fitted`` (the fitted initial state),
``rest`` (zero, where the record starts at rest), ``default`` and ``N<k>`` (the whole state fitted
to the first k samples, :func:`~charcurves.fitting.estimate_window_state`; ``N<k>_cpu`` its CPU
seconds). Test records: two-tank, another input (seed 100) from rest and the same from sample 200
(both levels mid-run); two-DOF, seconds 60-120 of a 120 s run (other noise); Bouc-Wen, the
8192-sample multisine and sweep of bench_greybox.

Run: ``python benchmarks/bench_free_run_start.py --fit two-tank,bouc-wen-kink`` (models to
``--models DIR``), then ``--eval two-tank,bouc-wen-kink [--windows 8,16,32,50,100,128]``; rows go
to stdout and ``--out FILE`` (JSON lines).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

TWO_DOF = ("x1'' + f1(x1') + f2(x1 - x2) = F1; x2'' + f3(x2') + f4(x2 - x1) = F2",
           "x1'' + f1(x1') + f2(x1 - x2) = F1; x2'' + f3(x2') - f2(x1 - x2) = F2")


def _two_dof_record(t_end, n_points, start, seed):
    from charcurves.data import MultiTrajectory
    from charcurves.systems import TwoDOF

    clean = TwoDOF().simulate(t_end=60.0, n_points=1500)  # the training record's noise level (40 dB)
    sigma = np.sqrt(np.mean(np.asarray(clean.states["x1"]) ** 2)) / 100.0
    run = TwoDOF().simulate(t_end=t_end, n_points=n_points)
    x = np.asarray(run.states["x1"])[start:]
    noisy = x + np.random.default_rng(seed).normal(0.0, sigma, x.size)
    return MultiTrajectory(run.t[start:], {"x1": noisy}, {k: np.asarray(v)[start:] for k, v in run.forces.items()}), x


def fit(case: str, models: str) -> None:
    from charcurves.curves import Basis
    from charcurves.fitting import fit_state_space
    from charcurves.templates import StateSpace

    t0 = time.process_time()
    if case == "two-tank":
        from charcurves.systems import TwoTank

        rec = TwoTank().simulate(n_points=1000, t_end=1000.0, seed=0)
        template = StateSpace("x1' = g*F - f1(x1); x2' = f1(x1) - f2(x2)", measured={"x2": "x"})
        model = fit_state_space(template, rec, start="growing", n_starts=4, seed=0)
    elif case in ("two-dof-x1", "two-dof-x1-newton"):
        newton = case.endswith("newton")
        rec, _ = _two_dof_record(60.0, 1500, 0, 0)
        spring = ", ".join(["z"] + [f"z**{k}" for k in range(2, 11)])
        template = StateSpace(TWO_DOF[newton], measured={"x1": "x1"}, **({"f2": Basis(spring)} if newton else {}))
        model = fit_state_space(template, rec, start="linear", n_starts=4, seed=0)
    elif case == "bouc-wen-kink":
        from charcurves.systems import BoucWen

        system = BoucWen()
        rec = system.simulate(system.multisine(seed=0, period=1000), seed=0)
        kink = Basis("1, z, Abs(z), z**2, z*Abs(z), z**3")
        template = StateSpace("x1'' + f1(x1') + f2(x1) + x2 = g*F; x2' = f3(x2)*Abs(x1') + f4(x2)*x1'",
                              measured={"x1": "x"}, f3=kink, f4=kink)
        model = fit_state_space(template, rec, start="growing", n_starts=4, seed=0, degree=3, time_budget=200)
    else:
        raise SystemExit(f"unknown case {case!r}")
    model.save(os.path.join(models, case))
    print(case, "fit CPU s", round(time.process_time() - t0, 1), flush=True)


def records(case: str):
    """(name, record, clean measured signal, starts at rest) of a case."""
    if case == "bouc-wen-kink":
        from charcurves.systems import BoucWen

        s = BoucWen()
        u0 = s.multisine(seed=0, period=1000)
        yield "train", s.simulate(u0, seed=0), s.states(u0)["y"], True
        for name, u in (("multisine", s.multisine(seed=100, period=8192)), ("sweep", s.sweep(8192))):
            yield name, s.simulate(u, seed=7), s.states(u)["y"], True
    elif case == "two-tank":
        from charcurves.systems import TwoTank

        s = TwoTank()
        yield ("train", s.simulate(n_points=1000, t_end=1000.0, seed=0),
               s.states(n_points=1000, t_end=1000.0, seed=0)["x2"], True)
        rec, clean = s.simulate(n_points=1000, t_end=1000.0, seed=100), s.states(n_points=1000, t_end=1000.0, seed=100)
        yield "test", rec, clean["x2"], True
        yield "test[200:]", rec.slice(slice(200, 1000)), clean["x2"][200:], False
    else:
        yield ("train", *_two_dof_record(60.0, 1500, 0, 0), False)
        yield ("t60-120", *_two_dof_record(120.0, 3001, 1500, 1), False)


def evaluate(case: str, models: str, windows, out) -> None:
    from charcurves import load_model
    from charcurves.fitting import estimate_window_state

    model = load_model(os.path.join(models, case))
    state, column = next(iter(model.info["measured"].items()))
    for name, rec, clean, at_rest in records(case):
        x = np.asarray(rec.x if column == "x" else rec.states[column])
        noise = float(np.sqrt(np.mean((x - clean) ** 2)))
        row = {"case": case, "record": name, "n": len(x), "noise": noise,
               "first8": model.free_run_rmse(rec, start="first-samples")[state] / noise,
               "default": model.free_run_rmse(rec)[state] / noise,
               "fitted": model.free_run_rmse(rec, initial=model.initial_state)[state] / noise}
        if at_rest:
            row["rest"] = model.free_run_rmse(rec, initial=dict.fromkeys(model.initial_state, 0.0))[state] / noise
        for n in windows:
            t0 = time.process_time()
            start = estimate_window_state(model, rec, n)
            row[f"N{n}_cpu"] = round(time.process_time() - t0, 2)
            row[f"N{n}"] = model.free_run_rmse(rec, initial=start)[state] / noise
        line = json.dumps(row)
        print(line, flush=True)
        if out:
            with open(out, "a") as fh:
                fh.write(line + "\n")


def main(argv=None) -> int:
    import torch

    torch.set_num_threads(1)
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--fit", default=None, help="cases to fit: two-tank, two-dof-x1, two-dof-x1-newton, bouc-wen-kink")
    p.add_argument("--eval", default=None, help="cases to score (fitted before)")
    p.add_argument("--models", default="runs/free-run-start")
    p.add_argument("--windows", default="8,16,32,50,100,128")
    p.add_argument("--out", default=None)
    a = p.parse_args(argv)
    for case in (a.fit.split(",") if a.fit else []):
        fit(case, a.models)
    for case in (a.eval.split(",") if a.eval else []):
        evaluate(case, a.models, [int(s) for s in a.windows.split(",")], a.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
