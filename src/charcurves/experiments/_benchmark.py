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

import dataclasses
import json
import math
import os
import time
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .._errors import ConfigError
from . import _paper_values as paper

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

#: Side studies that ``skip`` may leave out.
BENCHMARK_SECTIONS = ("forward", "lyapunov", "miw", "sensitivity", "appendix-f")
#: Columns of results.csv, in order (one row per (system, method, snr_db, realization[, preset]) job).
RESULT_COLUMNS = ("system", "method", "snr_db", "realization", "rmse_f1", "rmse_f2", "status", "preset",
                  "variant", "noise_on", "eta", "rmse_x", "t_sep", "n_cases", "n_failed_cases", "n_censored",
                  "seconds", "fit_seconds", "gain", "loss", "error")
BENCHMARK_TAG = "benchmark"
SYSTEMS = ("duffing", "stick-slip")
NEURAL = ("nn-cc", "nn-cc+post-sr", "nn-cc+sym", "nn-cc+sym+post-sr")
MIW_METHODS = ("nn-cc", "nn-cc+sym", "nn-cc+sym+post-sr")
#: The order of the paper's figures: increasing prior knowledge within each family.
METHOD_GROUPS = {
    "NN-CC variants": ("nn-cc", "nn-cc+post-sr", "nn-cc+sym", "nn-cc+sym+post-sr"),
    "sparse regression / polynomial": ("sindy", "sindy-cc", "poly-cc", "sindy-cc+sym", "sindy-cc+sym+post-sr"),
    "symbolic regression": ("sr", "sr-cc", "parametric"),
}
#: Stick-slip methods whose f-curves the paper fits with sqrt(bias² + (A η)²) (Table 3).
BIAS_LIMITED = ("sindy-cc", "poly-cc")
#: The scripts fit the stick-slip RMSE[x] of the NN variants at η ≤ 0.3 only (protocol §7.4).
NN_X_ETA_MAX = 0.3

#: The quick grid: minutes on a 2-core machine (Appendix F with one realisation per level).
QUICK = {"snr_db": (40.0, 20.0, 0.0), "realizations": 2, "appendix_f_realizations": 1, "forward_cases": 2,
         "miw_seeds": 10, "miw_realizations": 5, "lyapunov_time": 1000.0, "case_time_budget": 5.0,
         "sr_generations": 20}
#: ``full``: the paper's sizes (the grid itself is :data:`PAPER_SNR_DB` x 10).
FULL = {"appendix_f_realizations": 10, "forward_cases": 10, "miw_seeds": 100, "miw_realizations": 10,
        "lyapunov_time": 5000.0, "case_time_budget": 20.0, "sr_generations": None}


# ---------------------------------------------------------------------- option parsing
def parse_snr_list(text: str) -> tuple[float, ...]:
    """``"40,20,0"`` -> (40.0, 20.0, 0.0); ``inf`` allowed. Raises ConfigError on anything else."""
    parts = [p.strip() for p in str(text).split(",")]
    if not parts or any(not p for p in parts):
        raise ConfigError(f"--snr must be comma-separated dB values such as 40,20,0, got {text!r}")
    out = []
    for p in parts:
        try:
            v = float(p)
        except ValueError:
            raise ConfigError(f"--snr must be comma-separated dB values such as 40,20,0, got {text!r}") from None
        if math.isnan(v) or v == -math.inf:
            raise ConfigError(f"--snr values must be finite dB levels or inf, got {p!r}")
        out.append(v)
    return tuple(dict.fromkeys(out))


def parse_name_list(text: str, allowed: Sequence[str], what: str) -> tuple[str, ...]:
    """``"a,b"`` -> ("a", "b"), each checked against ``allowed`` (ConfigError naming the bad one)."""
    names = tuple(dict.fromkeys(p.strip() for p in str(text).split(",") if p.strip()))
    if not names:
        raise ConfigError(f"--{what} needs at least one name; choose from {', '.join(allowed)}")
    bad = [n for n in names if n not in allowed]
    if bad:
        raise ConfigError(f"unknown {what[:-1] if what.endswith('s') else what} {bad[0]!r} in --{what}; "
                          f"choose from {', '.join(allowed)}")
    return names


# ---------------------------------------------------------------------- results
def _eta(snr: float) -> float:
    return 0.0 if math.isinf(snr) else float(10.0 ** (-snr / 20.0))


