"""Where a sweep's units run: a pool of local processes or Ray tasks (a local Ray or a cluster).

Every executor hands each unit's rows back to the driver through ``consume``; the driver alone
writes the results store and the saved models (workers return a model's files as bytes, so a
worker on another machine never needs the driver's disk).
"""

from __future__ import annotations

import contextlib

import math
import os
import sys
import time
from collections.abc import Mapping
from typing import Any

from .._errors import ConfigError
from ._runner import RunSettings, failed_rows, init_worker, run_unit

__all__ = ["Progress", "StopSignals", "SweepInterrupted", "run_pool", "run_ray", "ray_address", "ray_session",
           "cancel_all"]


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl-C (SIGINT) or SIGTERM stopped :func:`run_sweep`; every finished row is stored.

    A ``KeyboardInterrupt``, so code that stops on Ctrl-C keeps doing so; ``str()`` is the one
    line to show. Attributes: ``n_finished`` (rows stored by this run), ``n_todo``, ``store_path``.

    Examples
    --------
    >>> from charcurves.experiments import SweepInterrupted
    >>> stop = SweepInterrupted(3, 10, "results.sqlite")
    >>> isinstance(stop, KeyboardInterrupt), stop.n_finished, stop.n_todo
    (True, 3, 10)
    >>> print(stop)
    sweep interrupted (SIGINT): 3 of 10 jobs finished and stored in results.sqlite; rerun the same command to resume
    """

    def __init__(self, n_finished: int, n_todo: int, store_path: str, signal_name: str = "SIGINT"):
        self.n_finished, self.n_todo, self.store_path = int(n_finished), int(n_todo), str(store_path)
        super().__init__(f"sweep interrupted ({signal_name}): {self.n_finished} of {self.n_todo} jobs finished "
                         f"and stored in {self.store_path}; rerun the same command to resume")

    def __str__(self) -> str:
        return str(self.args[0])


class StopSignals:
    """SIGINT/SIGTERM raise KeyboardInterrupt in the driver, but never while a row is being stored
    (the signal is held until the row is committed and counted). Only in the main thread: signal
    handlers cannot be installed elsewhere, and there the default Ctrl-C behaviour stays."""

    def __init__(self) -> None:
        self.received: str | None = None
        self.deferring = False
        self._old: dict = {}

    def __enter__(self):
        import signal
        import threading

        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._old[sig] = signal.signal(sig, self._handle)
        return self

    def __exit__(self, *exc) -> None:
        import signal

        for sig, old in self._old.items():
            signal.signal(sig, old)

    def _handle(self, signum, frame) -> None:
        import signal

        self.received = signal.Signals(signum).name
        if not self.deferring:
            raise KeyboardInterrupt

    def check(self) -> None:
        """Raise the interrupt held while a row was stored."""
        if self.received is not None:
            raise KeyboardInterrupt


class Progress:
    """tqdm when installed, else one line on stderr per finished unit."""

    def __init__(self, total: int, enabled: bool, desc: str = "sweep"):
        self.total, self.done, self.failed, self.enabled = total, 0, 0, enabled
        self.t0 = time.perf_counter()
        self.bar = None
        if enabled:
            try:
                from tqdm.auto import tqdm

                self.bar = tqdm(total=total, desc=desc, unit="job", file=sys.stderr)
            except ImportError:
                self.bar = None

    def update(self, n: int, failed: int) -> None:
        self.done += n
        self.failed += failed
        if not self.enabled:
            return
        if self.bar is not None:
            self.bar.update(n)
            self.bar.set_postfix(failed=self.failed)
            return
        el = time.perf_counter() - self.t0
        eta = el / self.done * (self.total - self.done) if self.done else float("nan")
        sys.stderr.write(f"[charcurves sweep] {self.done}/{self.total} jobs done, {self.failed} failed, "
                         f"elapsed {_fmt(el)}, eta {_fmt(eta)}\n")
        sys.stderr.flush()

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _fmt(s: float) -> str:
    if not math.isfinite(s):
        return "?"
    s = int(round(s))
    return f"{s // 3600}h{s % 3600 // 60:02d}m{s % 60:02d}s" if s >= 3600 else f"{s // 60}m{s % 60:02d}s"


# ---------------------------------------------------------------------- local processes
def run_pool(units, settings: RunSettings, n: int, consume) -> None:
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor, as_completed
    from concurrent.futures.process import BrokenProcessPool

    pool = ProcessPoolExecutor(max_workers=n, mp_context=mp.get_context("spawn"), initializer=_init_pool_worker,
                               initargs=(settings.torch_threads, os.getpid()))
    try:
        futures = {pool.submit(run_unit, unit, settings): unit for unit in units}
        for fut in as_completed(futures):
            unit = futures[fut]
            try:
                rows = fut.result()
            except BrokenProcessPool as exc:
                rows = failed_rows(unit, f"worker process died ({type(exc).__name__}: {exc}); "
                                         "rerun with retry_failed=True")
            except Exception as exc:  # noqa: BLE001 - e.g. an unpicklable result
                rows = failed_rows(unit, f"{type(exc).__name__}: {exc}")
            consume(rows)
    except BaseException:
        _stop_pool(pool)
        raise
    pool.shutdown(wait=True)


def _init_pool_worker(threads: int | None, parent_pid: int) -> None:
    """Pool workers ignore Ctrl-C: the terminal sends SIGINT to the whole process group, and a
    worker's fit would catch it and return an interrupted model as a finished job. The driver
    stops the workers itself (:func:`_stop_pool`)."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    init_worker(threads, parent_pid)


