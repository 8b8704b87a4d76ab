"""``charcurves simulate``, ``validate``, ``select``, ``benchmark`` and ``report``."""

from __future__ import annotations

import os
import sys

from ._common import UsageError, check_seed, make_out_dir, say

__all__ = ["cmd_simulate", "cmd_validate", "cmd_select", "cmd_benchmark", "cmd_report"]


def cmd_simulate(a) -> int:
    from ..data import corrupt
    from ..systems import get_system
    from ..systems import sample_times

    from ..io import check_output_file

    system = get_system(a.system, a.variant)
    sample_times(a.t_end, a.n_points)  # the bounds, before any integration
    check_output_file(a.out, "--out")  # a device, FIFO or socket is refused; a link is written through
    if a.system == "two-dof":  # a multi-DOF record: t,x1,x2,v1,a1,v2,a2,F1,F2
        return _simulate_multi(system, a, say)
    traj = system.simulate(t_end=a.t_end, n_points=a.n_points)
    clean = traj
    if a.snr is not None:
        traj = corrupt(traj, a.snr, on=a.noise_on, seed=a.seed, reference=a.noise_reference)
    if a.noise_on == "state" and a.snr is not None:
        # keep the contract's columns: v and a are the clean derivatives, for reference
        traj = traj.replace(v=clean.v, a=clean.a)
        print("note: x is noisy; v and a are the clean derivatives for reference. Fit with "
              "--derivatives savgol|spline|spectral to estimate them from x.", file=sys.stderr)
    traj.to_csv(a.out)
    say(f"wrote {a.out}: {a.system} ({a.variant}), {traj.n_samples} samples"
        + (f", SNR {a.snr:g} dB on {a.noise_on}" if a.snr is not None else ", no noise"))
    return 0


def cmd_report(a) -> int:
    """The one-page HTML report of a saved fit (default: report.html in the fit folder)."""
    from ..report import write_fit_report

    truth = None
    if a.truth:
        from ..systems import get_system

        truth = get_system(a.truth, a.truth_variant).true_curves()
    out = a.out
    if out is None:
        folder = os.path.abspath(a.model)
        if os.path.isfile(os.path.join(folder, "model.json")):  # a model/ folder: the report goes beside it
            folder = os.path.dirname(folder)
        out = os.path.join(folder, "report.html")
    elif os.path.isdir(out):
        raise UsageError(f"--out {out!r} is a directory; give the HTML file to write, e.g. {os.path.join(out, 'report.html')}")
    from ..io import check_output_file
    from ._common import refuse_inputs_among_outputs

    if a.out is not None:  # a device, FIFO or socket is refused, a link written through (the default too, on writing)
        check_output_file(out, "--out")
    folder = a.model if os.path.isfile(os.path.join(a.model, "model.json")) else os.path.join(a.model, "model")
    reads = {"model file": os.path.join(folder, "model.json"), "arrays file": os.path.join(folder, "arrays.safetensors"),
             "result file": os.path.join(os.path.dirname(os.path.abspath(folder)), "result.json")}
    for what, path in reads.items():
        refuse_inputs_among_outputs({what: path}, [out])
    import matplotlib

    matplotlib.use("Agg")
    say(f"wrote {write_fit_report(a.model, out, truth=truth)}")
    return 0


def cmd_select(a) -> int:
    from ._select import run_select

    address = ray_address(a)
    fit = None
    if address is not None:  # every family's ensembles as Ray tasks on the cluster
        from ..experiments import ray_ensemble_fitter

        fit = ray_ensemble_fitter(address, threads=1 if a.threads is None else a.threads)
    return run_select(a, say=say, check_out=make_out_dir, fit=fit)