def results_frame(store_path: str | os.PathLike, *, noise_on: str = "force", tag: str = BENCHMARK_TAG):
    """The rows of a benchmark store as a DataFrame with :data:`RESULT_COLUMNS`.

    Only rows with the benchmark's tag and the given noise target are kept; should a store hold
    several configurations of one (system, method, SNR, realisation, preset) job (e.g. runs with
    different numbers of validation cases), the most recently finished row wins, so the frame
    has one row per job.
    """
    import pandas as pd

    from ._store import ResultsStore

    with ResultsStore(store_path) as store:
        rows = store.rows()
    recs = []
    for r in rows:
        if r.get("tag") != tag or r.get("noise_on") != noise_on:
            continue
        ex = r.get("extra") or {}
        recs.append({
            "system": r["system"], "method": r["method"], "snr_db": float(r["snr_db"]),
            "realization": int(r["realization"]), "rmse_f1": r.get("rmse_f1"), "rmse_f2": r.get("rmse_f2"),
            "status": r["status"], "preset": r["preset"], "variant": r["variant"], "noise_on": r["noise_on"],
            "eta": r.get("eta") if r.get("eta") is not None else _eta(float(r["snr_db"])),
            "rmse_x": r.get("rmse_x_mean"), "t_sep": r.get("t_sep_mean"), "n_cases": r.get("n_cases"),
            "n_failed_cases": r.get("n_failed_cases"), "n_censored": r.get("n_censored"),
            "seconds": r.get("seconds"), "fit_seconds": ex.get("fit_seconds"), "gain": r.get("gain"),
            "loss": r.get("loss"), "error": r.get("error"), "_finished": r.get("finished_at") or "",
            "_model_path": ex.get("model_path"),
        })
    df = pd.DataFrame(recs, columns=list(RESULT_COLUMNS) + ["_finished", "_model_path"])
    if len(df):
        df = df.sort_values("_finished").drop_duplicates(
            ["system", "method", "snr_db", "realization", "preset"], keep="last")
        order = {m: i for i, m in enumerate(_all_methods())}
        df = df.assign(_o=df["method"].map(lambda m: order.get(m, 99))).sort_values(
            ["system", "preset", "_o", "snr_db", "realization"], ascending=[True, True, True, False, True])
        df = df.drop(columns="_o").reset_index(drop=True)
    for c in ("snr_db", "eta", "rmse_f1", "rmse_f2", "rmse_x", "t_sep", "seconds", "fit_seconds", "gain", "loss"):
        df[c] = pd.to_numeric(df[c], errors="coerce").astype(float)
    return df


def _all_methods() -> tuple[str, ...]:
    from ..fitting import METHODS

    return tuple(METHODS)


def _ok(df):
    return df[df["status"] == "ok"]