def _stop_pool(pool, grace: float = 3.0) -> None:
    """Cancel queued units and end the workers now (SIGTERM, SIGKILL after ``grace`` seconds);
    a unit a worker was running is lost and reruns on resume."""
    procs = list((getattr(pool, "_processes", None) or {}).values())  # no public handle before 3.14
    pool.shutdown(wait=False, cancel_futures=True)
    for p in procs:
        if p.is_alive():
            p.terminate()
    deadline = time.monotonic() + grace
    for p in procs:
        p.join(max(0.0, deadline - time.monotonic()))
        if p.is_alive():
            p.kill()
            p.join(1.0)


# ---------------------------------------------------------------------- Ray
def ray_address(address: str | None) -> str | None:
    """The cluster to connect to: ``address``, else ``RAY_ADDRESS`` from the environment (as Ray's
    own tools read it), else None (start a private Ray instance)."""
    if address is None:
        address = os.environ.get("RAY_ADDRESS") or None
    if address is not None and not str(address).strip():
        raise ConfigError("the Ray address is empty; give one such as 'auto' or 'ray://head:10001', or None for a "
                          "private Ray instance")
    return address


def _ray_unit(unit, settings: RunSettings) -> list[dict[str, Any]]:
    """A unit as a Ray task: its rows, marked with the node that ran them."""
    rows = run_unit(unit, settings)
    try:
        import ray

        node = ray.get_runtime_context().get_node_id()
    except Exception:  # noqa: BLE001 - the mark is informative only
        node = None
    for row in rows:
        row.setdefault("extra", {})["ray_node"] = node
    return rows


def run_ray(units, settings: RunSettings, num_cpus: int | None, address: str | None,
            init_kwargs: Mapping[str, Any] | None, consume) -> None:
    """Run the units as Ray tasks (one CPU each). With ``address`` (or ``RAY_ADDRESS``) on that
    cluster, whose size is its own (no ``num_cpus``); else on a private Ray instance of ``num_cpus``.
    A Ray already initialised in this process is used as it is."""
    with ray_session(address, num_cpus, init_kwargs) as ray:
        task = ray.remote(num_cpus=1, max_retries=0)(_ray_unit)
        pending = {task.remote(unit, settings): unit for unit in units}
        try:
            _drain_ray(ray, pending, consume)
        except BaseException:
            cancel_all(ray, pending)
            raise


def cancel_all(ray, refs) -> None:
    """Cancel queued and running tasks; a running one's result is lost."""
    for ref in refs:
        try:
            ray.cancel(ref, force=True)
        except Exception:  # noqa: BLE001 - already finished or its worker gone
            pass


@contextlib.contextmanager
def ray_session(address: str | None, num_cpus: int | None = None, init_kwargs: Mapping[str, Any] | None = None):
    """The ``ray`` module, connected: to the cluster at ``address`` (or ``RAY_ADDRESS``), whose size is
    its own (no ``num_cpus``), else to a private Ray instance of ``num_cpus``; a Ray already
    initialised in this process is used as it is. Disconnects (or stops the private instance) on exit."""
    try:
        import ray
    except ImportError:
        raise ConfigError("executor='ray' needs Ray: pip install 'charcurves[ray]' (or pip install ray)") from None
    owned = False
    if not ray.is_initialized():
        kw = dict(init_kwargs or {})
        kw.setdefault("logging_level", "warning")
        address = ray_address(address)
        if address is not None:
            sized = sorted(k for k in ("num_cpus", "num_gpus", "resources", "object_store_memory") if k in kw)
            if sized:
                raise ConfigError(f"ray_init_kwargs {sized} size a new Ray instance; a cluster ({address!r}) has its "
                                  "own size: drop them, or drop the address to start a private Ray")
            from ._ray_probe import probe_address

            probe_address(address)  # nothing there: one line in seconds, not Ray's endless retries
            try:
                ray.init(address=address, **kw)
            except (ConnectionError, ValueError, RuntimeError) as exc:
                raise ConfigError(f"cannot connect to the Ray cluster at {address!r} ({type(exc).__name__}: "
                                  f"{str(exc).splitlines()[0] if str(exc) else ''}); check the address (`ray status` "
                                  "on the head node) or unset RAY_ADDRESS to run here") from None
        else:
            kw.setdefault("include_dashboard", False)
            kw.setdefault("num_cpus", num_cpus or os.cpu_count() or 1)
            ray.init(**kw)
        owned = True
    try:
        yield ray
    finally:
        if owned:
            ray.shutdown()  # disconnects from a cluster; stops a private instance


def _drain_ray(ray, pending: dict, consume) -> None:
    while pending:
        ready, _ = ray.wait(list(pending), num_returns=1)
        for ref in ready:
            unit = pending.pop(ref)
            try:
                rows = ray.get(ref)
            except Exception as exc:  # noqa: BLE001 - a crashed worker or task
                rows = failed_rows(unit, f"Ray task failed ({type(exc).__name__}: {exc})"[:2000])
            consume(rows)
