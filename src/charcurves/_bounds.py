"""The documented range of every number a user gives, in one table the CLI and the API both check.

Each :class:`Bound` names the quantity, its command-line option(s), the type, the inclusive range
and why the range ends where it does (the cost of going further). :func:`check_number` refuses a
Python value outside its range with a :class:`~charcurves.ConfigError` naming the parameter, the
option, the range and the fix; :func:`cli_number` is the ``type=`` of an argparse option that reads
the text strictly (plain decimal digits; no ``1_000``, no hex, at most 40 characters) and applies
the same check, so ``--threads 100000`` or ``--snr=-1e308`` end in one line and exit 2 before any
work. Nothing happens at import; the thread bounds read ``os.cpu_count()`` when checked.

Examples
--------
>>> from charcurves._bounds import check_number
>>> check_number("bands", 8)
8
>>> try:
...     check_number("bands", 10**11)
... except ValueError as exc:
...     print(str(exc)[:60])
bands (--bands) must be an integer from 3 to 1000 (each memb
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import os
import re
from collections.abc import Callable
from typing import Any

from ._errors import ConfigError

__all__ = ["Bound", "BOUNDS", "THREADS_PER_CORE", "check_number", "check_seeds", "cli_number", "range_text", "max_threads",
           "markdown_table"]

#: threads (torch) and workers (processes) allowed per CPU core: more only slows the work down, and
#: thousands of threads crash the process (issue 50: --threads 100000 ended in a segmentation fault)
THREADS_PER_CORE = 4


def max_threads() -> int:
    """:data:`THREADS_PER_CORE` times the CPU count of this machine (at least 4)."""
    return THREADS_PER_CORE * max(1, os.cpu_count() or 1)


@dataclasses.dataclass(frozen=True)
class Bound:
    """The inclusive range ``low ... high`` of one number, with its options and the cost beyond it."""

    name: str
    kind: str  # "int" or "float"
    low: float
    high: float | Callable[[], float]
    why: str
    options: tuple[str, ...] = ()
    example: str = ""

    def upper(self) -> float:
        return self.high() if callable(self.high) else self.high


def _b(name, kind, low, high, why, options=(), example=""):
    return name, Bound(name, kind, low, high, why, tuple(options), example)


#: every bounded number, by name (the API parameter; the CLI options that set it are listed)
BOUNDS: dict[str, Bound] = dict([
    _b("seed", "int", 0, 2**32 - 1, "the 32-bit range every random generator charcurves seeds accepts",
       ("--seed",), "0"),
    _b("threads", "int", 1, max_threads, f"{THREADS_PER_CORE} x the CPU count: more threads than cores only "
       "slow torch down", ("fit --threads", "select --threads", "demo --threads"), "1"),
    _b("workers", "int", 1, max_threads, f"{THREADS_PER_CORE} x the CPU count: each worker is a process fitting "
       "one job", ("benchmark --workers",), "2"),
    _b("snr_db", "float", -300.0, 300.0, "dB; 300 dB is a noise 1e-15 of the signal, below float64's precision, "
       "and -300 dB a noise 1e15 times the signal", ("simulate --snr", "fit --snr", "select --snr",
                                                     "benchmark --snr"), "20"),
    _b("substeps", "int", 1, 64, "RK4 steps per sample: time and memory of output error grow in proportion; "
       "the default chooses 1 to 8", ("fit --refine-substeps", "validate --substeps"), "4"),
    _b("segment_length", "int", 16, 100_000, "samples per shooting segment; a segment as long as the record "
       "is one free run of it", ("fit --segment-length",), "64"),
    _b("bands", "int", 3, 1000, "each member is one more fit of the record", ("fit --bands",), "8"),
    _b("bands_level", "float", 1e-6, 1 - 1e-6, "the coverage of the bands, strictly between 0 and 1",
       ("fit --bands-level",), "0.95"),
    _b("sr_generations", "int", 1, 10_000, "SR time and memory grow with the generations; the default is 40",
       ("fit --sr-generations",), "40"),
    _b("sr_populations", "int", 1, 100, "each population is one more independent search", ("fit --sr-populations",),
       "1"),
    _b("sr_max_size", "int", 3, 100, "expression nodes; the search space grows exponentially with the size; "
       "the default is 20", ("fit --sr-max-size",), "20"),
    _b("members", "int", 3, 1000, "each member is one more fit of every record and family",
       ("select --members",), "6"),
    _b("realizations", "int", 1, 1000, "each realisation is one more fit per method and SNR level",
       ("benchmark --realizations",), "2"),
    _b("forward_cases", "int", 0, 1000, "each case is one more free run per model", ("benchmark --forward-cases",),
       "2"),
    _b("sample_rate", "float", 1e-9, 1e12, "Hz; beyond these the time steps leave float64's comfortable range",
       ("fit --sample-rate", "validate --sample-rate"), "100"),
    _b("n_points", "int", 2, 2_000_000, "2 million samples are a CSV of about 0.25 GB", ("simulate --n-points",),
       "1000"),
    _b("init_window", "int", 2, 2_000_000, "samples of a span that only fit its initial state; the RMSE is "
       "counted on the rest (at least 16 samples)", ("validate --init-window",), "100"),
    _b("t_end", "float", 1e-3, 1e5, "time units; LSODA takes about 1 s per 1000", ("simulate --t-end",), "40"),
])

_INT_TEXT = re.compile(r"[+-]?[0-9]+")
_FLOAT_TEXT = re.compile(r"[+-]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?")
_MAX_TEXT = 40  # characters of a number on the command line (no 4300-digit integers reach int())


def _fmt(value: float, kind: str) -> str:
    if kind == "int":
        return f"{int(value)}"
    return f"{value:g}"


def range_text(name: str) -> str:
    """``"1 ... 64: why"`` for help texts and docs (the limits as checked on this machine)."""
    b = BOUNDS[name]
    return f"{_fmt(b.low, b.kind)} ... {_fmt(b.upper(), b.kind)}: {b.why}"


def markdown_table() -> str:
    """The ranges as the Markdown table of ``docs/options.md`` (a test keeps the page equal to it);
    the thread bounds are written as their rule, not as this machine's number."""
    rows = ["| Option | Key | Range | Why the range ends there |", "|---|---|---|---|"]
    for name, b in BOUNDS.items():
        high = f"{THREADS_PER_CORE} x CPU count" if callable(b.high) else _fmt(b.high, b.kind)
        options = ", ".join(f"`{o}`" for o in b.options)
        kind = "integer" if b.kind == "int" else "number"
        rows.append(f"| {options} | `{name}` | {kind}, {_fmt(b.low, b.kind)} ... {high} | {b.why} |")
    return "\n".join(rows) + "\n"