def ensemble_table(df, value: str, how: str = "mean") -> dict[tuple, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """``{(system, preset, method): (eta, ensemble, counts)}`` of one column over the ok rows,
    ``how`` as :func:`charcurves.metrics.ensemble_rmse` (levels in descending SNR order)."""
    from ..metrics import ensemble_by_level

    out = {}
    if value not in df.columns:  # e.g. rows without forward validation have no rmse_x
        return out
    ok = _ok(df)
    for key, g in ok.groupby(["system", "preset", "method"], sort=False):
        levels, ens, n = ensemble_by_level(g["snr_db"].to_numpy(float), g[value].to_numpy(float), how)
        out[key] = (np.array([_eta(s) for s in levels]), ens, n)
    return out


def a_fit_table(df, how: str = "mean") -> dict[tuple, dict[str, Any]]:
    """Slope-1 A and bias fits per (system, preset, method), the paper's Tables 2 and 3.

    Ensembles per level by ``how`` ("mean": the scripts, which reproduce the tables; "rms": the
    paper's Eq. 19). The scripts' masks are applied: SR at η ≤ 8 (Duffing) / ≤ 5 (stick-slip) and
    the stick-slip RMSE[x] of the NN variants at η ≤ 0.3.

    Returns
    -------
    dict
        ``{key: {"A": {"f1", "f2", "x"}, "bias": {"f1": (b, A), ...}, "levels": int}}`` (NaN where
        a term has no data).
    """
    from ..metrics import fit_bias, fit_slope_one

    out: dict[tuple, dict[str, Any]] = {}
    terms = {"f1": "rmse_f1", "f2": "rmse_f2", "x": "rmse_x"}
    tables = {t: ensemble_table(df, col, how) for t, col in terms.items()}
    keys = list(dict.fromkeys(k for tab in tables.values() for k in tab))
    for key in keys:
        system, _, method = key
        A, bias, nlev = {}, {}, 0
        for t in terms:
            eta, ens, n = tables[t].get(key, (np.array([]), np.array([]), np.array([])))
            eta_max = None
            if method == "sr":
                eta_max = paper.SR_FIT_ETA_MAX.get(system)
            if t == "x" and method in NEURAL and system == "stick-slip":
                eta_max = NN_X_ETA_MAX
            if eta.size == 0 or not np.isfinite(ens).any():
                A[t], bias[t] = float("nan"), (float("nan"), float("nan"))
                continue
            A[t] = fit_slope_one(eta, ens, eta_max=eta_max)
            bias[t] = fit_bias(eta, ens, eta_max=eta_max)
            nlev = max(nlev, int(np.sum(np.isfinite(ens) & (eta > 0))))
        out[key] = {"A": A, "bias": bias, "levels": nlev}
    return out


def performance_table(fits: Mapping[tuple, Mapping[str, Any]]) -> dict[tuple, float]:
    """Performance % per (system, preset, method) against Parametric of the same system and
    preset (paper Figs. 9, 13); stick-slip SINDy-CC / Poly-CC use their bias-fit A, as the paper."""
    from ..metrics import PERFORMANCE_TERMS, performance_percent

    out = {}
    for (system, preset, method), f in fits.items():
        # Parametric does not depend on the training preset: any preset's rows serve as reference
        ref = fits.get((system, preset, "parametric")) or next(
            (v for (s, _, m), v in fits.items() if s == system and m == "parametric"), None)
        if ref is None:
            out[(system, preset, method)] = float("nan")
            continue
        a_m = _a_used(system, method, f)
        a_r = _a_used(system, "parametric", ref)
        terms = [t for t in PERFORMANCE_TERMS.get(system, ("f1", "f2"))
                 if _finite_pos(a_m.get(t)) and _finite_pos(a_r.get(t))]
        out[(system, preset, method)] = performance_percent(a_m, a_r, terms) if terms else float("nan")
    return out


def _a_used(system: str, method: str, f: Mapping[str, Any]) -> dict[str, float]:
    a = dict(f["A"])
    if system == "stick-slip" and method in BIAS_LIMITED:
        for t in ("f1", "f2"):
            a[t] = f["bias"][t][1]
        a.pop("x", None)  # the paper gives these methods only f-terms
    return a


def _finite_pos(v) -> bool:
    try:
        return v is not None and math.isfinite(float(v)) and float(v) > 0
    except (TypeError, ValueError):
        return False


def tsep_failure_snr(df, lyapunov_time: float) -> dict[tuple, float]:
    """Per (system, preset, method): the highest SNR level whose mean t_sep is below the Lyapunov
    time (the paper's "fails at SNR ≲ X"); ``-inf`` when no level fails, NaN without t_sep data."""
    out = {}
    ok = _ok(df)
    for key, g in ok.groupby(["system", "preset", "method"], sort=False):
        lv = g.groupby("snr_db")["t_sep"].mean().dropna().sort_index(ascending=False)
        if lv.empty:
            out[key] = float("nan")
            continue
        below = lv[lv < lyapunov_time]
        out[key] = float(below.index[0]) if len(below) else -math.inf
    return out


def cost_table(df) -> dict[tuple, dict[str, float]]:
    """Median fit time and median total job time (fit + validation) per (system, preset, method)."""
    out = {}
    ok = _ok(df)
    for key, g in ok.groupby(["system", "preset", "method"], sort=False):
        out[key] = {"fit_median": float(np.nanmedian(g["fit_seconds"])) if g["fit_seconds"].notna().any()
                    else float("nan"),
                    "job_median": float(np.nanmedian(g["seconds"])) if g["seconds"].notna().any() else float("nan"),
                    "total": float(np.nansum(g["seconds"])), "jobs": int(len(g))}
    return out


def status_table(df) -> dict[tuple, dict[str, int]]:
    """Jobs ok / failed and validation cases failed / run per (system, preset, method)."""
    out = {}
    for key, g in df.groupby(["system", "preset", "method"], sort=False):
        ok = g[g["status"] == "ok"]
        out[key] = {"jobs": int(len(g)), "failed_jobs": int((g["status"] != "ok").sum()),
                    "cases": int(np.nansum(ok["n_cases"].astype(float))) if len(ok) else 0,
                    "failed_cases": int(np.nansum(ok["n_failed_cases"].astype(float))) if len(ok) else 0}
    return out


# ---------------------------------------------------------------------- the run
@dataclasses.dataclass
class BenchmarkResult:
    """What :func:`run_benchmark` produced."""

    out_dir: str
    results_csv: str
    report_md: str
    report_html: str
    n_jobs: int
    n_run: int
    n_failed: int
    seconds: float
    section_seconds: dict

    def __str__(self) -> str:
        return (f"{self.n_jobs} jobs ({self.n_run} run now, {self.n_failed} failed in the store) in "
                f"{self.seconds:.1f} s; wrote {self.results_csv}, {self.report_md}, {self.report_html}")


class _Extras:
    """``extras.json``: results of the side studies keyed by a signature of their settings."""

    def __init__(self, path: str):
        self.path = path
        try:
            with open(path, encoding="utf-8") as fh:
                self.data = json.load(fh)
        except (OSError, ValueError):
            self.data = {}

    def get(self, section: str, signature: Mapping[str, Any]):
        entry = self.data.get(section)
        if entry and entry.get("signature") == json.loads(json.dumps(signature)):
            return entry.get("value")
        return None

    def put(self, section: str, signature: Mapping[str, Any], value) -> None:
        from ..io._csv import atomic_write_bytes
        from ._store import _jsonable

        self.data[section] = {"signature": _jsonable(signature), "value": _jsonable(value)}
        atomic_write_bytes(self.path, json.dumps(self.data, indent=1).encode("utf-8"))


def _log(progress: bool, msg: str) -> None:
    if progress:
        import sys

        print(f"[charcurves benchmark] {msg}", file=sys.stderr, flush=True)


def run_benchmark(out_dir: str | os.PathLike, *, systems: Sequence[str] = SYSTEMS,
                  methods: Sequence[str] | None = None, snr_db: Sequence[float] | None = None,
                  realizations: int | None = None, full: bool = False, preset: str = "default",
                  executor: str = "local", workers: int | None = None, forward_cases: int | None = None,
                  skip: Sequence[str] = (), progress: bool = True, t_end: float = 40.0, n_points: int = 1000,
                  base_seed: int = 0, retry_failed: bool = False) -> BenchmarkResult:
    """Run the paper's study and write ``results.csv``, ``report.md`` and ``report.html`` in ``out_dir``.

    Parameters
    ----------
    out_dir : str or PathLike
        Output folder; ``results.sqlite`` there makes the run resumable (finished jobs are skipped).
    systems : sequence of str
        "duffing", "stick-slip".
    methods : sequence of str, optional
        Methods (default: all twelve).
    snr_db, realizations : optional
        The grid; default the quick grid (40, 20, 0 dB x 2), or the paper's (40..-20 dB x 10)
        with ``full``.
    full : bool
        The paper's grid and protocol sizes (10 validation cases per model, 100-run MIW ensembles,
        Lyapunov over 5000 time units).
    preset : {"default", "paper"}
        Training preset of the neural methods. Rows of both presets can share one ``out_dir``;
        the report puts them side by side.
    executor, workers
        As :func:`run_sweep` ("local" processes or "ray").
    forward_cases : int, optional
        Validation cases per model (default 2 quick, 10 full; 0 with ``skip=("forward",)``).
    skip : sequence of str
        Side studies to leave out (:data:`BENCHMARK_SECTIONS`).
    t_end, n_points : training records (40 s, 1000 samples, as the paper)
    base_seed : int
        Enters every dataset seed.
    retry_failed : bool
        Also rerun jobs stored as failed (e.g. after a worker was killed).

    Returns
    -------
    BenchmarkResult
    """
    from ..fitting import get_preset
    from ._sweep import EXECUTORS, PAPER_SNR_DB, Sweep, run_sweep

    t_start = time.perf_counter()
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
        if isinstance(realizations, bool) or int(realizations) < 1:
            raise ConfigError(f"realizations must be a positive integer, got {realizations!r}")
        sizes["realizations"] = sizes["appendix_f_realizations"] = int(realizations)
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
                  preset=preset, t_end=t_end, n_points=n_points, base_seed=base_seed, tag=BENCHMARK_TAG,
                  method_options=_sr_budget(methods, sizes["sr_generations"]))
    store = os.path.join(out_dir, "results.sqlite")
    _log(progress, f"main sweep: {len(sweep.jobs())} jobs ({len(systems)} systems x {len(methods)} methods x "
                   f"{len(sweep.snr_db)} SNR levels x {len(sweep.realizations)} realisations), "
                   f"{sizes['forward_cases']} validation cases per model")
    rep = run_sweep(sweep, store, executor=executor, workers=workers, progress=progress,
                    forward_cases=sizes["forward_cases"], case_time_budget=sizes["case_time_budget"],
                    # no per-job budget: it would count the fit too and leave a slow (paper-preset) model no
                    # validation at all; the per-case budget bounds the validation to cases x budget
                    save_models=os.path.join(out_dir, "models"),
                    retry_failed=retry_failed)
    timing["main sweep"] = time.perf_counter() - t0
    df = results_frame(store)
    csv_path = os.path.join(out_dir, "results.csv")
    _write_csv(df, csv_path)

    extras = _Extras(os.path.join(out_dir, "extras.json"))
    ctx = _Context(out_dir=out_dir, systems=systems, methods=methods, preset=preset, sizes=sizes,
                   t_end=t_end, n_points=n_points, base_seed=base_seed, full=full, executor=executor,
                   workers=workers, progress=progress, skip=tuple(skip), sweep=sweep)

    # ------------------------------------------------------------------ side studies
    if "lyapunov" not in skip and "duffing" in systems:
        t0 = time.perf_counter()
        _lyapunov(ctx, extras)
        timing["lyapunov"] = time.perf_counter() - t0
    # the paper preset trains for minutes per fit: its side studies only run with the full protocol
    slow_preset = get_preset(preset).adam_steps > 2000 and not full
    if "miw" not in skip and "duffing" in systems and any(m in methods for m in MIW_METHODS) and not slow_preset:
        t0 = time.perf_counter()
        _miw_study(ctx, extras)
        timing["miw"] = time.perf_counter() - t0
    if "sensitivity" not in skip and "nn-cc" in methods and not slow_preset:
        t0 = time.perf_counter()
        _sensitivity(ctx, extras)
        timing["sensitivity"] = time.perf_counter() - t0
    if "appendix-f" not in skip and not (slow_preset and any(m in NEURAL for m in methods)):
        t0 = time.perf_counter()
        _appendix_f(ctx)
        timing["appendix-f"] = time.perf_counter() - t0

    # ------------------------------------------------------------------ report
    t0 = time.perf_counter()
    md, page = build_report(out_dir, ctx=ctx, extras=extras, df=df, timing=timing)
    timing["report"] = time.perf_counter() - t0
    n_failed = int((df["status"] != "ok").sum()) if len(df) else 0
    res = BenchmarkResult(out_dir, csv_path, md, page, rep.n_jobs, rep.n_run, n_failed,
                          time.perf_counter() - t_start, timing)
    return res