def cmd_validate(a) -> int:
    """Free runs of a saved model; exit 0 when every span's free run finished with a finite RMSE, else
    1 with one line on stderr: the command worked and its verdict is a failure (2 stays "fix the
    command", 130 "interrupted"), so scripts and CI can tell a model that fails from a typo."""
    from ..simulate import validate_cli
    from ._common import check_out_dir
    from ._fit import time_column
    from ._hidden import is_hidden_model, validate_hidden

    if a.out is not None:
        check_out_dir(a.out)  # before the free runs: a file there must not cost them (it was found after 100 s)
    if is_hidden_model(a.model):
        return validate_hidden(a)
    if getattr(a, "start", None) is not None:
        raise UsageError("--start applies to a model with hidden states; this model's free runs start from the "
                         "state fitted to the first 128 samples (or --init-window N)")
    out = validate_cli(a.model, a.csv, rows=a.rows, time_col=time_column(a.time_col), x_col=a.x_col,
                       force_col=a.force_col, sample_rate=a.sample_rate, hold=a.hold, substeps=a.substeps,
                       out_dir=a.out, init_window=a.init_window)
    lines = list(out[0] if isinstance(out, tuple) else out)
    for line in lines:
        say(line)
    failed = _failed_spans(lines)
    if a.out is not None:
        _standard_validation_json(os.path.join(a.out, "validation.json"))
    if failed:
        print(f"charcurves: validation failed: the free run of rows {', '.join(failed)} did not finish with a finite "
              "RMSE (see the status above and in validation.json); the model does not reproduce the record",
              file=sys.stderr, flush=True)
        return 1
    return 0


def _failed_spans(lines: list[str]) -> list[str]:
    """Row spans whose free run failed, from validate's segment lines ("  rows A:B: STATUS, RMSE x ...")."""
    import math
    import re

    failed = []
    for line in lines:
        m = re.match(r"^\s+rows (\d+:\d+): (\w+), RMSE (\S+?)[,\s]", line + " ")
        if m and (m.group(2) != "ok" or not math.isfinite(float(m.group(3)))):
            failed.append(m.group(1))
    return failed


def _standard_validation_json(path: str) -> None:
    """validation.json as standard JSON: non-finite numbers as null, a top-level ``status`` ("ok" or
    "failed") and each segment's ``status``; rewritten only when it is not so already."""
    import json

    from ..io import atomic_write_bytes, json_bytes, non_finite_paths

    try:
        with open(path, encoding="utf-8") as fh:
            doc = json.load(fh)  # Python's reader takes the bare Infinity/NaN that json.dumps writes
    except (OSError, ValueError):
        return
    if not isinstance(doc, dict):
        return
    segments = doc.get("segments") or []
    bad = non_finite_paths(doc)
    failed = bad or any(isinstance(s, dict) and s.get("status") != "ok" for s in segments)
    status = "failed" if failed else "ok"
    if not bad and doc.get("status") == status:
        return
    doc["status"] = status
    if bad:
        doc["non_finite"] = bad
    atomic_write_bytes(path, json_bytes(doc))


def ray_address(a) -> str | None:
    """``--address``, else ``RAY_ADDRESS`` from the environment (as Ray's own tools read it)."""
    address = a.address if a.address is not None else os.environ.get("RAY_ADDRESS") or None
    if address is not None and not address.strip():
        raise UsageError("--address is empty; give the Ray cluster's address, e.g. --address auto or "
                         "--address ray://head:10001")
    return address


def _real_benchmark(a) -> int:
    """``benchmark --real NAME``: the real benchmark's fit and test RMSE (charcurves.experiments.run_real_benchmark)."""
    from ..experiments import run_real_benchmark

    doc = run_real_benchmark(a.real, a.out, data_dir=a.data_dir, seed=a.seed, threads=1, quiet=a.quiet)
    say(f"benchmark {doc['benchmark']}: {doc['method']} on {doc['template']} ({doc['estimation_samples']} samples, "
        f"{doc['fit_seconds']:.1f} s); free-run RMSE after the {doc['init_window']}-sample initialisation window:",
        a.quiet)
    for name, r in doc["tests"].items():
        say(f"  {name}: {r['rmse_' + doc['unit']]:.4g} {doc['unit']} ({r['status']})", a.quiet)
    say(f"wrote {os.path.join(a.out, 'real.json')}, real.md, model/", a.quiet)
    return 0


