"""The job function of a sweep: build the noisy dataset, fit, score, return result rows.

It runs unchanged in the driver (one worker), in a local process pool or as a Ray task, and
never raises for a failing job: every job comes back as a row with status "ok" or "failed".
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import os
import socket
import time
import traceback
from typing import Any

__all__ = ["Job", "RunSettings", "run_unit", "init_worker"]


@dataclasses.dataclass(frozen=True)
class Job:
    """One fit of one method on one noisy dataset (one row of the results store).

    Examples
    --------
    >>> from charcurves.experiments import Job, Sweep
    >>> job = Sweep(methods=["parametric"], snr_db=[20], realizations=1).jobs()[0]
    >>> isinstance(job, Job), job.label(), round(job.eta, 3)
    (True, 'duffing/parametric/force@20dB#0', 0.1)
    """

    system: str
    variant: str
    method: str
    noise_on: str
    snr_db: float
    realization: int
    preset: str
    config: str
    tag: str
    noise_seed: int
    fit_seed: int
    validation_seed: int
    #: CharacteristicCurves keyword arguments (without ``method`` and ``preset``)
    fit_kwargs: tuple = ()
    #: the preset object when it is not a named one (a TrainingPreset), else None
    preset_obj: Any = None
    noise_reference: str | None = None
    t_end: float = 40.0
    n_points: int = 1000

    @property
    def key(self) -> tuple:
        return (self.system, self.variant, self.method, self.noise_on, float(self.snr_db), int(self.realization),
                self.preset, self.config, self.tag)

    @property
    def eta(self) -> float:
        return 0.0 if math.isinf(self.snr_db) else float(10.0 ** (-self.snr_db / 20.0))

    def key_dict(self) -> dict[str, Any]:
        return {"system": self.system, "variant": self.variant, "method": self.method, "noise_on": self.noise_on,
                "snr_db": float(self.snr_db), "realization": int(self.realization), "preset": self.preset,
                "config": self.config, "tag": self.tag}

    def label(self) -> str:
        return f"{self.system}/{self.method}/{self.noise_on}@{self.snr_db:g}dB#{self.realization}"


@dataclasses.dataclass(frozen=True)
class RunSettings:
    """How jobs are evaluated and run (not part of a job's identity unless noted in its config).

    Examples
    --------
    >>> from charcurves.experiments import RunSettings, Sweep, run_unit
    >>> settings = RunSettings(forward_cases=0, torch_threads=1)  # fits only, no forward validation
    >>> settings.eps, settings.case_time_budget
    (0.2, 20.0)
    >>> [row] = run_unit(Sweep(methods=["parametric"], snr_db=[20], realizations=1).jobs(), settings)
    >>> row["status"]
    'ok'
    """

    forward_cases: int = 0
    eps: float = 0.2
    box_margin: float | None = 1.0
    case_time_budget: float = 20.0
    time_budget_per_job: float | None = None
    max_attempts: int = 1000
    max_failed_cases: int | None = None
    sim_rtol: float | None = None
    sim_atol: float | None = None
    torch_threads: int | None = 1
    #: return each fitted model's files (bytes) with its row, for the driver to write
    return_models: bool = False


# ---------------------------------------------------------------------- worker setup
def init_worker(threads: int | None = 1, parent_pid: int | None = None) -> None:
    """Initialiser of pool workers: thread counts, and exit when the parent process dies."""
    if threads is not None:
        for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
            os.environ[var] = str(int(threads))
    if parent_pid is not None:
        import threading

        def watch():
            while True:
                time.sleep(1.0)
                if os.getppid() != parent_pid:
                    os._exit(1)

        threading.Thread(target=watch, name="charcurves-parent-watch", daemon=True).start()


@functools.lru_cache(maxsize=16)
def _system(name: str, variant: str):
    from ..systems import get_system

    return get_system(name, variant)


@functools.lru_cache(maxsize=16)
def _clean(name: str, variant: str, t_end: float, n_points: int):
    return _system(name, variant).simulate(t_end, n_points)


def _error_text(exc: BaseException) -> str:
    return f"{type(exc).__name__}: {exc}"


def _tb(exc: BaseException) -> str:
    lines = traceback.format_exception(type(exc), exc, exc.__traceback__)
    return "".join(lines)[-4000:]


def _now() -> str:
    import datetime as _dt

    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="milliseconds")


def _small_info(info: dict) -> dict:
    from ._store import _jsonable

    out = {}
    for k, v in (info or {}).items():
        j = _jsonable(v)
        if len(json.dumps(j)) <= 2000:
            out[str(k)] = j
    return out


def _curve_summary(model) -> dict:
    out = {}
    for name, c in model.curves.items():
        entry: dict[str, Any] = {"domain": list(getattr(c, "domain", ())), "kind": getattr(c, "kind", None)}
        try:
            expr = c.expression()
            entry["expression"] = None if expr is None else str(expr)
        except Exception:  # noqa: BLE001 - a summary must not fail the job
            entry["expression"] = None
        try:
            comps = c.components()
            if comps:
                entry["components"] = comps
        except Exception:  # noqa: BLE001
            pass
        out[name] = entry
    return out


def _base_row(job: Job) -> dict[str, Any]:
    row = job.key_dict()
    row.update(eta=job.eta, noise_seed=job.noise_seed, fit_seed=job.fit_seed, host=socket.gethostname(),
               pid=os.getpid())
    return row


def _failed_row(job: Job, exc: BaseException | str, started: str, seconds: float, stage: str,
                extra: dict | None = None) -> dict[str, Any]:
    row = _base_row(job)
    text = exc if isinstance(exc, str) else _error_text(exc)
    ex = {"stage": stage, **(extra or {})}
    if not isinstance(exc, str):
        ex["traceback"] = _tb(exc)
    row.update(status="failed", error=text, seconds=seconds, started_at=started, finished_at=_now(), extra=ex)
    return row


def _estimator(job: Job, settings: RunSettings):
    from ..fitting import CharacteristicCurves

    kwargs = dict(job.fit_kwargs)
    kwargs.setdefault("threads", settings.torch_threads)
    if "derivatives" in kwargs:  # the sweeps' stored name (part of each job's signature) of the differentiator
        kwargs["differentiator"] = kwargs.pop("derivatives")
    preset = job.preset_obj if job.preset_obj is not None else job.preset
    return CharacteristicCurves.from_method(job.method, preset=preset, **kwargs)


def _is_neural(method: str) -> bool:
    from ..fitting import METHODS

    return METHODS.get(method, {}).get("representation") == "neural"


def _slug(job: Job) -> str:
    """The folder name of a job's saved model (readable, and unique by a hash of config and tag)."""
    import hashlib
    import re

    h = hashlib.blake2b(json.dumps([job.config, job.tag]).encode(), digest_size=4).hexdigest()
    raw = f"{job.system}_{job.variant}_{job.method}_{job.noise_on}_{job.snr_db:g}dB_r{job.realization}_{job.preset}_{h}"
    return re.sub(r"[^A-Za-z0-9_.+-]", "-", raw)


# ---------------------------------------------------------------------- the job function
def run_unit(jobs: list[Job], settings: RunSettings) -> list[dict[str, Any]]:
    """Run a unit of jobs (one job, or a batch of neural jobs trained together) and return
    one result row per job. Never raises for a failing job.

    Examples
    --------
    >>> from charcurves.experiments import RunSettings, Sweep, run_unit
    >>> [row] = run_unit(Sweep(methods=["parametric"], snr_db=[20], realizations=1).jobs(), RunSettings())
    >>> row["status"], row["method"], row["rmse_f2"] < 0.01
    ('ok', 'parametric', True)
    """
    if settings.torch_threads is not None:
        try:
            import torch

            torch.set_num_threads(int(settings.torch_threads))
        except Exception:  # noqa: BLE001 - torch missing only matters to neural methods
            pass
    rows: dict[int, dict[str, Any]] = {}
    started = _now()
    t_unit = time.perf_counter()

    # ------------------------------------------------------------------ datasets
    from ..data import corrupt

    datasets: dict[int, Any] = {}
    data_seconds: dict[int, float] = {}
    for i, job in enumerate(jobs):
        t0 = time.perf_counter()
        try:
            clean = _clean(job.system, job.variant, float(job.t_end), int(job.n_points))
            kw = {} if job.noise_reference is None else {"reference": job.noise_reference}
            datasets[i] = corrupt(clean, job.snr_db, on=job.noise_on, seed=job.noise_seed, **kw)
        except Exception as exc:  # noqa: BLE001
            rows[i] = _failed_row(job, exc, started, time.perf_counter() - t0, "data")
        data_seconds[i] = time.perf_counter() - t0

    # ------------------------------------------------------------------ fits
    models: dict[int, Any] = {}
    fit_seconds: dict[int, float] = {}
    batch_of: dict[int, int] = {}
    by_method: dict[str, list[int]] = {}
    for i in range(len(jobs)):
        if i in datasets:
            by_method.setdefault(jobs[i].method, []).append(i)
    for plain, distilled in _post_sr_pairs(jobs, by_method):
        _fit_pair(jobs, plain, distilled, datasets, settings, models, fit_seconds, batch_of)
    from ..fitting import shared_fit_base

    # the methods others extend first: their searches are the ones the extensions then find done
    for method, idx in sorted(by_method.items(), key=lambda kv: shared_fit_base(kv[0]) is not None):
        pending = [i for i in idx if i not in models]
        _fit_jobs(jobs, pending, datasets, settings, started, models, fit_seconds, batch_of, rows)
    _count_shared_searches(jobs, by_method, fit_seconds)

    # ------------------------------------------------------------------ scoring
    for i, model in models.items():
        job = jobs[i]
        t0 = time.perf_counter()
        try:
            rows[i] = _score(job, model, settings, started, fit_seconds[i] + data_seconds.get(i, 0.0), batch_of[i],
                             t_unit)
        except Exception as exc:  # noqa: BLE001
            rows[i] = _failed_row(job, exc, started, fit_seconds[i] + time.perf_counter() - t0, "evaluate")
    return [rows[i] for i in range(len(jobs))]


def _post_sr_pairs(jobs: list[Job], by_method: dict[str, list[int]]) -> list[tuple[list[int], list[int]]]:
    """(plain, distilled) job indices on the same records: X and "X+post-sr" (one fit, finished twice)."""
    from ..fitting import METHODS, shared_fit_base

    out = []
    for method, idx in by_method.items():
        base = shared_fit_base(method)
        if base is None or base not in by_method or not METHODS[method].get("post_sr"):
            continue
        plain_of = {(jobs[i].noise_seed, jobs[i].fit_seed): i for i in by_method[base]}
        pairs = [(plain_of[(jobs[i].noise_seed, jobs[i].fit_seed)], i) for i in idx
                 if (jobs[i].noise_seed, jobs[i].fit_seed) in plain_of]
        if pairs:
            out.append(([p for p, _ in pairs], [d for _, d in pairs]))
    return out


def _fit_pair(jobs, plain, distilled, datasets, settings, models, fit_seconds, batch_of) -> None:
    """Fit X and X+post-sr from one training; on any failure leave them to be fitted one method at a time.

    Each job's ``fit_seconds`` is what a fit of its own method costs: the training's share for both, plus
    the job's own post-SR for the distilled one (the training is counted for each method that uses it).
    """
    from ..fitting import fit_with_post_sr

    t0 = time.perf_counter()
    try:
        a, b = fit_with_post_sr(_estimator(jobs[plain[0]], settings), _estimator(jobs[distilled[0]], settings),
                                [datasets[i] for i in plain], seeds=[jobs[i].fit_seed for i in plain])
    except Exception:  # noqa: BLE001 - the per-method path isolates and records the failure
        return
    post = [float(m.info.get("post_sr_seconds", 0.0)) for m in b]
    share = max(0.0, time.perf_counter() - t0 - sum(post)) / len(plain)
    for i, j, ma, mb, p in zip(plain, distilled, a, b, post):
        models[i], fit_seconds[i], batch_of[i] = ma, share, len(plain)
        models[j], fit_seconds[j], batch_of[j] = mb, share + p, len(plain)


def _count_shared_searches(jobs, by_method, fit_seconds) -> None:
    """sr-cc+refit after sr-cc on the same record finds every search done (the engine remembers them):
    its ``fit_seconds`` gets sr-cc's, so that it says what the method costs on its own."""
    from ..fitting import METHODS, shared_fit_base

    for method, idx in by_method.items():
        base = shared_fit_base(method)
        if base is None or base not in by_method or METHODS[method].get("post_sr"):
            continue
        base_of = {(jobs[i].noise_seed, jobs[i].fit_seed): i for i in by_method[base] if i in fit_seconds}
        for i in idx:
            b = base_of.get((jobs[i].noise_seed, jobs[i].fit_seed))
            if b is not None and i in fit_seconds:
                fit_seconds[i] += fit_seconds[b]


def _fit_jobs(jobs, pending, datasets, settings, started, models, fit_seconds, batch_of, rows) -> None:
    """Fit jobs of one method: neural ones in one batch (one by one after a failure), the others one by one."""
    batched = len(pending) > 1 and _is_neural(jobs[pending[0]].method)
    if batched:
        t0 = time.perf_counter()
        try:
            est = _estimator(jobs[pending[0]], settings)
            fitted = est.fit_many([datasets[i] for i in pending], seeds=[jobs[i].fit_seed for i in pending])
            share = (time.perf_counter() - t0) / len(pending)
            for i, m in zip(pending, fitted):
                models[i], fit_seconds[i], batch_of[i] = m, share, len(pending)
            return
        except Exception as exc:  # noqa: BLE001
            from .._errors import ConfigError

            if isinstance(exc, (ConfigError, TypeError)):  # the same for every member: no retry
                for i in pending:
                    rows[i] = _failed_row(jobs[i], exc, started, (time.perf_counter() - t0) / len(pending), "fit",
                                          {"batch_size": len(pending)})
                return
            # otherwise fall through: fit the members one by one to isolate the failing dataset
    for i in pending:
        t0 = time.perf_counter()
        try:
            est = _estimator(jobs[i], settings)
            models[i] = est.fit_many([datasets[i]], seeds=[jobs[i].fit_seed])[0]
            fit_seconds[i], batch_of[i] = time.perf_counter() - t0, 1
        except Exception as exc:  # noqa: BLE001
            rows[i] = _failed_row(jobs[i], exc, started, time.perf_counter() - t0, "fit")


def _score(job: Job, model, settings: RunSettings, started: str, fit_seconds: float, batch_size: int,
           t_unit: float) -> dict[str, Any]:
    from ..metrics import curve_errors

    t0 = time.perf_counter()
    system = _system(job.system, job.variant)
    errors = curve_errors(model, system.true_curves())
    row = _base_row(job)
    extra: dict[str, Any] = {
        "batch_size": batch_size,
        "fit_seconds": fit_seconds,
        "curves": _curve_summary(model),
        "model_info": _small_info(getattr(model, "info", {})),
        "validation_seed": job.validation_seed,
    }
    row.update(rmse_f1=errors.get("f1"), rmse_f2=errors.get("f2"), gain=float(model.gain), loss=float(model.loss))
    if settings.forward_cases > 0:
        from ..metrics import cached_validation_cases, evaluate_forward, training_box

        budget = None
        if settings.time_budget_per_job is not None:
            budget = max(0.0, float(settings.time_budget_per_job) - fit_seconds)
        clean = _clean(job.system, job.variant, float(job.t_end), int(job.n_points))
        t_cases = time.perf_counter()
        cases = cached_validation_cases(system, settings.forward_cases, seed=job.validation_seed,
                                        max_attempts=settings.max_attempts, box=training_box(clean))
        extra["validation_set_seconds"] = time.perf_counter() - t_cases  # ~0 when cached in this process
        ev = evaluate_forward(model, system, cases, eps=settings.eps, box_margin=settings.box_margin,
                              case_time_budget=settings.case_time_budget, time_budget=budget,
                              max_failed=settings.max_failed_cases, rtol=settings.sim_rtol,
                              atol=settings.sim_atol)
        s = ev.summary()
        row.update(t_sep_mean=s["t_sep_mean"], rmse_x_mean=s["rmse_x_mean"], n_cases=s["n_cases"],
                   n_failed_cases=s["n_failed_cases"], n_censored=s["n_censored"])
        extra["forward"] = {"summary": s, "cases": ev.to_records(), "n_requested": settings.forward_cases,
                            "n_attempts": cases.n_attempts, "box": cases.box}
    if settings.return_models:  # the driver writes them (model_name under the sweep's models folder)
        from ._models import MODEL_FILES_KEY, model_files

        row[MODEL_FILES_KEY] = model_files(model)
        extra["model_name"] = _slug(job)
    extra["eval_seconds"] = time.perf_counter() - t0
    row.update(status="ok", error=None, seconds=fit_seconds + extra["eval_seconds"], started_at=started,
               finished_at=_now(), extra=extra)
    if settings.time_budget_per_job is not None and row["seconds"] > settings.time_budget_per_job:
        extra["over_budget"] = True
    return row


def failed_rows(jobs: list[Job], message: str) -> list[dict[str, Any]]:
    """Rows of a unit that never returned (its worker died)."""
    now = _now()
    return [_failed_row(j, message, now, float("nan"), "worker") for j in jobs]