def _sr_budget(methods: Sequence[str], generations: int | None) -> dict[str, dict]:
    """``method_options`` giving the symbolic-regression methods a smaller budget (quick grid):
    20 Operon generations instead of 40 recover the same benchmark curves about twice as fast."""
    if generations is None:
        return {}
    return {m: {"sr_options": {"generations": int(generations)}} for m in methods
            if m in ("sr", "sr-cc") or m.endswith("post-sr")}


@dataclasses.dataclass
class _Context:
    out_dir: str
    systems: tuple
    methods: tuple
    preset: str
    sizes: dict
    t_end: float
    n_points: int
    base_seed: int
    full: bool
    executor: str
    workers: int | None
    progress: bool
    skip: tuple
    sweep: Any


def _write_csv(df, path: str) -> None:
    cols = [c for c in RESULT_COLUMNS if c in df.columns]
    tmp = f"{path}.tmp{os.getpid()}"
    df[cols].to_csv(tmp, index=False)
    os.replace(tmp, path)


def _dataset(ctx: _Context, system: str, snr: float, realization: int, noise_on: str = "force"):
    """The exact noisy record the sweep's jobs of (system, snr, realization) saw."""
    from ..data import corrupt
    from ..systems import get_system
    from ._sweep import dataset_seed

    variant = ctx.sweep.variant_of(system)
    clean = get_system(system, variant).simulate(ctx.t_end, ctx.n_points)
    seed = dataset_seed("noise", system, variant, noise_on, snr, realization, ctx.base_seed)
    return clean, corrupt(clean, snr, on=noise_on, seed=seed)


