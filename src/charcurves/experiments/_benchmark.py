"""The paper's whole study in one call: sweeps, tables, figures and a report beside the paper's numbers.

:func:`run_benchmark` runs the main noise sweep (noise on the forcing, forward validation) into a
resumable SQLite store, then the side studies (Table 1's MIW ensembles, Appendix C sensitivity,
Appendix F noise on x, the Lyapunov time), each cached in ``extras.json`` so that a re-run only
computes what is missing, and writes ``results.csv``, ``report.md`` and ``report.html``.

The table builders (:func:`a_fit_table`, :func:`performance_table`, :func:`tsep_failure_snr`,
:func:`cost_table`, :func:`status_table`) take a plain DataFrame of result rows (the columns of
``results.csv``), so they can be checked on synthetic rows and reused on any store.

Examples
--------
>>> import numpy as np, pandas as pd
>>> snr = np.array([40.0, 20.0, 0.0]); eta = 10 ** (-snr / 20)
>>> df = pd.DataFrame({"system": "duffing", "preset": "default", "method": "parametric", "snr_db": snr,
...                    "realization": 0, "rmse_f1": 0.01 * eta, "rmse_f2": 0.02 * eta, "status": "ok"})
>>> fits = a_fit_table(df)
>>> round(fits[("duffing", "default", "parametric")]["A"]["f2"], 6)
0.02
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Sequence
from typing import Any


from .._bounds import check_number
from .._errors import ConfigError
from ._run_files import BenchmarkResult as BenchmarkResult
from ._results import BENCHMARK_TAG, MIW_METHODS, RESULT_COLUMNS, _all_methods, _write_csv, empty_results_frame
from ._results import results_frame
from ._run_files import _Context, _Extras, _log, _sr_budget

__all__ = [
    "BENCHMARK_SECTIONS",
    "RESULT_COLUMNS",
    "BenchmarkResult",
    "run_benchmark",
    "parse_snr_list",
    "parse_name_list",
    "results_frame",
    "ensemble_table",
    "a_fit_table",
    "performance_table",
    "tsep_failure_snr",
    "cost_table",
    "status_table",
    "build_report",
]

BENCHMARK_SECTIONS = ("forward", "lyapunov", "miw", "sensitivity", "appendix-f")
"""The side studies of :func:`run_benchmark` that ``skip`` (``--skip``) may leave out."""
SYSTEMS = ("duffing", "stick-slip")
"""The paper's two benchmark systems, what :func:`run_benchmark` runs by default (``--systems``)."""

#: The quick grid: minutes on a 2-core machine (Appendix F with one realisation per level).
QUICK: dict[str, Any] = {
    "snr_db": (40.0, 20.0, 0.0), "realizations": 2, "appendix_f_realizations": 1, "forward_cases": 2,
    "miw_seeds": 10, "miw_realizations": 5, "lyapunov_time": 1000.0, "case_time_budget": 5.0, "sr_generations": 20}
#: ``full``: the paper's sizes (the grid itself is :data:`PAPER_SNR_DB` x 10).
FULL: dict[str, Any] = {
    "appendix_f_realizations": 10, "forward_cases": 10, "miw_seeds": 100, "miw_realizations": 10,
    "lyapunov_time": 5000.0, "case_time_budget": 20.0, "sr_generations": None}


