"""Ctrl-C / SIGTERM stop a multi-worker sweep: workers gone, finished rows kept, a rerun resumes."""

from __future__ import annotations

import os
import signal
import sqlite3
import subprocess
import sys
import time

import pytest

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals and /proc")

#: post-SR jobs take seconds each, so the signal lands while workers are busy
ARGS = ["--systems", "duffing", "--methods", "sindy-cc+sym+post-sr", "--snr", "40,20", "--realizations", "3",
        "--workers", "2", "--forward-cases", "0", "--skip", "forward,lyapunov,miw,sensitivity,appendix-f", "--quiet"]
N_JOBS = 6


def _children(pid: int) -> set[int]:
    """All descendants of ``pid`` (from /proc)."""
    parents: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as fh:
                    ppid = int(fh.read().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            parents.setdefault(ppid, []).append(int(entry))
    out, todo = set(), [pid]
    while todo:
        for c in parents.get(todo.pop(), []):
            out.add(c)
            todo.append(c)
    return out


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def _rows(db: str) -> list[tuple]:
    if not os.path.exists(db):
        return []
    con = sqlite3.connect(db, timeout=30)
    try:
        return con.execute("SELECT system, method, snr_db, realization, status, rmse_f1 FROM results").fetchall()
    except sqlite3.OperationalError:  # table not created yet
        return []
    finally:
        con.close()


DRIVER = """
import multiprocessing, os, signal, sys
from charcurves.experiments import run_sweep
from charcurves.experiments._sweep import Sweep, SweepInterrupted

if __name__ == "__main__":
    sweep = Sweep(systems=["duffing"], methods=["parametric"], snr_db=[40, 20, 0], realizations=4)
    signame = sys.argv[2]

    def on_row(row):
        if signame != "none":  # stop after the first stored row, with the workers busy on the next units
            print("WORKERS", *[p.pid for p in multiprocessing.active_children()], flush=True)
            os.kill(os.getpid(), getattr(signal, signame))

    try:
        print(run_sweep(sweep, sys.argv[1], workers=2, progress=False, on_row=on_row), flush=True)
    except SweepInterrupted as exc:
        print(exc, file=sys.stderr)
        sys.exit(130)
"""


@pytest.mark.parametrize("sig", ["SIGINT", pytest.param("SIGTERM", marks=pytest.mark.slow)])
def test_signal_stops_pool_sweep_keeps_rows_and_resumes(tmp_path, sig):
    script = tmp_path / "driver.py"
    script.write_text(DRIVER)
    db = str(tmp_path / "store.sqlite")
    env = dict(os.environ, OMP_NUM_THREADS="1")
    t0 = time.monotonic()
    res = subprocess.run([sys.executable, str(script), db, sig], capture_output=True, text=True, env=env, timeout=120)
    assert res.returncode == 130, res.stderr
    workers = [int(p) for p in res.stdout.split("WORKERS", 1)[1].split("\n")[0].split()]
    assert len(workers) >= 2
    deadline = time.monotonic() + 5
    while any(_alive(p) for p in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not [p for p in workers if _alive(p)], "orphan worker processes"
    rows = _rows(db)
    n = len(rows)
    assert n >= 1, "the driver signals only after a row is stored, so that row must survive"
    assert n < 12, f"the sweep finished all 12 jobs before the signal stopped it ({n} rows)"
    assert res.stderr.strip().splitlines()[-1] == (
        f"sweep interrupted ({sig}): {n} of 12 jobs finished and stored in {db}; rerun the same command to resume")
    assert len({r[:4] for r in rows}) == n
    assert all(r[4] == "ok" and r[5] is not None and 0.0 <= r[5] < 0.1 for r in rows)
    assert time.monotonic() - t0 < 60

    # the rerun in this process, on one worker (a fresh driver and two spawned workers would pay ~15 CPU s
    # of imports; the rerun of the same two-worker command is test_signal_stops_two_worker_benchmark_and_rerun_resumes)
    from charcurves.experiments import Sweep, run_sweep

    done = run_sweep(Sweep(systems=["duffing"], methods=["parametric"], snr_db=[40, 20, 0], realizations=4), db,
                     workers=1, progress=False)
    assert f"12 jobs: {n} already stored, {12 - n} run" in str(done)
    rows2 = _rows(db)
    assert len(rows2) == 12 and len({r[:4] for r in rows2}) == 12
    assert set(rows) <= set(rows2) and all(r[4] == "ok" for r in rows2)


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_signal_stops_two_worker_benchmark_and_rerun_resumes(tmp_path, sig):
    """End to end through the CLI, the signal sent from outside while post-SR jobs run."""
    out = tmp_path / "bench"
    db = str(out / "results.sqlite")
    cmd = [sys.executable, "-m", "charcurves", "benchmark", "--out", str(out), *ARGS]
    env = dict(os.environ, OMP_NUM_THREADS="1")
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        deadline = time.monotonic() + 240
        while not _rows(db):
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "no row within 240 s"
            time.sleep(0.2)
        workers = _children(proc.pid)
        assert len(workers) >= 2  # the two pool workers (and the resource tracker)
        t0 = time.monotonic()
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=10)
        stopped_in = time.monotonic() - t0
    finally:
        if proc.poll() is None:
            proc.kill()
    deadline = time.monotonic() + 5
    while any(_alive(p) for p in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not [p for p in workers if _alive(p)], "orphan worker processes"
    assert stopped_in < 10
    assert proc.returncode == 130, err
    lines = [ln for ln in err.strip().splitlines() if ln.startswith("charcurves:")]
    assert len(lines) == 1, err
    rows = _rows(db)
    n = len(rows)
    assert n >= 1, "the signal was sent once a row existed, so that row must survive"
    assert n < N_JOBS, f"the benchmark finished all {N_JOBS} jobs before the signal stopped it"
    assert lines[0] == (f"charcurves: sweep interrupted ({sig.name}): {n} of {N_JOBS} jobs finished and stored in "
                        f"{db}; rerun the same command to resume")
    keys = [r[:4] for r in rows]
    assert len(set(keys)) == n  # unique
    assert all(r[4] == "ok" and r[5] is not None and 0.0 <= r[5] < 1.0 for r in rows)  # complete rows

    done = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=300)
    assert done.returncode == 0, done.stderr
    rows2 = _rows(db)
    assert len(rows2) == N_JOBS and len({r[:4] for r in rows2}) == N_JOBS
    assert set(rows) <= set(rows2)  # the first run's rows were kept, not recomputed
    assert all(r[4] == "ok" for r in rows2)