def _lyapunov(ctx: _Context, extras: _Extras) -> None:
    from ..metrics import largest_lyapunov_exponent
    from ..systems import get_system

    system = get_system("duffing", ctx.sweep.variant_of("duffing"))
    sig = {"variant": system.variant, "params": system.parameters(), "t_total": ctx.sizes["lyapunov_time"]}
    if extras.get("lyapunov", sig) is not None:
        return
    _log(ctx.progress, f"Lyapunov exponent of the true Duffing over {ctx.sizes['lyapunov_time']:g} time units")
    t0 = time.perf_counter()
    p = system.parameters()
    lam = largest_lyapunov_exponent(system.f1, system.f2, system.forcing, p["x0"], p["v0"],
                                    t_total=float(ctx.sizes["lyapunov_time"]), rtol=1e-9, atol=1e-11)
    extras.put("lyapunov", sig, {"lambda_max": lam, "T_L": 1.0 / lam if lam > 0 else float("nan"),
                                 "seconds": time.perf_counter() - t0})


def _estimator(ctx: _Context, system: str, method: str, preset=None, **extra_opts):
    from ..fitting import CharacteristicCurves

    opts = ctx.sweep.fit_options(system, method)
    opts.update(extra_opts)
    opts.setdefault("threads", 1)
    return CharacteristicCurves(method=method, preset=preset if preset is not None else ctx.preset, **opts)


