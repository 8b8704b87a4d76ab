"""Before a fit of a very long record: say what it costs, and refuse beyond a bound unless told.

Issue 50: a record of 10 million rows was accepted and fitted by output error on all of it (11.4 GB
peak) without a word. From :data:`LONG_RECORD_WARN` samples on, ``fit`` prints one warning line
before the fit (time and memory grow in proportion to the samples; how to take fewer); beyond
:data:`LONG_RECORD_MAX` it refuses unless ``--long-record`` is given.
"""

from __future__ import annotations

from ._common import UsageError

__all__ = ["LONG_RECORD_WARN", "LONG_RECORD_MAX", "record_cost_warnings"]

#: samples from which the fit's cost is said before it starts
LONG_RECORD_WARN = 1_000_000
#: samples beyond which ``fit`` refuses the record unless ``--long-record`` is given
LONG_RECORD_MAX = 5_000_000


def record_cost_warnings(n_samples: int, *, allow_long: bool, output_error: bool) -> list[str]:
    """The warning line for a record of ``n_samples`` (none below :data:`LONG_RECORD_WARN`); a
    UsageError beyond :data:`LONG_RECORD_MAX` without ``allow_long``."""
    if n_samples < LONG_RECORD_WARN:
        return []
    k = max(2, -(-n_samples // 200_000))  # a stride that leaves about 200 000 samples
    fewer = (f"for a first fit take a span (--rows 0:200000) or one row in {k} of the file (a shorter record of "
             f"the same span, if the sampling rate allows it)")
    if n_samples > LONG_RECORD_MAX and not allow_long:
        raise UsageError(f"the record has {n_samples:,} samples, more than {LONG_RECORD_MAX:,}: the fit's time and "
                         f"memory grow in proportion to them; {fewer}, or add --long-record to fit all of it")
    where = ("output error simulates every sample in each of its iterations" if output_error else
             "every sample enters each pass of the fit")
    return [f"the record has {n_samples:,} samples: the fit's time and memory grow in proportion to them ({where}); "
            f"{fewer}"]