def cmd_benchmark(a) -> int:
    from ..experiments import BENCHMARK_SECTIONS, BENCHMARK_SYSTEMS as SYSTEMS, parse_name_list, parse_snr_list, run_benchmark
    from ..fitting import METHODS

    if a.real is not None:  # its own fit and test: the options of the paper's study do not reach it
        given = [flag for flag, v in (("--systems", None if a.systems == "duffing,stick-slip" else a.systems),
                                      ("--methods", a.methods), ("--snr", a.snr), ("--realizations", a.realizations),
                                      ("--full", a.full or None), ("--preset", None if a.preset == "default" else 1),
                                      ("--executor", a.executor), ("--address", a.address), ("--workers", a.workers),
                                      ("--forward-cases", a.forward_cases), ("--skip", a.skip.strip() or None),
                                      ("--retry-failed", a.retry_failed or None), ("--report-only", a.report_only or None),
                                      ("--noise-on", None if a.noise_on == "force" else a.noise_on),
                                      ("--variant", None if a.variant == "paper" else a.variant))
                 if v is not None]
        if given:
            raise UsageError(f"{given[0]} does not apply to --real (a real benchmark runs its own fit and test, "
                             f"with --data-dir, --seed and --out only); drop {given[0]}")
        return _real_benchmark(a)
    if a.data_dir is not None:
        raise UsageError("--data-dir goes with --real (a real benchmark's records); drop it or add --real silverbox")
    if a.report_only:
        given = [flag for flag, v in (("--methods", a.methods), ("--snr", a.snr), ("--realizations", a.realizations),
                                      ("--full", a.full or None), ("--forward-cases", a.forward_cases),
                                      ("--retry-failed", a.retry_failed or None), ("--skip", a.skip.strip() or None),
                                      ("--noise-on", None if a.noise_on == "force" else a.noise_on),
                                      ("--variant", None if a.variant == "paper" else a.variant))
                 if v is not None]
        if given:
            raise UsageError(f"--report-only runs nothing, so {given[0]} has no effect; drop {given[0]} (or "
                             "--report-only to run the benchmark)")
        res = run_benchmark(a.out, report_only=True)
        say(f"benchmark: rebuilt {res.report_md} and {res.report_html} from the files in {a.out}", a.quiet)
        return 0
    systems = parse_name_list(a.systems, SYSTEMS, "systems")
    methods = parse_name_list(a.methods, tuple(METHODS), "methods") if a.methods is not None else None
    snr = parse_snr_list(a.snr) if a.snr is not None else None
    skip = parse_name_list(a.skip, BENCHMARK_SECTIONS, "skip") if a.skip.strip() else ()
    for name, value in (("--realizations", a.realizations), ("--workers", a.workers)):
        if value is not None and value < 1:
            raise UsageError(f"{name} must be a positive integer, got {value}")
    if a.forward_cases is not None and a.forward_cases < 0:
        raise UsageError(f"--forward-cases must be 0 or more, got {a.forward_cases}")
    check_seed(a.seed)
    if a.executor == "local" and a.address is not None:
        raise UsageError("--address names a Ray cluster but --executor is local; drop --executor local to run on "
                         "the cluster, or drop --address to run here")
    address = None if a.executor == "local" else ray_address(a)  # an explicit local run ignores RAY_ADDRESS
    executor = a.executor or ("ray" if address is not None else "local")
    res = run_benchmark(a.out, systems=systems, methods=methods, snr_db=snr, realizations=a.realizations,
                        full=a.full, preset=a.preset, executor=executor, workers=a.workers,
                        forward_cases=a.forward_cases, skip=skip, progress=not a.quiet,
                        retry_failed=a.retry_failed, base_seed=a.seed, address=address, noise_on=a.noise_on,
                        variant=a.variant)
    say(f"benchmark: {res}", a.quiet)
    return 0


def _simulate_multi(system, a, say) -> int:
    """``charcurves simulate two-dof``: the multi-DOF record with optional noise on the forcings."""
    from .._errors import ConfigError
    from ..systems import corrupt_forces

    if a.snr is not None and a.noise_on != "force":
        raise ConfigError("multi-DOF records take noise on the forcings only; drop --noise-on state")
    traj = system.simulate(t_end=a.t_end, n_points=a.n_points)
    if a.snr is not None:
        traj = corrupt_forces(traj, a.snr, seed=a.seed, reference=a.noise_reference or "std")
    traj.to_csv(a.out)
    say(f"wrote {a.out}: {system.name} ({a.variant}), {traj.n_samples} samples"
        + (f", SNR {a.snr:g} dB on each forcing" if a.snr is not None else ", no noise"))
    return 0
