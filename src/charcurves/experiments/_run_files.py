"""The benchmark's small run objects: its result summary, ``extras.json``, the progress line, the
settings of a run that its sections share and the symbolic-regression budget of the quick grid."""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping, Sequence
from typing import Any

__all__ = ["BenchmarkResult"]


@dataclasses.dataclass
class BenchmarkResult:
    """What :func:`run_benchmark` produced.

    Examples
    --------
    The example is not run in the tests: even this smallest benchmark takes about 15 s.

    >>> import os
    >>> from charcurves.experiments import run_benchmark
    >>> result = run_benchmark("bench", systems=["duffing"], methods=["parametric"], snr_db=[20], realizations=1,
    ...                        skip=("forward", "lyapunov", "miw", "sensitivity", "appendix-f"))  # doctest: +SKIP
    >>> result.n_jobs, result.n_failed, os.path.basename(result.report_html)  # doctest: +SKIP
    (1, 0, 'report.html')
    """

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
        from ._store import _jsonable

        self.data[section] = {"signature": _jsonable(signature), "value": _jsonable(value)}
        self.save()

    def save(self) -> None:
        """Write the file (also when empty: the report's rebuild needs it)."""
        from ..io import atomic_write_bytes

        # compact: the figures' trajectories make most of it (a few hundred kB for a full study)
        atomic_write_bytes(self.path, json.dumps(self.data, separators=(",", ":")).encode("utf-8"))


def _log(progress: bool, msg: str) -> None:
    if progress:
        import sys

        print(f"[charcurves benchmark] {msg}", file=sys.stderr, flush=True)


def _sr_budget(methods: Sequence[str], generations: int | None) -> dict[str, dict]:
    """``method_options`` giving the symbolic-regression methods a smaller budget (quick grid):
    20 Operon generations instead of 40 recover the same benchmark curves about twice as fast."""
    if generations is None:
        return {}
    return {m: {"sr_options": {"generations": int(generations)}} for m in methods
            if m in ("sr", "sr-cc", "sr-cc+refit") or m.endswith("post-sr")}


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
    address: str | None = None
