"""A sampled input between its samples (the *hold*), and fixed-step RK4 driven by it.

Real records give the input u only at the sample times, so a free run has to say what u is
between samples:

* ``"linear"`` (first-order hold): u interpolated linearly between samples;
* ``"zoh"`` (zero-order hold): u constant over each sample interval, as a DAC outputs it;
* ``"bandlimited"``: u interpolated through its spectrum (FFT zero padding), the right choice for
  an input that is band-limited well below the Nyquist frequency.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from .._errors import ConfigError, DataError

__all__ = ["HOLDS", "stage_inputs", "check_hold", "rk4_sampled"]

#: How the input is reconstructed between its samples.
HOLDS = ("linear", "zoh", "bandlimited")

#: Check for divergence and the time budget every this many samples (a check costs a few ops).
_CHECK_EVERY = 32


def check_hold(hold: str, substeps: int) -> None:
    """Refuse an unknown input hold (see :data:`HOLDS`) or a bad number of RK4 sub-steps per sample.

    Examples
    --------
    >>> from charcurves.data import check_hold
    >>> check_hold("zoh", 4)
    >>> try:
    ...     check_hold("cubic", 4)
    ... except ValueError as exc:
    ...     print(exc)
    unknown input hold 'cubic'; choose one of linear, zoh, bandlimited
    """
    if hold not in HOLDS:
        raise ConfigError(f"unknown input hold {hold!r}; choose one of {', '.join(HOLDS)}")
    from .._bounds import check_number

    check_number("substeps", substeps, label="substeps (--refine-substeps, validate --substeps)")


def _upsample_bandlimited(u: np.ndarray, r: int) -> np.ndarray:
    """Band-limited interpolation of ``u`` (along axis 0) onto ``r`` points per sample interval.

    The record is mirrored before the FFT so that its two ends do not wrap onto each other.
    Returns ``(n - 1) * r + 1`` points.
    """
    n = u.shape[0]
    if n < 3:
        return np.interp(np.arange((n - 1) * r + 1) / r, np.arange(n), u)
    ext = np.concatenate([u, u[-2:0:-1]])
    m = ext.shape[0]
    spec = np.fft.rfft(ext)
    padded = np.zeros(m * r // 2 + 1, dtype=complex)
    padded[: spec.shape[0]] = spec
    if m % 2 == 0:
        padded[m // 2] *= 0.5  # the old Nyquist bin is shared between +f and -f after padding
    return np.fft.irfft(padded, m * r)[: (n - 1) * r + 1] * r


def stage_inputs(u, substeps: int = 1, hold: str = "linear") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The input at the three RK4 evaluation times of every sub-step.

    Parameters
    ----------
    u : array (n,)
        The sampled input.
    substeps : int
        RK4 steps per sample interval.
    hold : {"linear", "zoh", "bandlimited"}
        How u continues between samples (module docstring).

    Returns
    -------
    u_start, u_mid, u_end : arrays ((n - 1) * substeps,)
        u at the start, the middle and the end of each sub-step, in time order.

    Examples
    --------
    >>> from charcurves.data import stage_inputs
    >>> u_start, u_mid, u_end = stage_inputs([0.0, 1.0, 2.0], substeps=2)
    >>> u_start.tolist(), u_mid.tolist(), u_end.tolist()
    ([0.0, 0.5, 1.0, 1.5], [0.25, 0.75, 1.25, 1.75], [0.5, 1.0, 1.5, 2.0])
    """
    check_hold(hold, substeps)
    u = np.asarray(u, dtype=float).reshape(-1)
    n = u.shape[0]
    if n < 2:
        raise DataError(f"a sampled input needs at least 2 samples, got {n}")
    if hold == "zoh":
        held = np.repeat(u[:-1], substeps)
        return held, held, held
    r = 2 * substeps  # grid of half sub-steps
    if hold == "linear":
        grid = np.interp(np.arange((n - 1) * r + 1) / r, np.arange(n), u)
    else:
        grid = _upsample_bandlimited(u, r)
    return grid[0:-1:2], grid[1::2], grid[2::2]