def _problem(b: Bound, value: Any) -> str | None:
    if b.kind == "int":
        if isinstance(value, bool) or not isinstance(value, numbers.Integral):
            return "an integer"
    elif isinstance(value, bool) or not isinstance(value, numbers.Real):
        return "a number"
    elif not math.isfinite(float(value)):
        return "a finite number"
    if not b.low <= value <= b.upper():
        return "in range"
    return None


def _message(b: Bound, value: Any, label: str, shown: str | None = None) -> str:
    kind = "an integer" if b.kind == "int" else "a number"
    if shown is not None:
        pass
    elif isinstance(value, numbers.Integral) and not isinstance(value, bool):
        shown = f"{int(value)}" if abs(int(value)) < 10**30 else f"an integer of {len(str(abs(int(value))))} digits"
    elif isinstance(value, float) and math.isfinite(value) and float(f"{value:g}") == value:
        shown = f"{value:g}"  # 1e+12, not 1000000000000.0
    else:
        shown = repr(value)
    fix = f"; give e.g. {b.options[0].split()[-1]} {b.example}" if b.options and b.example else ""
    return (f"{label} must be {kind} from {_fmt(b.low, b.kind)} to {_fmt(b.upper(), b.kind)} ({b.why}), "
            f"got {shown}{fix}")


def check_number(name: str, value: Any, *, label: str | None = None) -> Any:
    """``value`` if it is a number in the range of ``BOUNDS[name]``, else a ConfigError naming it.

    ``label`` names the value in the message (default: the parameter and its first option, e.g.
    ``"threads (--threads)"``). Integers come back as ``int``, numbers as ``float``.
    """
    b = BOUNDS[name]
    if label is None:
        label = name + (f" ({b.options[0].split()[-1]})" if b.options else "")
    if _problem(b, value) is not None:
        raise ConfigError(_message(b, value, label))
    return int(value) if b.kind == "int" else float(value)


def cli_number(name: str) -> Callable[[str], Any]:
    """The argparse ``type=`` of an option bounded by ``BOUNDS[name]``: strict decimal text, then
    :func:`check_number`; the error is one line naming the range (argparse prefixes the option)."""
    import argparse

    b = BOUNDS[name]
    pattern = _INT_TEXT if b.kind == "int" else _FLOAT_TEXT

    def parse(text: str):
        stripped = text.strip()
        kind = "an integer" if b.kind == "int" else "a number"
        if len(stripped) > _MAX_TEXT or not pattern.fullmatch(stripped):
            shown = repr(text) if len(text) <= _MAX_TEXT else f"{text[:20]!r}... ({len(text)} characters)"
            raise argparse.ArgumentTypeError(f"must be {kind} from {_fmt(b.low, b.kind)} to "
                                             f"{_fmt(b.upper(), b.kind)} ({b.why}), got {shown}")
        value = int(stripped) if b.kind == "int" else float(stripped)
        if _problem(b, value) is not None:
            raise argparse.ArgumentTypeError(_message(b, value, "the value", shown=stripped)[len("the value "):])
        return value

    parse.__name__ = b.kind  # argparse names the type in its own messages
    return parse


def check_seeds(seeds: Any, n_records: int) -> list[int] | None:
    """``seeds`` as a list of ``n_records`` seeds, each an integer in the seed's range, or None
    (then the estimator derives them); a ConfigError in one line otherwise (issue 50: fewer seeds
    than records ended in an IndexError, a float seed was used as it was).

    >>> check_seeds(range(2), 2)
    [0, 1]
    >>> try:
    ...     check_seeds([0], 3)
    ... except ValueError as exc:
    ...     print(str(exc)[:36])
    seeds has 1 entry for 3 records; giv
    """
    if seeds is None:
        return None
    if isinstance(seeds, (str, bytes, dict)) or not hasattr(seeds, "__iter__"):
        raise ConfigError(f"seeds must be a sequence of integers, one per record, got {type(seeds).__name__}; give e.g. "
                          f"seeds=list(range({n_records})), or leave seeds out")
    out = list(seeds)
    if len(out) != n_records:
        raise ConfigError(f"seeds has {len(out)} entr{'y' if len(out) == 1 else 'ies'} for {n_records} record"
                          f"{'' if n_records == 1 else 's'}; give one seed per record, e.g. "
                          f"seeds=list(range({n_records})), or leave seeds out")
    return [check_number("seed", s, label=f"seeds[{i}]") for i, s in enumerate(out)]