def _miw_study(ctx: _Context, extras: _Extras) -> None:
    """Table 1: f2 residuals at the training points, (i) K training seeds on one 20 dB dataset,
    (ii) one run on each of R noise realisations; MIW_range and MIW_99 of each ensemble."""
    from ..metrics import curve_residuals, miw
    from ..systems import get_system

    truth = get_system("duffing", ctx.sweep.variant_of("duffing")).true_curves()
    k, r = int(ctx.sizes["miw_seeds"]), int(ctx.sizes["miw_realizations"])
    for method in [m for m in MIW_METHODS if m in ctx.methods]:
        sig = {"method": method, "preset": ctx.preset, "seeds": k, "realizations": r, "base_seed": ctx.base_seed,
               "n_points": ctx.n_points, "t_end": ctx.t_end}
        if extras.get(f"miw:{method}:{ctx.preset}", sig) is not None:
            continue
        _log(ctx.progress, f"MIW ensembles of {method}: {k} seeds on one dataset, {r} noise realisations (20 dB)")
        t0 = time.perf_counter()
        est = _estimator(ctx, "duffing", method)
        _, data0 = _dataset(ctx, "duffing", 20.0, 0)
        seed_models = est.fit_many([data0] * k, seeds=list(range(k)))
        z, res = zip(*(curve_residuals(m, data0, truth, "f2") for m in seed_models))
        m_seeds = miw(list(z), list(res))
        t1 = time.perf_counter()
        datasets = [_dataset(ctx, "duffing", 20.0, i)[1] for i in range(r)]
        real_models = est.fit_many(datasets, seeds=list(range(r)))
        z2, res2 = zip(*(curve_residuals(m, d, truth, "f2") for m, d in zip(real_models, datasets)))
        m_real = miw(list(z2), list(res2))
        extras.put(f"miw:{method}:{ctx.preset}", sig, {
            "seeds": {"miw_range": m_seeds.miw_range, "miw_99": m_seeds.miw_99, "n": k, "seconds": t1 - t0},
            "realizations": {"miw_range": m_real.miw_range, "miw_99": m_real.miw_99, "n": r,
                             "seconds": time.perf_counter() - t1}})


#: Appendix C variations tried on the run's preset (a few of the paper's rows that are quick here).
SENSITIVITY_VARIATIONS: tuple[tuple[str, Any], ...] = (
    ("activation", "softplus"), ("activation", "tanh"), ("activation", "relu"),
    ("adam_lr", 1e-3), ("adam_lr", 1e-2), ("adam_lr", 1e-1),
    ("width", 5), ("width", 10), ("width", 25),
)
#: Added with ``full``: a 100-wide network costs ~1-2 min per fit with the default preset's LM.
SENSITIVITY_FULL_EXTRA: tuple[tuple[str, Any], ...] = (("width", 100),)


