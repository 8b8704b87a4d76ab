"""Noise sweeps: systems × methods × SNR levels × noise realisations, resumable and parallel.

A :class:`Sweep` names what to run; :func:`run_sweep` runs the jobs that its results store does not hold yet, in the
driver, in a local process pool or as Ray tasks, and writes one row per job as soon as it finishes. Every method sees
the identical noisy dataset of a (system, SNR, realisation): the noise seed is a stable hash of the dataset's identity,
never of the method. Neural jobs of one (system, method, noise target, preset) are trained together, all realisations
of an SNR level in one batched computation (``CharacteristicCurves.fit_many``). A resumed sweep trains what is
left of a level, perhaps a single record, and a batch of one can differ from a larger batch in the last bits
(see ``charcurves.train._problem``); ``run_sweep``'s ``batch`` and ``max_batch`` choose the batches.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from .._errors import ConfigError
from ._executors import Progress, StopSignals, SweepInterrupted, ray_address, run_pool, run_ray
from ._models import write_row_model
from ._runner import Job, RunSettings, run_unit
from ._units import plan_units
from ._store import ResultsStore, _jsonable

__all__ = ["Sweep", "SweepReport", "paper_grid", "quick_grid", "PAPER_SNR_DB", "QUICK_SNR_DB", "dataset_seed",
           "default_fit_options", "plan_units", "run_sweep", "EXECUTORS", "SweepInterrupted"]

#: The paper's grid: 40, 39, ..., −20 dB (61 levels), 10 realisations each.
PAPER_SNR_DB: tuple[float, ...] = tuple(float(s) for s in range(40, -21, -1))
#: A quick grid for smoke runs.
QUICK_SNR_DB: tuple[float, ...] = (40.0, 20.0, 0.0)
EXECUTORS = ("local", "ray")


def paper_grid(include_clean: bool = False) -> dict[str, Any]:
    """``{"snr_db": (40, 39, ..., -20), "realizations": 10}`` (with ``inf`` first when ``include_clean``, as the
    NN-CC and SR-CC scripts prepend 10 noise-free runs); pass it to :class:`Sweep` with ``**paper_grid()``.

    Examples
    --------
    >>> from charcurves.experiments import paper_grid
    >>> len(paper_grid()["snr_db"]), paper_grid(include_clean=True)["snr_db"][:2], paper_grid()["realizations"]
    (61, (inf, 40.0), 10)
    """
    snr = ((math.inf,) if include_clean else ()) + PAPER_SNR_DB
    return {"snr_db": snr, "realizations": 10}


def quick_grid() -> dict[str, Any]:
    """``{"snr_db": (40, 20, 0), "realizations": 2}``.

    Examples
    --------
    >>> from charcurves.experiments import quick_grid
    >>> quick_grid()
    {'snr_db': (40.0, 20.0, 0.0), 'realizations': 2}
    """
    return {"snr_db": QUICK_SNR_DB, "realizations": 2}


def _snr_text(snr: float) -> str:
    return "inf" if math.isinf(snr) else repr(float(snr))


def dataset_seed(purpose: str, system: str, variant: str, noise_on: str | None, snr_db: float | None,
                 realization: int, base_seed: int = 0, bits: int = 63) -> int:
    """A stable seed from a dataset's identity (blake2b of a canonical string).

    ``purpose`` separates the streams ("noise", "fit", "validation"); no method enters, so every method
    sees the same noise, initialisation seed and validation cases (drawn afresh per SNR level, as the paper's).

    Examples
    --------
    >>> from charcurves.experiments import dataset_seed
    >>> dataset_seed("noise", "duffing", "paper", "force", 20.0, 0)
    6385019594570048337
    """
    text = json.dumps([purpose, system, variant, noise_on, None if snr_db is None else _snr_text(float(snr_db)),
                       int(realization), int(base_seed)])
    h = int.from_bytes(hashlib.blake2b(text.encode(), digest_size=8).digest(), "big")
    return h >> (64 - bits)


def default_fit_options(system, method: str) -> dict[str, Any]:
    """Method settings a system needs by default: Parametric gets the system's true basis (the
    paper's Duffing basis ``f1 = z; f2 = z, z**3``; stick-slip ``f1 = z, sign(z)`` for Coulomb
    friction, ``tanh(500 z)`` for the tanh law of the scripts).

    Examples
    --------
    >>> from charcurves import experiments, systems
    >>> experiments.default_fit_options(systems.get_system("stick-slip"), "parametric")
    {'basis': 'f1=z, sign(z); f2=z'}
    """
    if method == "parametric" and getattr(system, "name", "") == "stick-slip":
        if getattr(system, "friction", "coulomb") == "coulomb":
            return {"basis": "f1=z, sign(z); f2=z"}
        return {"basis": f"f1=z, tanh({float(system.tanh_scale):g}*z); f2=z"}
    if method == "parametric" and getattr(system, "name", "") == "duffing":
        return {"basis": "f1=z; f2=z, z**3"}
    return {}


@dataclasses.dataclass(frozen=True)
class Sweep:
    """What a sweep runs.

    Parameters
    ----------
    systems : sequence of str
        Benchmark systems ("duffing", "stick-slip").
    methods : sequence of str
        Method names (:data:`charcurves.METHODS`).
    snr_db : sequence of float
        SNR levels in dB (``inf``: noise-free).
    realizations : int or sequence of int
        Noise realisations per level (an int n means 0..n−1).
    noise_on : {"force", "state"}
        Noise target (main text / Appendix F).
    preset : str or TrainingPreset
        Training preset of neural methods ("default", "paper" or an object; an object that is not a named preset is
        recorded with all its settings).
    variant : str or mapping
        System variant ("paper", "scripts"...), or ``{system: variant}``.
    options : mapping
        ``CharacteristicCurves.from_method`` keyword arguments for every method (e.g. ``{"differentiator": "savgol"}``;
        ``derivatives`` is read as ``differentiator``).
    method_options : mapping
        Per-method keyword arguments, ``{method: {...}}``; they override ``options`` and the system defaults
        (:func:`default_fit_options`).
    noise_reference : {"std", "rms"}, optional
        Size of the clean forcing for the SNR (default: the library's "std"; the scripts: "rms").
    t_end, n_points : training record (40 s, 1000 samples)
    base_seed : int
        Enters every derived seed; change it for an independent replicate of the whole sweep (0 ... 2**32 - 1).
    tag : str
        A free label that is part of every job's identity (separates campaigns in one store).

    Examples
    --------
    >>> from charcurves.experiments import Sweep
    >>> len(Sweep(systems=["duffing"], methods=["parametric"], snr_db=[20, 0], realizations=2).jobs())
    4
    >>> a, b = Sweep(methods=["parametric"]).jobs()[0], Sweep(methods=["nn-cc"]).jobs()[0]
    >>> a.noise_seed == b.noise_seed  # every method sees the same noisy record
    True
    """

    systems: Sequence[str] = ("duffing",)
    methods: Sequence[str] = ("parametric", "nn-cc", "nn-cc+sym")
    snr_db: Sequence[float] = QUICK_SNR_DB
    realizations: int | Sequence[int] = 2
    noise_on: str = "force"
    preset: Any = "default"
    variant: str | Mapping[str, str] = "paper"
    options: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    method_options: Mapping[str, Mapping[str, Any]] = dataclasses.field(default_factory=dict)
    noise_reference: str | None = None
    t_end: float = 40.0
    n_points: int = 1000
    base_seed: int = 0
    tag: str = ""

    def __post_init__(self) -> None:
        from ..data import NOISE_TARGETS
        from ..fitting import METHODS
        from ..fitting import get_preset
        from ..systems import get_system

        set_ = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731 - frozen dataclass
        for name in ("systems", "methods"):
            value = getattr(self, name)
            if isinstance(value, str):
                value = (value,)
            set_(name, tuple(str(v) for v in value))
            if not getattr(self, name):
                raise ConfigError(f"a sweep needs at least one entry in {name}")
        unknown = [m for m in self.methods if m not in METHODS]
        if unknown:
            raise ConfigError(f"unknown method(s) {unknown}; choose from {', '.join(METHODS)}")
        snr = (self.snr_db,) if isinstance(self.snr_db, (int, float)) else tuple(self.snr_db)
        try:
            snr = tuple(float(s) for s in snr)
        except (TypeError, ValueError):
            raise ConfigError(f"snr_db must be numbers of decibels (inf allowed), got {self.snr_db!r}") from None
        if not snr or any(math.isnan(s) or s == -math.inf for s in snr):
            raise ConfigError("snr_db must be a non-empty list of dB values (inf for noise-free), without NaN or -inf")
        set_("snr_db", tuple(dict.fromkeys(snr)))
        reals = self.realizations
        if isinstance(reals, bool):
            raise ConfigError("realizations must be an int or a list of ints")
        reals = tuple(range(int(reals))) if isinstance(reals, int) else tuple(int(r) for r in reals)
        if not reals or any(r < 0 for r in reals):
            raise ConfigError("realizations must give at least one non-negative realisation index")
        set_("realizations", tuple(dict.fromkeys(reals)))
        if self.noise_on not in NOISE_TARGETS:
            raise ConfigError(f"noise_on must be one of {', '.join(NOISE_TARGETS)}, got {self.noise_on!r}")
        get_preset(self.preset)  # validates the name
        for s in self.systems:
            get_system(s, self.variant_of(s))
        for k in ("method", "preset", "random_state"):
            if k in self.options or any(k in (o or {}) for o in self.method_options.values()):
                raise ConfigError(f"{k!r} is set by the sweep itself; remove it from options/method_options")
        bad = [m for m in self.method_options if m not in self.methods]
        if bad:
            raise ConfigError(f"method_options names methods not in the sweep: {bad}")
        if isinstance(self.base_seed, bool) or not isinstance(self.base_seed, int) or \
                not 0 <= self.base_seed <= 2**32 - 1:
            raise ConfigError(f"base_seed must be an integer from 0 to {2**32 - 1} (32 bits, what every random "
                              f"generator charcurves seeds accepts), got {self.base_seed!r}")
        set_("options", dict(self.options))
        set_("method_options", {k: dict(v or {}) for k, v in self.method_options.items()})

    # ------------------------------------------------------------------ helpers
    def variant_of(self, system: str) -> str:
        if isinstance(self.variant, Mapping):
            return str(self.variant.get(system, "paper"))
        return str(self.variant)

    @property
    def preset_name(self) -> str:
        from ..fitting import PRESETS

        p = self.preset
        if isinstance(p, str):
            return p
        named = PRESETS.get(p.name)
        return p.name if named == p else f"{p.name}*"

    def _preset_config(self) -> dict | None:
        from ..fitting import PRESETS

        p = self.preset
        if isinstance(p, str) or PRESETS.get(p.name) == p:
            return None
        return p.to_dict()

    def fit_options(self, system: str, method: str) -> dict[str, Any]:
        """The ``CharacteristicCurves.from_method`` keyword arguments one method gets on one system."""
        from ..systems import get_system

        opts = default_fit_options(get_system(system, self.variant_of(system)), method)
        opts.update(self.options)
        opts.update(self.method_options.get(method, {}))
        return opts

    def to_dict(self) -> dict[str, Any]:
        d = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        d["preset"] = self.preset_name
        d["preset_settings"] = self._preset_config()
        return _jsonable(d)

    def jobs(self, evaluation: Mapping[str, Any] | None = None) -> list[Job]:
        """All jobs, system-major, then SNR level, method and realisation.

        ``evaluation``: settings of the forward validation that belong to a job's identity
        (number of cases, ε, box margin); jobs with other settings are other jobs.
        """
        out = []
        preset_cfg = self._preset_config()
        preset_obj = None if isinstance(self.preset, str) else self.preset
        for system in self.systems:
            variant = self.variant_of(system)
            for method in self.methods:
                opts = self.fit_options(system, method)
                cfg: dict[str, Any] = {"fit": opts, "data": {"t_end": float(self.t_end), "n_points": int(self.n_points),
                                                             "noise_reference": self.noise_reference}}
                if preset_cfg is not None:
                    cfg["preset_settings"] = preset_cfg
                if self.base_seed:
                    cfg["base_seed"] = int(self.base_seed)
                if evaluation:
                    cfg["forward"] = dict(evaluation)
                config = json.dumps(_jsonable(cfg), sort_keys=True, separators=(",", ":"))
                assert not isinstance(self.realizations, int)  # __post_init__ made it a tuple
                for snr in self.snr_db:
                    for r in self.realizations:
                        out.append(Job(
                            system=system, variant=variant, method=method, noise_on=self.noise_on, snr_db=snr,
                            realization=r, preset=self.preset_name, config=config, tag=str(self.tag),
                            noise_seed=dataset_seed("noise", system, variant, self.noise_on, snr, r, self.base_seed),
                            fit_seed=dataset_seed("fit", system, variant, self.noise_on, snr, r, self.base_seed,
                                                  bits=31),
                            validation_seed=dataset_seed("validation", system, variant, None, snr, r, self.base_seed,
                                                         bits=31),
                            fit_kwargs=tuple(sorted(opts.items(), key=lambda kv: kv[0])),
                            preset_obj=preset_obj, noise_reference=self.noise_reference,
                            t_end=float(self.t_end), n_points=int(self.n_points),
                        ))
        order = {s: i for i, s in enumerate(self.snr_db)}
        out.sort(key=lambda j: (self.systems.index(j.system), order[j.snr_db], self.methods.index(j.method),
                                j.realization))
        return out


@dataclasses.dataclass
class SweepReport:
    """What :func:`run_sweep` did.

    Examples
    --------
    >>> from charcurves.experiments import Sweep, run_sweep
    >>> print(run_sweep(Sweep(methods=["parametric"], snr_db=[20]), "sweep.sqlite", workers=1, progress=False))
    2 jobs: 0 already stored, 2 run in 2 units (2 ok, 0 failed) in ... s with local x1; results in sweep.sqlite
    """

    store_path: str
    n_jobs: int
    n_skipped: int
    n_run: int
    n_ok: int
    n_failed: int
    n_units: int
    seconds: float
    executor: str
    workers: int

    def __str__(self) -> str:
        return (f"{self.n_jobs} jobs: {self.n_skipped} already stored, {self.n_run} run in {self.n_units} units "
                f"({self.n_ok} ok, {self.n_failed} failed) in {self.seconds:.1f} s with {self.executor} "
                f"x{self.workers}; results in {self.store_path}")


def run_sweep(sweep: Sweep, store_path: str | os.PathLike, *, executor: str = "local", workers: int | None = None,
              progress: bool = True, forward_cases: int = 0, eps: float = 0.2, box_margin: float | None = 1.0,
              case_time_budget: float = 20.0, time_budget_per_job: float | None = None,
              max_failed_cases: int | None = None, max_attempts: int = 1000,
              forward_rtol: float | None = None, forward_atol: float | None = None, retry_failed: bool = False,
              batch: str | int = "level", max_batch: int | None = None, torch_threads: int | None = 1,
              save_models: bool | str = False, address: str | None = None,
              ray_init_kwargs: Mapping[str, Any] | None = None,
              on_row: Callable[[dict], None] | None = None) -> SweepReport:
    """Run the jobs of ``sweep`` that ``store_path`` does not hold yet, writing one row per job.

    Parameters
    ----------
    sweep : Sweep
    store_path : str or PathLike
        SQLite results file (created when missing); a rerun resumes where the last one stopped.
    executor : {"local", "ray"}
        "local": the driver itself when ``workers`` is 1, else a pool of ``workers`` processes (spawned; call from
        under ``if __name__ == "__main__":`` in scripts). "ray": the same job function as Ray tasks
        (``ray.init(num_cpus=workers, include_dashboard=False)`` unless Ray is initialised already, or
        ``ray.init(address=address)`` for a cluster). Only the driver (this process) writes the store and the models.
    workers : int, optional
        Parallel workers (default: the CPU count).
    progress : bool
        A progress bar on stderr (tqdm when installed, else a line per finished unit).
    forward_cases : int
        Validation cases per fitted model (0: none). Part of a job's identity, with ``eps`` and ``box_margin``.
    eps, box_margin, case_time_budget, max_attempts, max_failed_cases
        Forward-validation settings (see :func:`~charcurves.experiments.evaluate_forward`).
    forward_rtol, forward_atol : float, optional
        Tolerances of the models' forward integration; default: the system's (the truth's: tight for the "paper"
        variants, LSODA's defaults for "scripts"). Part of a job's identity when given. The forward simulations
        dominate a sweep's cost with the default preset; the scripts' LSODA defaults (1e-3, 1e-6) are about 3x faster
        than 1e-10/1e-12.
    time_budget_per_job : float, optional
        Soft wall-clock budget of one job: a fit is never interrupted, but the forward cases only get what is left of
        it (cases left over are recorded as "timeout").
    retry_failed : bool
        Also rerun jobs stored with status "failed".
    batch, max_batch
        How neural jobs are batched (see :func:`plan_units`).
    torch_threads : int or None
        Torch threads in each worker (1: best on shared machines; None: leave torch's setting).
    save_models : bool or str
        Save each fitted model (``FittedModel.save``) under ``<store>.models/`` or the given folder. Workers return the
        model files as bytes with their rows and the driver writes them, so on a cluster the models land on the
        driver's disk; a row's ``extra["model_path"]`` is the folder relative to the store's folder.
    address : str, optional
        Ray cluster to run on with ``executor="ray"`` (``"auto"``, ``"ray://head:10001"``); default ``RAY_ADDRESS``
        from the environment, else a private Ray instance of ``workers`` CPUs. See docs/cluster.md.
    ray_init_kwargs : mapping, optional
        Extra ``ray.init`` arguments (e.g. ``runtime_env``; no ``num_cpus`` with a cluster).
    on_row : callable, optional
        Called with every row after it is stored.

    Examples
    --------
    >>> from charcurves.experiments import Sweep, run_sweep
    >>> sweep = Sweep(methods=["parametric"], snr_db=[20], realizations=2)
    >>> report = run_sweep(sweep, "sweep.sqlite", workers=1, progress=False)  # in this process
    >>> report.n_run, report.n_ok, run_sweep(sweep, "sweep.sqlite", workers=1, progress=False).n_skipped  # resumes
    (2, 2, 2)
    """
    if executor not in EXECUTORS:
        raise ConfigError(f"executor must be one of {', '.join(EXECUTORS)}, got {executor!r}")
    if workers is not None and (isinstance(workers, bool) or int(workers) < 1):
        raise ConfigError(f"workers must be a positive integer, got {workers!r}")
    if isinstance(forward_cases, bool) or int(forward_cases) < 0:
        raise ConfigError(f"forward_cases must be a non-negative integer, got {forward_cases!r}")
    t0 = time.perf_counter()
    evaluation = None
    if forward_cases:
        evaluation = {"cases": int(forward_cases), "eps": float(eps), "box_margin": box_margin,
                      "seeds": "per-level"}  # cases drawn per level: rows of older stores are other jobs
        if forward_rtol is not None or forward_atol is not None:
            evaluation.update(rtol=forward_rtol, atol=forward_atol)
    jobs = sweep.jobs(evaluation)
    models_dir = None
    if save_models:
        models_dir = (os.fspath(save_models) if isinstance(save_models, (str, os.PathLike))
                      else f"{os.fspath(store_path)}.models")
    settings = RunSettings(forward_cases=int(forward_cases), eps=float(eps), box_margin=box_margin,
                           case_time_budget=float(case_time_budget), time_budget_per_job=time_budget_per_job,
                           max_attempts=int(max_attempts), max_failed_cases=max_failed_cases,
                           sim_rtol=forward_rtol, sim_atol=forward_atol,
                           torch_threads=torch_threads, return_models=models_dir is not None)
    if executor == "ray":
        address = ray_address(address)
    store_dir = os.path.dirname(os.path.abspath(os.fspath(store_path)))
    store = ResultsStore(store_path)
    try:
        done = store.completed_keys(status="ok" if retry_failed else None)
        todo = [j for j in jobs if j.key not in done]
        units = plan_units(todo, batch=batch, max_batch=max_batch)
        n_workers = int(workers) if workers is not None else (os.cpu_count() or 1)
        store.log_run(sweep.to_dict(), {"executor": executor, "workers": n_workers, **dataclasses.asdict(settings),
                                        "n_jobs": len(jobs), "n_todo": len(todo)})
        bar = Progress(len(todo), progress and bool(todo))
        counts = {"ok": 0, "failed": 0}
        stop = StopSignals()

        def consume(rows: list[dict]) -> None:
            stop.deferring = True  # a signal now waits until the rows are committed and counted
            try:
                for row in rows:
                    write_row_model(row, models_dir, store_dir)  # before its row: the row commits the job
                    store.write(row)
                    counts[row["status"]] += 1
                    if on_row is not None:
                        on_row(row)
                bar.update(len(rows), sum(r["status"] == "failed" for r in rows))
            finally:
                stop.deferring = False
            stop.check()

        try:
            with stop:
                if executor == "ray":
                    run_ray(units, settings, n_workers if workers is not None or address is None else None,
                            address, ray_init_kwargs, consume)
                elif min(n_workers, len(units)) <= 1:
                    for unit in units:
                        rows = run_unit(unit, settings)
                        stop.check()  # a fit that caught Ctrl-C returns its model so far: not a finished job
                        consume(rows)
                else:
                    run_pool(units, settings, min(n_workers, len(units)), consume)
        except KeyboardInterrupt:
            raise SweepInterrupted(counts["ok"] + counts["failed"], len(todo), store.path,
                                   stop.received or "SIGINT") from None
        finally:
            bar.close()
        return SweepReport(store.path, len(jobs), len(jobs) - len(todo), len(todo), counts["ok"], counts["failed"],
                           len(units), time.perf_counter() - t0, executor,
                           1 if executor == "local" and min(n_workers, len(units)) <= 1 else n_workers)
    finally:
        store.close()

