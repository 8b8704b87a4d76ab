"""Threads versus processes for batched NN-CC fits on a small machine.

The same workload (N Duffing records at 20 dB, NN-CC+sym default preset, fitted with
``fit_many``) is run as
  * one process with 1 torch thread (the baseline),
  * one process with T threads (intra-op parallelism),
  * P processes with 1 thread each (what ``charcurves benchmark`` / ``run_sweep`` do),
  * P processes with T threads each (oversubscribed when P*T exceeds the cores),
each in fresh subprocesses, timed as wall time of the whole group, in one run. Prints seconds
and throughput relative to the baseline.

    python benchmarks/bench_threads.py [--records 12] [--processes 2] [--threads 2]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time

_CHILD = r"""
import sys, torch
threads, first, count = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
torch.set_num_threads(threads)
import charcurves as cc
from charcurves.data import corrupt
from charcurves.systems import get_system
clean = get_system("duffing").simulate()
recs = [corrupt(clean, 20.0, seed=s) for s in range(first, first + count)]
cc.CharacteristicCurves.from_method(method="nn-cc+sym", threads=threads).fit_many(recs, seeds=list(range(first, first + count)))
"""


def run_group(processes: int, threads: int, records: int) -> float:
    env = {**os.environ, "OMP_NUM_THREADS": str(threads), "MKL_NUM_THREADS": str(threads)}
    share = records // processes
    t0 = time.perf_counter()
    procs = [subprocess.Popen([sys.executable, "-c", _CHILD, str(threads), str(i * share), str(share)], env=env)
             for i in range(processes)]
    codes = [p.wait() for p in procs]
    if any(codes):
        raise RuntimeError(f"a child failed: {codes}")
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--records", type=int, default=12)
    ap.add_argument("--processes", type=int, default=2)
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    P, T, N = args.processes, args.threads, args.records
    configs = [(1, 1), (1, T), (P, 1), (P, T)]
    print(f"cores: {os.cpu_count()}, load average before: {os.getloadavg()[0]:.2f}, records: {N}")
    base = None
    for p, t in configs:
        sec = run_group(p, t, N)
        base = base or sec
        print(f"{p} process(es) x {t} thread(s): {sec:7.1f} s   throughput x{base / sec:4.2f} vs 1x1")


if __name__ == "__main__":
    main()