# ---------------------------------------------------------------------- option parsing
def parse_snr_list(text: str) -> tuple[float, ...]:
    """``"40,20,0"`` -> (40.0, 20.0, 0.0); ``inf`` allowed. Raises ConfigError on anything else.

    How ``charcurves benchmark --snr`` is read (repeated levels are kept once, in order).

    Examples
    --------
    >>> from charcurves.experiments import parse_snr_list
    >>> parse_snr_list("40, 20, inf, 40")
    (40.0, 20.0, inf)
    """
    parts = [p.strip() for p in str(text).split(",")]
    if not parts or any(not p for p in parts):
        raise ConfigError(f"--snr must be comma-separated dB values such as 40,20,0, got {text!r}")
    out = []
    for p in parts:
        try:
            v = float(p)
        except ValueError:
            raise ConfigError(f"--snr must be comma-separated dB values such as 40,20,0, got {text!r}") from None
        if math.isnan(v) or v == -math.inf or (v == math.inf and p.lower().lstrip("+") not in ("inf", "infinity")):
            raise ConfigError(f"--snr values must be finite dB levels or inf, got {p!r}")  # 1e999 is not 'inf'
        if v != math.inf:
            check_number("snr_db", v, label="each --snr level")
        out.append(v)
    return tuple(dict.fromkeys(out))


def parse_name_list(text: str, allowed: Sequence[str], what: str) -> tuple[str, ...]:
    """``"a,b"`` -> ("a", "b"), each checked against ``allowed`` (ConfigError naming the bad one).

    How ``charcurves benchmark --systems/--methods/--skip`` are read; ``what`` is the option's name.

    Examples
    --------
    >>> from charcurves.experiments import BENCHMARK_SYSTEMS, parse_name_list
    >>> parse_name_list("stick-slip,duffing", BENCHMARK_SYSTEMS, "systems")
    ('stick-slip', 'duffing')
    >>> parse_name_list("duffing,vdp", BENCHMARK_SYSTEMS, "systems")
    Traceback (most recent call last):
    ...
    charcurves._errors.ConfigError: unknown system 'vdp' in --systems; choose from duffing, stick-slip
    """
    names = tuple(dict.fromkeys(p.strip() for p in str(text).split(",") if p.strip()))
    if not names:
        raise ConfigError(f"--{what} needs at least one name; choose from {', '.join(allowed)}")
    bad = [n for n in names if n not in allowed]
    if bad:
        raise ConfigError(f"unknown {what[:-1] if what.endswith('s') else what} {bad[0]!r} in --{what}; "
                          f"choose from {', '.join(allowed)}")
    return names


# ---------------------------------------------------------------------- results


from ._tables import (  # noqa: E402 - the tables of the report, re-exported (they were defined here)
    BIAS_LIMITED as BIAS_LIMITED,
    NEURAL as NEURAL,
    NN_X_ETA_MAX as NN_X_ETA_MAX,
    a_fit_table as a_fit_table,
    cost_table as cost_table,
    ensemble_table as ensemble_table,
    mixed_terms_table as mixed_terms_table,
    performance_table as performance_table,
    status_table as status_table,
    tsep_failure_snr as tsep_failure_snr,
)