def rk4_sampled(accel: Callable, u_start, u_mid, u_end, x0, v0, dt: float, substeps: int = 1, *,
                max_abs: float = 1e6, time_budget: float | None = None):
    """Fixed-step RK4 of ``x'' = accel(x, v, u)`` for one state or a whole batch of states.

    Parameters
    ----------
    accel : callable
        ``accel(x, v, u)``; with arrays it must broadcast (numpy operations do).
    u_start, u_mid, u_end : arrays ((n - 1) * substeps, ...)
        Stage inputs from :func:`stage_inputs`; trailing axes broadcast against the state.
    x0, v0 : float or arrays of one shape S
        Initial states; a batch advances in lock-step (e.g. candidate parameter sets or record
        segments), which costs about as much per step as a single state.
    dt : float
        Sample interval.
    max_abs : float
        A state larger than this counts as diverged; it is set to NaN and stays NaN.
    time_budget : float, optional
        Seconds of wall-clock time; when spent the run stops.

    Returns
    -------
    x, v : arrays (n, *S)
        The state at every sample; NaN after divergence, and from the stop on after a timeout.
    status : str
        "ok", "diverged" (at least one state of the batch diverged) or "timeout".

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.data import rk4_sampled, stage_inputs
    >>> u = np.zeros(101)
    >>> x, v, status = rk4_sampled(lambda x, v, u: u - x, *stage_inputs(u), x0=1.0, v0=0.0, dt=0.01 * np.pi)
    >>> status, round(float(x[-1]), 6)
    ('ok', -1.0)
    """
    n_sub = len(u_start)
    if n_sub % substeps:
        raise ConfigError(f"{n_sub} stage inputs do not divide into {substeps} sub-steps per sample")
    n = n_sub // substeps + 1
    scalar = np.ndim(x0) == 0 and np.ndim(v0) == 0 and np.ndim(u_start[0]) == 0
    h = dt / substeps
    deadline = None if time_budget is None else time.monotonic() + float(time_budget)
    xs: Any  # the samples: a list of floats (scalar state) or an array (a batch)
    vs: Any
    if scalar:
        # plain Python floats: ~100x faster per step than 0-d numpy arrays
        x, v = float(x0), float(v0)
        ua_l, um_l, ub_l = (np.asarray(a, dtype=float).tolist() for a in (u_start, u_mid, u_end))
        xs, vs = [x], [v]
    else:
        shape = np.broadcast_shapes(np.shape(x0), np.shape(v0), np.shape(u_start[0]))
        x = np.broadcast_to(np.asarray(x0, dtype=float), shape).copy()
        v = np.broadcast_to(np.asarray(v0, dtype=float), shape).copy()
        ua_l, um_l, ub_l = u_start, u_mid, u_end
        xs = np.empty((n, *shape))
        vs = np.empty((n, *shape))
        xs[0], vs[0] = x, v
    try:
        xs, vs, status = _loop(accel, ua_l, um_l, ub_l, x, v, xs, vs, n, substeps, h, scalar, max_abs, deadline)
    except (OverflowError, ZeroDivisionError, ValueError):
        # math functions raise where numpy returns inf/NaN: a diverged run (Python floats only)
        status = "diverged"
        xs = np.concatenate([np.asarray(xs, dtype=float), np.full(n - len(xs), np.nan)])
        vs = np.concatenate([np.asarray(vs, dtype=float), np.full(n - len(vs), np.nan)])
    if scalar:
        return np.asarray(xs), np.asarray(vs), status
    if status == "ok" and not (np.all(np.abs(xs[-1]) < max_abs) and np.all(np.abs(vs[-1]) < max_abs)):
        status = "diverged"  # diverged after the last periodic check
    return xs, vs, status


def _loop(accel, ua_l, um_l, ub_l, x, v, xs, vs, n, substeps, h, scalar, max_abs, deadline):
    hh, h6 = 0.5 * h, h / 6.0
    status = "ok"
    j = 0
    with np.errstate(over="ignore", invalid="ignore"):
        for k in range(1, n):
            for _ in range(substeps):
                ua, um, ub = ua_l[j], um_l[j], ub_l[j]
                j += 1
                a1 = accel(x, v, ua)
                x2 = x + hh * v
                v2 = v + hh * a1
                a2 = accel(x2, v2, um)
                x3 = x + hh * v2
                v3 = v + hh * a2
                a3 = accel(x3, v3, um)
                x4 = x + h * v3
                v4 = v + h * a3
                a4 = accel(x4, v4, ub)
                x = x + h6 * (v + 2.0 * v2 + 2.0 * v3 + v4)
                v = v + h6 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
            if scalar:
                if not (abs(x) < max_abs and abs(v) < max_abs):  # also catches NaN
                    x = v = float("nan")
                    status = "diverged"
                    xs.extend([x] * (n - k))
                    vs.extend([v] * (n - k))
                    break
                xs.append(x)
                vs.append(v)
            else:
                if k % _CHECK_EVERY == 0:
                    bad = ~((np.abs(x) < max_abs) & (np.abs(v) < max_abs))
                    if bad.any():
                        x[bad] = np.nan  # NaN propagates silently; huge values would overflow
                        v[bad] = np.nan
                        status = "diverged"
                xs[k], vs[k] = x, v
            if deadline is not None and k % _CHECK_EVERY == 0 and time.monotonic() > deadline:
                status = "timeout"
                if scalar:
                    xs.extend([float("nan")] * (n - k - 1))
                    vs.extend([float("nan")] * (n - k - 1))
                else:
                    xs[k + 1:] = np.nan
                    vs[k + 1:] = np.nan
                break
    return xs, vs, status