def _sensitivity(ctx: _Context, extras: _Extras) -> None:
    """Appendix C, feasible part: NN-CC on one 20 dB dataset per system, one setting changed at a time."""
    from ..fitting import get_preset
    from ..metrics import curve_errors
    from ..systems import get_system

    base = get_preset(ctx.preset)
    for system in ctx.systems:
        variations = SENSITIVITY_VARIATIONS + (SENSITIVITY_FULL_EXTRA if ctx.full else ())
        sig = {"system": system, "preset": base.to_dict(), "base_seed": ctx.base_seed, "n_points": ctx.n_points,
               "variations": [list(v) for v in variations]}
        if extras.get(f"sensitivity:{system}:{ctx.preset}", sig) is not None:
            continue
        _log(ctx.progress, f"Appendix C sensitivity of NN-CC on {system} (20 dB, one dataset)")
        truth = get_system(system, ctx.sweep.variant_of(system)).true_curves()
        _, data = _dataset(ctx, system, 20.0, 0)
        rows = []
        for setting, value in variations:
            change = {"hidden": (int(value),) * len(base.hidden)} if setting == "width" else {setting: value}
            preset = base.replace(name=f"{base.name}*", **change)
            t0 = time.perf_counter()
            try:
                model = _estimator(ctx, system, "nn-cc", preset=preset).fit(data).model_
                err = curve_errors(model, truth)
                rows.append({"setting": setting, "value": value, "loss": float(model.loss), "rmse_f1": err.get("f1"),
                             "rmse_f2": err.get("f2"), "seconds": time.perf_counter() - t0,
                             "is_default": _is_base(base, setting, value)})
            except Exception as exc:  # noqa: BLE001 - a diverging setting is a result, not a crash
                rows.append({"setting": setting, "value": value, "error": f"{type(exc).__name__}: {exc}"[:300],
                             "seconds": time.perf_counter() - t0, "is_default": _is_base(base, setting, value)})
        extras.put(f"sensitivity:{system}:{ctx.preset}", sig, rows)


def _is_base(base, setting: str, value) -> bool:
    if setting == "width":
        return all(h == int(value) for h in base.hidden)
    return getattr(base, setting) == value


def _appendix_f(ctx: _Context) -> None:
    """Appendix F: noise on x, derivatives by Savitzky-Golay, CC errors only (its own store)."""
    from ._sweep import Sweep, run_sweep

    reals = min(int(ctx.sizes["realizations"]), int(ctx.sizes["appendix_f_realizations"]))
    sweep = Sweep(systems=ctx.systems, methods=ctx.methods, snr_db=ctx.sizes["snr_db"],
                  realizations=reals, noise_on="state", options={"derivatives": "savgol"},
                  method_options=_sr_budget(ctx.methods, ctx.sizes["sr_generations"]),
                  preset=ctx.preset, t_end=ctx.t_end, n_points=ctx.n_points, base_seed=ctx.base_seed,
                  tag=BENCHMARK_TAG)
    _log(ctx.progress, f"Appendix F (noise on x, Savitzky-Golay): {len(sweep.jobs())} jobs")
    store = os.path.join(ctx.out_dir, "appendix_f.sqlite")
    run_sweep(sweep, store, executor=ctx.executor, workers=ctx.workers, progress=ctx.progress)
    _write_csv(results_frame(store, noise_on="state"), os.path.join(ctx.out_dir, "appendix_f.csv"))


# ---------------------------------------------------------------------- the report
def build_report(out_dir: str | os.PathLike, *, ctx: _Context | None = None, extras: _Extras | None = None,
                 df=None, timing: Mapping[str, float] | None = None) -> tuple[str, str]:
    """Write ``report.md`` and ``report.html`` from what ``out_dir`` holds (the stores and
    ``extras.json``); sections without data say so. Returns the two paths."""
    from ..report._html import Report
    from . import _report_sections as sections

    out_dir = os.fspath(out_dir)
    if df is None:
        df = results_frame(os.path.join(out_dir, "results.sqlite"))
    if extras is None:
        extras = _Extras(os.path.join(out_dir, "extras.json"))
    rep = Report("charcurves benchmark: the paper's study")
    sections.write_all(rep, df=df, ctx=ctx, extras=extras, out_dir=out_dir, timing=dict(timing or {}))
    return rep.write(out_dir, "report")