# ---------------------------------------------------------------------- the run
def run_benchmark(out_dir: str | os.PathLike, *, systems: Sequence[str] = SYSTEMS,
                  methods: Sequence[str] | None = None, snr_db: Sequence[float] | None = None,
                  realizations: int | None = None, full: bool = False, preset: str = "default",
                  executor: str = "local", workers: int | None = None, forward_cases: int | None = None,
                  skip: Sequence[str] = (), progress: bool = True, t_end: float = 40.0, n_points: int = 1000,
                  base_seed: int = 0, retry_failed: bool = False, address: str | None = None,
                  noise_on: str = "force", report_only: bool = False, variant: str = "paper") -> BenchmarkResult:
    """Run the paper's study and write ``results.csv``, ``report.md`` and ``report.html`` in ``out_dir``.

    Parameters
    ----------
    out_dir : str or PathLike
        Output folder; ``results.sqlite`` there makes the run resumable (finished jobs are skipped).
    systems : sequence of str
        "duffing", "stick-slip".
    methods : sequence of str, optional
        Methods (default: all of :data:`charcurves.METHODS`: the paper's twelve and sr-cc+refit).
    snr_db, realizations : optional
        The grid; default the quick grid (40, 20, 0 dB x 2), or the paper's (40..-20 dB x 10)
        with ``full``.
    full : bool
        The paper's grid and protocol sizes (10 validation cases per model, 100-run MIW ensembles,
        Lyapunov over 5000 time units).
    preset : {"default", "paper"}
        Training preset of the neural methods. Rows of both presets can share one ``out_dir``;
        the report puts them side by side.
    executor, workers, address
        As :func:`run_sweep` ("local" processes or "ray"; ``address``, default ``RAY_ADDRESS``: a
        Ray cluster, whose workers return rows and models to this process, which alone writes
        ``out_dir``; see docs/cluster.md).
    forward_cases : int, optional
        Validation cases per model (default 2 quick, 10 full; 0 with ``skip=("forward",)``).
    skip : sequence of str
        Side studies to leave out (:data:`BENCHMARK_SECTIONS`).
    t_end, n_points : training records (40 s, 1000 samples, as the paper)
    base_seed : int
        Enters every dataset seed.
    retry_failed : bool
        Also rerun jobs stored as failed (e.g. after a worker was killed).
    noise_on : {"force", "state"}
        ``"force"``: the paper's main study (noise on the forcing) with its side studies.
        ``"state"``: Appendix F alone, on the grid given (noise on x only; the paper's protocol,
        Savitzky-Golay and equation error, beside charcurves' default, output error); nothing else runs.
    variant : {"paper", "scripts"}
        The systems' parameter sets: ``"paper"`` (the paper's text: Duffing α = −1, β = 1; stick-slip
        Ω = 0.5 with a sign) or ``"scripts"`` (the authors' scripts, with which Tables 2 and 3 were
        made: Duffing α = −1.05, β = 1.02; stick-slip Ω = 0.3 with tanh(500 v); LSODA's default
        tolerances). One variant per output folder: its report states which.
    report_only : bool
        Run nothing: rebuild ``report.md``, ``report.html`` and ``figures/`` from the small files of
        ``out_dir`` (``results.csv``, ``run.json``, ``extras.json``, ``appendix_f.csv``), as
        :func:`build_report`; the grid arguments are then ignored.

    Returns
    -------
    BenchmarkResult

    Examples
    --------
    The example is not run in the tests: even this smallest benchmark (one fit, no side studies) takes about 15 s.

    >>> import os
    >>> from charcurves.experiments import run_benchmark
    >>> result = run_benchmark("bench", systems=["duffing"], methods=["parametric"], snr_db=[20], realizations=1,
    ...                        skip=("forward", "lyapunov", "miw", "sensitivity", "appendix-f"))  # doctest: +SKIP
    >>> sorted(os.listdir("bench"))  # doctest: +SKIP
    ['extras.json', 'figures', 'models', 'report.html', 'report.md', 'results.csv', 'results.sqlite']
    """
    from ..fitting import get_preset
    from ._sweep import EXECUTORS, PAPER_SNR_DB, Sweep, run_sweep

    t_start = time.perf_counter()
    if report_only:
        from ._report_inputs import committed_csv, load_report_inputs, write_report

        inputs = load_report_inputs(out_dir)
        md, page = write_report(out_dir, inputs)
        df, run, _, af = inputs
        frames = [df] if run.get("noise_on", "force") == "force" else list(af.values())
        name = "results.csv" if run.get("noise_on", "force") == "force" else "appendix_f.csv"
        csv = committed_csv(os.fspath(out_dir), name) or os.path.join(os.fspath(out_dir), name)
        return BenchmarkResult(os.fspath(out_dir), csv, md, page, sum(len(f) for f in frames), 0,
                               sum(int((f["status"] != "ok").sum()) for f in frames), time.perf_counter() - t_start,
                               {"report": time.perf_counter() - t_start})
    systems = tuple(systems)
    bad = [s for s in systems if s not in SYSTEMS]
    if bad or not systems:
        raise ConfigError(f"unknown system {bad[0] if bad else ''!r}; choose from {', '.join(SYSTEMS)}")
    methods = tuple(methods) if methods else _all_methods()
    unknown = [m for m in methods if m not in _all_methods()]
    if unknown:
        raise ConfigError(f"unknown method {unknown[0]!r}; choose from {', '.join(_all_methods())}")
    if executor not in EXECUTORS:
        raise ConfigError(f"executor must be one of {', '.join(EXECUTORS)}, got {executor!r}")
    get_preset(preset)
    if variant not in ("paper", "scripts"):
        raise ConfigError(f"variant must be 'paper' (the paper's text) or 'scripts' (the authors' scripts), "
                          f"got {variant!r}")
    if noise_on not in ("force", "state"):
        raise ConfigError(f"noise_on must be 'force' (the main study) or 'state' (Appendix F), got {noise_on!r}")
    if noise_on == "state":  # Appendix F alone: the main sweep and the other side studies are not run
        skip = tuple(s for s in BENCHMARK_SECTIONS if s != "appendix-f")
    bad_skip = [s for s in skip if s not in BENCHMARK_SECTIONS]
    if bad_skip:
        raise ConfigError(f"unknown section {bad_skip[0]!r} to skip; choose from {', '.join(BENCHMARK_SECTIONS)}")
    sizes = dict(QUICK)
    if full:
        sizes.update(FULL)
        sizes["snr_db"], sizes["realizations"] = PAPER_SNR_DB, 10
    if snr_db is not None:
        sizes["snr_db"] = tuple(float(s) for s in snr_db)
    if realizations is not None:
        check_number("realizations", realizations, label="realizations (--realizations)")
        sizes["realizations"] = sizes["appendix_f_realizations"] = int(realizations)
    if workers is not None:
        check_number("workers", workers, label="workers (--workers)")
    if forward_cases is not None:
        check_number("forward_cases", forward_cases, label="forward_cases (--forward-cases)")
    for level in sizes["snr_db"] if snr_db is not None else ():
        if level != math.inf:
            check_number("snr_db", level, label="each snr_db level (--snr)")
    from ..symbolic import POST_SR_OPTIONS

    # what post-SR searches with (the quick grid's budget, else the post-SR defaults), for the report
    sizes["post_sr"] = {"generations": int(sizes["sr_generations"] or POST_SR_OPTIONS["generations"]),
                        "max_points": int(POST_SR_OPTIONS["max_points"])}
    if forward_cases is not None:
        if isinstance(forward_cases, bool) or int(forward_cases) < 0:
            raise ConfigError(f"forward cases must be a non-negative integer, got {forward_cases!r}")
        sizes["forward_cases"] = int(forward_cases)
    if "forward" in skip:
        sizes["forward_cases"] = 0
    out_dir = os.fspath(out_dir)
    if os.path.exists(out_dir) and not os.path.isdir(out_dir):
        raise ConfigError(f"--out {out_dir!r} is a file; give a directory (it is created when missing)")
    try:
        os.makedirs(out_dir, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"cannot create the output directory {out_dir!r} ({exc.strerror}); choose another --out") \
            from None
    timing: dict[str, float] = {}

    # ------------------------------------------------------------------ main sweep
    t0 = time.perf_counter()
    sweep = Sweep(systems=systems, methods=methods, snr_db=sizes["snr_db"], realizations=sizes["realizations"],
                  preset=preset, t_end=t_end, n_points=n_points, base_seed=base_seed, tag=BENCHMARK_TAG, variant=variant,
                  method_options=_sr_budget(methods, sizes["sr_generations"]))
    store = os.path.join(out_dir, "results.sqlite")
    assert not isinstance(sweep.realizations, int)  # Sweep made it a tuple
    n_jobs = n_run = n_failed = 0
    if noise_on == "force":
        _log(progress, f"main sweep: {len(sweep.jobs())} jobs ({len(systems)} systems x {len(methods)} methods x "
                       f"{len(sweep.snr_db)} SNR levels x {len(sweep.realizations)} realisations), "
                       f"{sizes['forward_cases']} validation cases per model")
        rep = run_sweep(sweep, store, executor=executor, workers=workers, progress=progress, address=address,
                        forward_cases=sizes["forward_cases"], case_time_budget=sizes["case_time_budget"],
                        # no per-job budget: it would count the fit too and leave a slow (paper-preset) model no
                        # validation at all; the per-case budget bounds the validation to cases x budget
                        save_models=os.path.join(out_dir, "models"),
                        retry_failed=retry_failed)
        n_jobs, n_run = rep.n_jobs, rep.n_run
        timing["main sweep"] = time.perf_counter() - t0
    df = results_frame(store) if noise_on == "force" else empty_results_frame()  # state: no main store
    csv_path = os.path.join(out_dir, "results.csv")
    if noise_on == "force":
        _write_csv(df, csv_path)

    extras = _Extras(os.path.join(out_dir, "extras.json"))
    ctx = _Context(out_dir=out_dir, systems=systems, methods=methods, preset=preset, sizes=sizes,
                   t_end=t_end, n_points=n_points, base_seed=base_seed, full=full, executor=executor,
                   workers=workers, progress=progress, skip=tuple(skip), sweep=sweep, address=address)

    # ------------------------------------------------------------------ side studies
    from ._appendix_f import appendix_f
    from ._side_studies import lyapunov, miw_study, sensitivity

    if "lyapunov" not in skip and "duffing" in systems:
        t0 = time.perf_counter()
        lyapunov(ctx, extras)
        timing["lyapunov"] = time.perf_counter() - t0
    # the paper preset trains for minutes per fit: its side studies only run with the full protocol
    slow_preset = get_preset(preset).adam_steps > 2000 and not full
    if "miw" not in skip and "duffing" in systems and any(m in methods for m in MIW_METHODS) and not slow_preset:
        t0 = time.perf_counter()
        miw_study(ctx, extras)
        timing["miw"] = time.perf_counter() - t0
    if "sensitivity" not in skip and "nn-cc" in methods and not slow_preset:
        t0 = time.perf_counter()
        sensitivity(ctx, extras)
        timing["sensitivity"] = time.perf_counter() - t0
    if "appendix-f" not in skip and not (slow_preset and any(m in NEURAL for m in methods)):
        t0 = time.perf_counter()
        af_counts = appendix_f(ctx)
        timing["appendix-f"] = time.perf_counter() - t0
        if noise_on == "state":  # the Appendix F study is the run: its jobs and CSV are what it reports
            n_jobs, n_run, n_failed = af_counts
            csv_path = os.path.join(out_dir, "appendix_f.csv")

    # ------------------------------------------------------------------ report, from the files alone
    t0 = time.perf_counter()
    from ._report_figures import figure_data
    from ._report_inputs import run_record, write_run_file

    if noise_on == "force":  # the simulated figures (Figs. 6, 7) belong to the main study
        figure_data(df, {s: sweep.variant_of(s) for s in systems}, extras)
    extras.save()
    ran = [name for name in ("lyapunov", "miw", "sensitivity", "appendix-f") if name in timing]
    write_run_file(out_dir, run_record(systems=systems, methods=methods, preset=preset, full=full, sizes=sizes,
                                       variants={s: sweep.variant_of(s) for s in systems}, skip=skip, sections=ran,
                                       timing=timing, t_end=t_end, n_points=n_points, base_seed=base_seed,
                                       noise_on=noise_on))
    md, page = build_report(out_dir)
    timing["report"] = time.perf_counter() - t0
    if noise_on == "force":
        n_failed = int((df["status"] != "ok").sum()) if len(df) else 0
    res = BenchmarkResult(out_dir, csv_path, md, page, n_jobs, n_run, n_failed,
                          time.perf_counter() - t_start, timing)
    return res


from ._report_inputs import build_report as build_report  # noqa: E402 - re-exported (it was defined here)
