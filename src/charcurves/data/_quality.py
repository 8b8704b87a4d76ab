"""Checks of a record's rows and signals: rows beyond the file, gaps in t, x that looks like noise."""

from __future__ import annotations

import numpy as np

from .._errors import DataError

__all__ = ["check_rows", "gap_warnings", "signal_warnings", "lag1", "GAP_FACTOR", "NOISE_LAG1", "OFFSET_WARN",
           "OFFSET_REFUSE", "STEP_RANGE", "check_offset", "check_time_step", "offset_warnings", "time_unit_warnings"]

#: A time step this many times the median step is a gap (:meth:`Trajectory.quality_warnings`).
GAP_FACTOR = 10.0
#: A state whose lag-1 autocorrelation is below this looks like white noise (a sampled motion has
#: close to 1, independent samples 0; the benchmark records with noise on x measure 0.99 at 20 dB,
#: 0.5 at 0 dB and 0.1 at -10 dB). The lag-1 autocorrelation of the differences is no test: it is
#: near -0.5 already for 20 dB noise on x, a record the spline and Savitzky-Golay differentiators fit.
NOISE_LAG1 = 0.3


#: A state whose median lies more than this many standard deviations from 0 is warned about, for
#: precision: its motion then keeps fewer than 12 of float64's 16 digits and fewer than 3 of the 7
#: of the single-precision SR search. A record resting far from 0 (a level sensor) is otherwise no
#: defect: a gauge anchored at 0 outside the data moves no residual; what a one-sided range does
#: break, a parity prior imposed on the curve, is warned about at the fit (fitting's priors).
OFFSET_WARN = 1e4
#: ... and refused beyond this many: float64 then keeps fewer than 10 of its 16 digits for the motion,
#: and differences (derivatives) lose more.
OFFSET_REFUSE = 1e6


def _offset_ratio(values: np.ndarray) -> tuple[float, float, float]:
    v = np.asarray(values, dtype=float)
    centre = float(np.median(v))
    spread = float(np.std(v - centre))  # about the median: no cancellation against the offset
    ratio = abs(centre) / spread if spread > 0 else 0.0
    return ratio, centre, spread


def check_offset(name: str, values: np.ndarray) -> None:
    """Refuse a state whose offset swamps its motion in float64 (more than :data:`OFFSET_REFUSE`
    standard deviations from 0), naming the offset to subtract."""
    ratio, centre, spread = _offset_ratio(values)
    if ratio > OFFSET_REFUSE and spread > 64 * np.finfo(float).eps * abs(centre):  # else x is constant: its own check
        raise DataError(f"{name} is offset by {centre:.6g}, {ratio:.3g} times its motion (standard deviation "
                        f"{spread:.3g}): float64 keeps too few digits of the motion; subtract the offset "
                        f"({name} - {centre:.6g}) and fit again")


def offset_warnings(name: str, values: np.ndarray) -> list[str]:
    """A state offset by more than :data:`OFFSET_WARN` standard deviations (the precision its motion
    keeps); [] otherwise: a level sensor resting at 120 with a motion of 1 (170 sd) is fitted without one."""
    ratio, centre, spread = _offset_ratio(values)
    if ratio > OFFSET_WARN:
        digits = np.log10(ratio)
        return [f"{name} is centred at {centre:.6g}, {ratio:.3g} standard deviations from 0: its motion keeps about "
                f"{max(16 - digits, 0):.0f} of float64's 16 digits (the single-precision SR search about "
                f"{max(7 - digits, 0):.0f} of 7), and derivatives lose more; subtract the offset "
                f"({name} - {centre:.6g}) and fit again"]
    return []


#: the median time step a record may have: the reciprocals of the sample-rate bounds (1e-9 ... 1e12 Hz,
#: charcurves._bounds); beyond them x' and x'' leave float64's comfortable range (a step of 5e-14
#: fitted at 7e7 times its noise floor)
STEP_RANGE = (1e-12, 1e9)


def check_time_step(t: np.ndarray) -> None:
    """Refuse a record whose median time step lies outside :data:`STEP_RANGE`, naming the fix."""
    steps = np.diff(np.asarray(t, dtype=float))
    if not steps.size:
        return
    step = float(np.median(steps))
    lo, hi = STEP_RANGE
    if not lo <= step <= hi:
        raise DataError(f"the median time step is {step:.3g}, outside {lo:g} ... {hi:g} (the sample rates "
                        f"{1 / hi:g} ... {1 / lo:g} Hz that charcurves computes derivatives for); rescale t to "
                        "seconds (or another unit that brings the step into range)")


def time_unit_warnings(t: np.ndarray) -> list[str]:
    """A step of 1 or more time units looks like t in milliseconds (or samples): derivatives and
    curves are per unit of t, so the curves' scale (and any fixed gain) changes with the unit."""
    steps = np.diff(np.asarray(t, dtype=float))
    step = float(np.median(steps)) if steps.size else 0.0
    if step >= 1.0:
        return [f"the time step is {step:.6g} time units: if t is in milliseconds (or sample numbers), convert it to "
                "seconds (t / 1000), since x', x'' and the curves are per unit of t"]
    return []


def check_rows(rows: slice, n_all: int) -> None:
    """Refuse START:STOP rows beyond the end of the file (Python slicing would silently cut them short)."""
    beyond = [v for v in (rows.start, rows.stop) if v is not None and v > n_all]
    if beyond:
        raise DataError(
            f"rows {'' if rows.start is None else rows.start}:{'' if rows.stop is None else rows.stop} go beyond "
            f"the file, which has {n_all} rows; choose START:STOP within 0:{n_all}"
        )


def lag1(values: np.ndarray) -> float | None:
    """Lag-1 autocorrelation of ``values`` (None when they are constant or fewer than 3)."""
    d = np.asarray(values, dtype=float)
    d = d - d.mean()
    den = float(np.dot(d, d))
    if not den > 0.0 or d.size < 3:
        return None
    return float(np.dot(d[:-1], d[1:]) / den)


def signal_warnings(name: str, values: np.ndarray) -> list[str]:
    r1 = lag1(values)
    if r1 is not None and r1 < NOISE_LAG1:
        return [f"{name} looks like white noise (lag-1 autocorrelation {r1:.2f}; a sampled motion has close to 1): "
                "its curves would be fitted to noise; check the column, its units and the sampling rate"]
    return []


def gap_warnings(t: np.ndarray) -> list[str]:
    steps = np.diff(t)
    median = float(np.median(steps))
    row = int(np.argmax(steps))
    if steps[row] > GAP_FACTOR * median:
        return [f"the time step at row {row + 1} is {steps[row] / median:.3g} times the median step "
                f"(a gap of {steps[row]:.6g} after t={t[row]:.6g}); derivatives and curves are fitted across it: "
                "fit the spans on either side separately (--rows) or fill the gap"]
    return []
