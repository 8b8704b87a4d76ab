"""Wall and CPU seconds of ``charcurves demo`` (the README's first command), run as a user runs it.

Each repetition runs ``python -m charcurves demo --out DIR`` in a fresh process (imports included) and
records its wall seconds and its CPU seconds (user + system of the finished child), with the load average
at start and end: on a shared machine the wall time grows with the load, the CPU time barely does. A timing
is a measurement, not a test: tests/test_cli.py checks what the demo writes, this script how long it takes.

    OMP_NUM_THREADS=1 python benchmarks/bench_demo.py [--repeat 3] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time


def run_once() -> dict:
    """One demo in a fresh process: its wall and CPU seconds (raises if the demo fails)."""
    with tempfile.TemporaryDirectory() as out:
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        r = subprocess.run([sys.executable, "-m", "charcurves", "demo", "--out", out], capture_output=True, text=True)
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        if r.returncode != 0:
            raise SystemExit(f"demo failed with exit code {r.returncode}: {r.stderr.strip()}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"wall_s": round(wall, 2), "cpu_s": round(cpu, 2)}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description="time `charcurves demo` in fresh processes")
    parser.add_argument("--repeat", type=int, default=3, help="runs (default 3)")
    parser.add_argument("--json", help="also write the runs and their medians here")
    args = parser.parse_args(argv)
    load0 = os.getloadavg()
    runs = [run_once() for _ in range(args.repeat)]
    load1 = os.getloadavg()
    result = {"runs": runs, "median_wall_s": statistics.median(r["wall_s"] for r in runs),
              "median_cpu_s": statistics.median(r["cpu_s"] for r in runs), "cpu_count": os.cpu_count(),
              "load_average": {"start": load0, "end": load1}}
    print(f"charcurves demo, {len(runs)} runs: median wall {result['median_wall_s']:.1f} s, median CPU "
          f"{result['median_cpu_s']:.1f} s ({os.cpu_count()} cores, load average {load0[0]:.1f} at start, "
          f"{load1[0]:.1f} at end)")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump(result, fh, indent=1)


if __name__ == "__main__":
    main()
