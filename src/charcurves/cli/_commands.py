"""``charcurves simulate``, ``validate``, ``select`` and ``benchmark``."""

from __future__ import annotations

import os
import sys

from ._common import UsageError, check_seed, make_out_dir, say

__all__ = ["cmd_simulate", "cmd_validate", "cmd_select", "cmd_benchmark"]


def cmd_simulate(a) -> int:
    from ..data import corrupt
    from ..systems import get_system
    from ..systems._base import sample_times

    system = get_system(a.system, a.variant)
    sample_times(a.t_end, a.n_points)  # the bounds, before any integration
    if a.system == "two-dof":  # a multi-DOF record: t,x1,x2,v1,a1,v2,a2,F1,F2
        from ..templates._fit import simulate_multi_cli

        return simulate_multi_cli(system, a, say=say)
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


def cmd_select(a) -> int:
    from ..selection._cli import run_select

    return run_select(a, say=say, check_out=make_out_dir)


def cmd_validate(a) -> int:
    from ..fitting._output_error import validate_cli
    from ._fit import time_column

    for line in validate_cli(a.model, a.csv, rows=a.rows, time_col=time_column(a.time_col), x_col=a.x_col,
                             force_col=a.force_col, sample_rate=a.sample_rate, hold=a.hold, substeps=a.substeps,
                             out_dir=a.out):
        say(line)
    return 0


def ray_address(a) -> str | None:
    """``--address``, else ``RAY_ADDRESS`` from the environment (as Ray's own tools read it)."""
    address = a.address if a.address is not None else os.environ.get("RAY_ADDRESS") or None
    if address is not None and not address.strip():
        raise UsageError("--address is empty; give the Ray cluster's address, e.g. --address auto or "
                         "--address ray://head:10001")
    return address


def cmd_benchmark(a) -> int:
    from ..experiments._benchmark import BENCHMARK_SECTIONS, SYSTEMS, parse_name_list, parse_snr_list, run_benchmark
    from ..fitting._estimator import METHODS

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
                        retry_failed=a.retry_failed, base_seed=a.seed, address=address)
    say(f"benchmark: {res}", a.quiet)
    return 0
