"""Shooting segments of several records: one common step, and segments that never cross a join."""

from __future__ import annotations

import numpy as np

from .._errors import DataError

__all__ = ["common_step", "record_segments"]


def common_step(records, uniform_step, tol: float = 1e-3) -> float:
    """The one uniform sample step of every record (``uniform_step(record)`` each; output error
    integrates all segments with one step; DataError naming the steps otherwise)."""
    steps = [uniform_step(r) for r in records]
    if max(steps) - min(steps) > tol * min(steps):
        raise DataError("output error of several records needs one sampling step, got "
                        f"{', '.join(f'{s:.6g}' for s in steps)}; resample the records to one rate, or use "
                        "objective='equation-error' (which takes each record at its own rate)")
    return float(np.median(steps))


def record_segments(bounds, L: int, max_segments: int, segments):
    """Shooting segments of each record (none crosses a boundary): ``(L, starts, contiguous)`` with
    one segment length for all (the shortest record's choice when it is shorter), the starts in
    the joined rows and which consecutive pairs abut (never across a boundary)."""
    n_min = min(b - a for a, b in bounds)
    L = min(int(L), n_min)
    starts: list[int] = []
    contiguous: list[bool] = []
    share = max(1, int(max_segments) // len(bounds))
    for a, b in bounds:
        Lk, s, c = segments(b - a, L, share)
        if Lk != L:  # equal segments of this record: keep the common length, the tail rows unused
            count = max(1, (b - a - 1) // (L - 1))
            s = np.arange(count) * (L - 1)
            c = np.diff(s) == L - 1
        if contiguous:
            contiguous.append(False)
        starts.extend((a + s).tolist())
        contiguous.extend(np.asarray(c, bool).tolist())
    return L, np.asarray(starts, dtype=int), np.asarray(contiguous, dtype=bool)
