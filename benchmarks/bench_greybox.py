"""Grey-box targets of issue 47 (hidden states): two-tank, two-DOF with x1 only, Bouc-Wen.

Each case fits a :class:`~charcurves.templates.StateSpace` template by
:func:`~charcurves.fitting.fit_state_space` and scores

* each curve by its normalised RMSE: the RMSE against the true curve over the argument range the
  true (clean) states visit, 400 points, divided by the true curve's standard deviation there (as
  benchmarks/bench_zoo.py);
* the free run: RMSE of one free run of the whole record against the noisy measured signal, beside
  the noise's own RMSE (the true model's free-run RMSE on the same noisy record); from the default
  start (the whole state fitted to the record's first samples, ``free_run_start`` says how many) and from the
  older one (``*_first_samples``: a quadratic through the first 8 samples, hidden states as fitted);
* the cost (seconds, one thread).

Cases: ``two-tank`` (and ``two-tank-anchored``: both outflows a basis z..z**5 without a constant,
f(0) = 0) (``TwoTank``, 1000 samples over 1000 s, noise 0.01 on the lower level, the
upper level hidden; both starts of ``fit_state_space``), ``two-dof-x1`` (the paper's two-DOF
system, 1500 samples over 60 s, noise on x1 at 40 dB, x2 hidden; ``two-dof-x1-newton``: one coupling
curve, ``- f2(x1 - x2)`` in the second equation), ``bouc-wen`` (``BoucWen``,
``--bw-samples`` multisine samples for training, the test multisine and sweep records for the free
run; ``bouc-wen-kink``: f3, f4 on the basis 1, z, |z|, z**2, z*|z|, z**3; both with a linear
second-order baseline fitted the same way and test free runs from rest and with a 50-sample window).

Run: ``python benchmarks/bench_greybox.py [--cases two-tank,two-dof-x1,bouc-wen] [--out DIR]``;
results go to ``DIR/results.json`` (default benchmarks/results/greybox).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))


def nrmse(fitted, true, lo, hi) -> float:
    z = np.linspace(lo, hi, 400)
    t = np.asarray(true(z), dtype=float)
    return float(np.sqrt(np.mean((np.asarray(fitted(z), dtype=float) - t) ** 2)) / np.std(t))


def two_tank(start: str, n_starts: int, seed: int, anchored: bool = False, neural: bool = False, hold: float = 25.0,
             **fit) -> dict:
    from charcurves.curves import Basis, Neural
    from charcurves.fitting import fit_state_space, window_free_run_error
    from charcurves.systems import TwoTank
    from charcurves.templates import StateSpace

    system = TwoTank(hold=hold)  # hold: mean seconds between the pump's level changes
    record = system.simulate(n_points=1000, t_end=1000.0, seed=seed)
    clean = system.states(n_points=1000, t_end=1000.0, seed=seed)
    test = system.simulate(n_points=1000, t_end=1000.0, seed=seed + 100)
    # anchored: an empty tank does not drain, f(0) = 0 (a basis without the constant)
    # (powers 1..5, or 1..degree where --degree is given)
    basis = ", ".join(["z"] + [f"z**{k}" for k in range(2, int(fit.get("degree", 5)) + 1)])
    curves = {n: Basis(basis) for n in ("f1", "f2")} if anchored else {}
    if neural:  # networks (statespace._neural: the polynomial stages, then a stage of the networks)
        curves = {n: Neural() for n in ("f1", "f2")}
    template = StateSpace("x1' = g*F - f1(x1); x2' = f1(x1) - f2(x2)", measured={"x2": "x"}, **curves)
    t0 = time.perf_counter()
    model = fit_state_space(template, record, start=start, n_starts=n_starts, seed=seed, **fit)
    seconds = time.perf_counter() - t0
    sim = model.simulate(record)
    return {
        "case": "two-tank" + ("-anchored" if anchored else ""), "start": start, "seed": seed, "seconds": seconds,
        "input_hold_s": hold,
        **fit, "fit_cpu_seconds": model.info["cpu_seconds"], "x1_max_fitted": float(np.nanmax(sim["x1"])), "x1_max_true": float(clean["x1"].max()),
        "f1_nrmse": nrmse(model.curves["f1"], system.f1, clean["x1"].min(), clean["x1"].max()),
        "f2_nrmse": nrmse(model.curves["f2"], system.f2, clean["x2"].min(), clean["x2"].max()),
        "gain": model.gain, "free_run_start": model.info["free_run_start"],
        "free_run_rmse_train": model.info["free_run_rmse"]["x2"],  # the default start (50-sample window)
        "free_run_rmse_train_first_samples": model.free_run_rmse(record, start="first-samples")["x2"],
        # the same free run from the fitted initial state (the measured level's too) instead of the record's
        "free_run_rmse_train_fitted_start": model.free_run_rmse(record, initial=model.initial_state)["x2"],
        "free_run_rmse_test": model.free_run_rmse(test)["x2"],
        "free_run_rmse_test_first_samples": model.free_run_rmse(test, start="first-samples")["x2"],
        "noise_rmse_test": float(np.sqrt(np.mean((test.x - system.states(n_points=1000, t_end=1000.0,
                                                                         seed=seed + 100)["x2"]) ** 2))),
        # the benchmarks' convention: the test's initial state (hidden x1 too) from its first 50 samples
        "free_run_rmse_test_window50": window_free_run_error(model, test, 50)[0]["x2"],
        "noise_rmse_train": float(np.sqrt(np.mean((record.x - clean["x2"]) ** 2))),
        "stages": model.info["stages"], "gauges": model.info["gauge_freedoms"],
        "curves": model.info["representations"],
        **({"post_sr_forms": {n: c["expression"] for n, c in model.info["post_sr"]["curves"].items()},
            "post_sr_losses": {k: model.info["post_sr"][k] for k in ("loss_before", "loss_distilled", "loss_refit")}}
           if "post_sr" in model.info else {}),
    }


def two_dof_x1(start: str, n_starts: int, seed: int, newton: bool = False, **fit) -> dict:
    from charcurves.curves import Basis
    from charcurves.data import MultiTrajectory
    from charcurves.fitting import fit_state_space
    from charcurves.systems import TwoDOF
    from charcurves.templates import StateSpace

    system = TwoDOF()
    clean = system.simulate(t_end=60.0, n_points=1500)
    x1 = np.asarray(clean.states["x1"])
    sigma = np.sqrt(np.mean(x1 ** 2)) / 100.0  # 40 dB
    noisy = x1 + np.random.default_rng(seed).normal(0.0, sigma, x1.size)
    record = MultiTrajectory(clean.t, {"x1": noisy}, dict(clean.forces))
    # the couplings f2, f4 of a difference are anchored at 0 by the template, so x2(t0) is fitted;
    # newton: one coupling force, equal and opposite on the two masses (f4(z) = -f2(-z), true here),
    # f2 on a basis without the constant (no force at zero extension), which fixes x2's offset
    equation = ("x1'' + f1(x1') + f2(x1 - x2) = F1; x2'' + f3(x2') - f2(x1 - x2) = F2" if newton else
                "x1'' + f1(x1') + f2(x1 - x2) = F1; x2'' + f3(x2') + f4(x2 - x1) = F2")
    spring = ", ".join(["z"] + [f"z**{k}" for k in range(2, int(fit.get("degree", 10)) + 1)])
    template = StateSpace(equation, measured={"x1": "x1"}, **({"f2": Basis(spring)} if newton else {}))
    t0 = time.perf_counter()
    model = fit_state_space(template, record, start=start, n_starts=n_starts, seed=seed, **fit)
    seconds = time.perf_counter() - t0
    v1 = np.gradient(x1, clean.t)
    x2 = np.asarray(clean.states["x2"])
    v2 = np.gradient(x2, clean.t)
    ranges = {"f1": (v1.min(), v1.max()), "f2": ((x1 - x2).min(), (x1 - x2).max()),
              "f3": (v2.min(), v2.max()), "f4": ((x2 - x1).min(), (x2 - x1).max())}
    truth = system.true_curves()
    first_samples = model.free_run_rmse(record, start="first-samples")["x1"]  # (before f4 is set below)
    if newton:  # f4 is -f2(-z) by construction
        model.curves["f4"] = lambda z, f2=model.curves["f2"]: -np.asarray(f2(-np.asarray(z, dtype=float)))
    return {"case": "two-dof-x1" + ("-newton" if newton else ""), "start": start, "seed": seed,
            "seconds": seconds, **fit, "x2_0_fitted": float(model.initial_state["x2"]), "x2_0_true": float(x2[0]),
            "gauge_conditions": model.info["gauge_conditions"],
            "fit_cpu_seconds": model.info["cpu_seconds"],
            **{f"{n}_nrmse": nrmse(model.curves[n], truth[n], *ranges[n]) for n in truth},
            "free_run_start": model.info["free_run_start"],
            "free_run_rmse_train": model.info["free_run_rmse"]["x1"], "noise_rmse_train": float(sigma),
            "free_run_rmse_train_first_samples": first_samples,
            "free_run_rmse_train_fitted_start": model.info["free_run_rmse_fitted_start"]["x1"],
            "stages": model.info["stages"], "gauges": model.info["gauge_freedoms"]}


def bouc_wen(start: str, n_starts: int, seed: int, samples: int, extrapolation: str = "polynomial", kink: bool = False,
             **fit) -> dict:
    from charcurves.curves import Basis
    from charcurves.fitting import fit_state_space, window_free_run_error
    from charcurves.systems import BoucWen
    from charcurves.templates import StateSpace

    system = BoucWen()
    train_input = system.multisine(seed=seed, period=samples)
    train = system.simulate(train_input, seed=seed)
    tests = {"multisine": system.multisine(seed=seed + 100, period=8192), "sweep": system.sweep(8192)}
    template = StateSpace("x1'' + f1(x1') + f2(x1) + x2 = g*F; x2' = f3(x2)*Abs(x1') + f4(x2)*x1'",
                          measured={"x1": "x"},
                          # kink: the hysteresis curves on powers with a kink at 0 (|z|, z |z|), which the
                          # Bouc-Wen law's |z| needs and a smooth polynomial only approximates
                          **({n: Basis("1, z, Abs(z), z**2, z*Abs(z), z**3") for n in ("f3", "f4")} if kink else {}))
    t0 = time.perf_counter()
    model = fit_state_space(template, train, start=start, n_starts=n_starts, seed=seed, extrapolation=extrapolation,
                            **fit)
    seconds = time.perf_counter() - t0
    clean_train = system.states(train_input)
    ranges = {"f1": clean_train["v"], "f2": clean_train["y"], "f3": clean_train["w"], "f4": clean_train["w"]}
    truth = system.curves()
    out = {"case": "bouc-wen" + ("-kink" if kink else ""), "extrapolation": extrapolation, "start": start, "seed": seed, "samples": samples, "seconds": seconds,
           **fit, "fit_cpu_seconds": model.info["cpu_seconds"],
           "gain": model.gain, "free_run_start": model.info["free_run_start"],
           "free_run_rmse_train": model.info["free_run_rmse"]["x1"],
           "free_run_rmse_train_first_samples": model.free_run_rmse(train, start="first-samples")["x1"],
           "free_run_rmse_train_fitted_start": model.info["free_run_rmse_fitted_start"]["x1"],
           "noise_rmse_train": float(np.sqrt(np.mean((train.x - clean_train["y"]) ** 2))),
           **{f"{n}_nrmse": nrmse(model.curves[n], truth[n], r.min(), r.max()) for n, r in ranges.items()},
           "stages": model.info["stages"], "gauges": model.info["gauge_freedoms"]}
    # the baseline of the same run: a linear second-order model (no hidden state), fitted the same way
    linear = fit_state_space(StateSpace("x1'' + f1(x1') + f2(x1) = g*F", measured={"x1": "x"}, f1=Basis("z"),
                                        f2=Basis("z")), train, start=start, n_starts=n_starts, seed=seed)
    for name, u in tests.items():
        rec = system.simulate(u, seed=seed + 7)
        clean = system.states(u)
        # the default start (the state fitted to the first samples), every sample counted, and the
        # benchmarks' convention (the state from the first 50 samples, the RMSE after them)
        out[f"test_{name}_rmse"] = model.free_run_rmse(rec)["x1"]
        out[f"test_{name}_rmse_window50"] = window_free_run_error(model, rec, 50)[0]["x1"]
        out[f"test_{name}_rmse_first_samples"] = model.free_run_rmse(rec, start="first-samples")["x1"]
        out[f"test_{name}_linear_rmse"] = linear.free_run_rmse(rec)["x1"]
        # from rest (the records' true initial state, the one the true model's run starts from), hidden x2 = 0
        out[f"test_{name}_rmse_from_rest"] = model.free_run_rmse(rec, initial=dict.fromkeys(model.initial_state, 0.0))["x1"]
        out[f"test_{name}_linear_rmse_from_rest"] = linear.free_run_rmse(
            rec, initial=dict.fromkeys(linear.initial_state, 0.0))["x1"]
        noise = rec.x - clean["y"]  # the true model's free-run residual: the measurement noise
        out[f"test_{name}_true_model_rmse_window50"] = float(np.sqrt(np.mean(noise[50:] ** 2)))
        out[f"test_{name}_true_model_rmse"] = float(np.sqrt(np.mean(noise ** 2)))
    return out


def main(argv=None) -> int:
    import torch

    torch.set_num_threads(1)
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cases", default="two-tank,two-dof-x1,bouc-wen")
    p.add_argument("--starts", default="growing,linear")
    p.add_argument("--n-starts", type=int, default=4)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--bw-samples", type=int, default=1000)
    p.add_argument("--out", default=os.path.join(HERE, "results", "greybox"))
    p.add_argument("--degree", type=int, default=None, help="curves' polynomial degree (two-tank, two-dof-x1; default the fit's)")
    p.add_argument("--schedule", default=None, help="segment lengths, e.g. 16,64,256,1000 (two-tank, two-dof-x1)")
    p.add_argument("--label", default=None, help="a label stored in each row")
    p.add_argument("--max-iter", type=int, default=None, help="Levenberg-Marquardt iterations per stage")
    p.add_argument("--tank-hold", type=float, default=25.0,
                   help="two-tank: mean seconds between the pump's level changes (TwoTank.hold)")
    p.add_argument("--extrapolation", default="polynomial", help="bouc-wen curves past their range: polynomial|linear")
    p.add_argument("--neural", action="store_true", help="two-tank: both outflows as networks (Neural())")
    p.add_argument("--post-sr", action="store_true", help="two-tank: post-SR of the fitted curves (closed forms)")
    p.add_argument("--time-budget", type=float, default=None,
                   help="two-tank: the fit's wall-clock budget in seconds (default the fit's, 600)")
    args = p.parse_args(argv)
    fit = {k: v for k, v in (("degree", args.degree), ("time_budget", args.time_budget), ("max_iter", args.max_iter),
                             ("schedule", [int(s) for s in args.schedule.split(",")] if args.schedule else None))
           if v is not None}
    if args.post_sr:
        fit["post_sr"] = True
    os.makedirs(args.out, exist_ok=True)
    path = os.path.join(args.out, "results.jsonl")
    for case in args.cases.split(","):
        for start in args.starts.split(","):
            t0, c0 = time.perf_counter(), time.process_time()
            try:
                if case in ("two-tank", "two-tank-anchored"):
                    row = two_tank(start, args.n_starts, args.seed, anchored=case.endswith("anchored"),
                                   neural=args.neural, hold=args.tank_hold, **fit)
                elif case in ("two-dof-x1", "two-dof-x1-newton"):
                    row = two_dof_x1(start, args.n_starts, args.seed, newton=case.endswith("newton"), **fit)
                elif case in ("bouc-wen", "bouc-wen-kink"):
                    row = bouc_wen(start, args.n_starts, args.seed, args.bw_samples, args.extrapolation,
                                   kink=case.endswith("kink"), **fit)
                else:
                    raise SystemExit(f"unknown case {case!r}")
            except Exception as exc:  # a failure of the library is a result too
                row = {"case": case, "start": start, "error": f"{type(exc).__name__}: {exc}",
                       "seconds": time.perf_counter() - t0}
            row["cpu_seconds_case"] = time.process_time() - c0  # fit and scoring, one thread
            if args.label:
                row["label"] = args.label
            with open(path, "a") as fh:
                fh.write(json.dumps(row) + "\n")
            print(json.dumps({k: v for k, v in row.items() if k != "stages"}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
