"""CPU seconds of each test, a figure that a busy machine does not inflate (the test tiers' cost).

On a shared machine a test's wall time grows with the load (at a load average of 19 on 2 cores a
test that needs 4 s of CPU takes 45 s), so summed wall durations measured at different times
cannot be compared. The CPU time a test uses, its process's and its finished subprocesses', barely
moves with the load. As a pytest plugin this module records, per test (setup, call and teardown
together), the CPU seconds and the wall seconds::

    CPU_TIMES_OUT=cpu.json PYTHONPATH=src:benchmarks python -m pytest -p pytest_cpu_times -n 0 tests/test_cli.py
    python benchmarks/pytest_cpu_times.py cpu.json [more.json ...] [--top 20]

``CPU_TIMES_OUT`` gets a JSON list ``[nodeid, cpu_seconds, wall_seconds]`` at the end of the session;
``CPU_TIMES_LINES``, if set, gets one such JSON line per test as it ends (for a run that may be cut
short). Run it without xdist (``-n 0``): each worker would write its own list over the others'. A
module-scoped fixture's cost counts in the first test that uses it. Run as a script, it prints the
tests' count, their summed CPU and wall seconds, and the costliest tests by CPU.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import time

import pytest

_rows: list[list] = []


def _cpu_seconds() -> float:
    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)  # subprocesses that have been waited for
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    cpu, wall = _cpu_seconds(), time.perf_counter()
    yield
    _rows.append([item.nodeid, round(_cpu_seconds() - cpu, 3), round(time.perf_counter() - wall, 3)])
    lines = os.environ.get("CPU_TIMES_LINES")
    if lines:
        with open(lines, "a", encoding="utf-8") as f:
            f.write(json.dumps(_rows[-1]) + "\n")


def pytest_sessionfinish(session):
    path = os.environ.get("CPU_TIMES_OUT")
    if path:
        with open(path, "w", encoding="utf-8") as f:
            json.dump(_rows, f)


def summary(rows: list[list], top: int = 15) -> str:
    """The count, the summed CPU and wall seconds of ``rows`` and the ``top`` costliest tests by CPU.

    >>> print(summary([["t.py::a", 2.0, 9.0], ["t.py::b", 0.5, 1.0]], top=1))
    2 tests: CPU 2.5 s, wall 10.0 s
       2.00 CPU s    9.00 wall s  t.py::a
    """
    lines = [f"{len(rows)} tests: CPU {sum(r[1] for r in rows):.1f} s, wall {sum(r[2] for r in rows):.1f} s"]
    for nodeid, cpu, wall in sorted(rows, key=lambda r: -r[1])[:top]:
        lines.append(f"{cpu:7.2f} CPU s {wall:7.2f} wall s  {nodeid}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description="sum the CPU and wall seconds that -p pytest_cpu_times recorded")
    parser.add_argument("files", nargs="+", help="JSON files written through CPU_TIMES_OUT or CPU_TIMES_LINES")
    parser.add_argument("--top", type=int, default=15, help="costliest tests to list (default 15)")
    args = parser.parse_args(argv)
    rows: list[list] = []
    for path in args.files:
        with open(path, encoding="utf-8") as f:
            text = f.read()
        rows += json.loads(text) if text.lstrip().startswith("[[") or text.strip() == "[]" else [
            json.loads(line) for line in text.splitlines() if line.strip()]
    print(summary(rows, args.top))


if __name__ == "__main__":
    main()
