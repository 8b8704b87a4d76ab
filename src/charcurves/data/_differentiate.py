"""Numerical differentiation of a sampled state: ``x(t) -> (x̂, x̂', x̂'')``.

The characteristic-curve regression ``x'' + f1(x') + f2(x) = F(t)`` needs the velocity and the
acceleration of the measured state. A simulation can hand them over exactly (``Given``); a measured
record only has a noisy ``x(t)``, and plain finite differences amplify that noise by ``1/dt²`` in
``x''``. The differentiators here smooth and differentiate in one step:

=============  ====================================================  ===========  ==========
name           method                                                sampling     speed
=============  ====================================================  ===========  ==========
``given``      use the record's own ``v`` and ``a`` columns          any          --
``savgol``     Savitzky-Golay filter (paper, App. F; window 31/3)    uniform      fast
``spline``     smoothing spline, smoothing chosen by GCV             any          ~0.4 s/1k
``spectral``   FFT derivative with a noise-floor low-pass cutoff     uniform      fast
``fd``         second-order central differences (naive baseline)     any          fast
``kalman``     Kalman/RTS smoother, constant-jerk model, q/r by      any          ~0.3 s/1k
               maximum likelihood (a degree-7 smoothing spline)
``tvr``        total variation of x''' (cvxpy), alpha by the         uniform      ~2 s/1k
               discrepancy principle
=============  ====================================================  ===========  ==========

``estimate_derivatives(traj, "auto")`` uses ``given`` when the record carries ``v`` and ``a``,
otherwise ``spectral`` for uniformly sampled records and ``spline`` for non-uniform ones.

Measured accuracy: relative RMSE of ``x''`` (RMSE / std(x'')) over the interior 90 % of the
record, in brackets over the whole record; mean of 4 noise seeds. σ is the standard deviation of
the added Gaussian noise relative to std(x); the Duffing and stick-slip records are the paper's
systems (1000 samples on [0, 40]) with noise at the given SNR (σ² = var(x) / 10^(SNR/10)).

=============================  ===========  ===========  ===========  ===========  ======
signal                         savgol       spline       spline       spectral     fd
                               (31, 3)      (order 5)    (order 3)
=============================  ===========  ===========  ===========  ===========  ======
sin 2t + 0.3 cos 5t, clean     0.47 (0.50)  3e-5 (3e-5)  3e-3 (0.04)  1e-4 (4e-3)  0.012
sin 2t + 0.3 cos 5t, σ = 1 %   0.47 (0.50)  0.031 (.05)  0.13 (0.14)  0.016 (.06)  0.47
sin 2t + 0.3 cos 5t, σ = 5 %   0.47 (0.50)  0.089 (.16)  0.24 (0.25)  0.046 (.15)  2.3
sin(2π·68 t) at 610.35 Hz,     0.99 (0.99)  0.097 (.24)  0.13 (0.13)  0.007 (.04)  0.15
σ = 1 % (9 samples/period)
Duffing, 40 dB                 0.11 (0.12)  0.074 (.14)  0.14 (0.18)  0.066 (.08)  5.8
Duffing, 30 dB                 0.19 (0.21)  0.14 (0.52)  0.22 (0.25)  0.14 (0.18)  18
Duffing, 20 dB                 0.49 (0.55)  0.26 (0.40)  0.32 (0.35)  0.24 (0.27)  58
stick-slip, 30 dB              0.37 (0.40)  0.23 (0.49)  0.32 (0.46)  0.22 (0.23)  41
=============================  ===========  ===========  ===========  ===========  ======

The same measurement for the Kalman smoother (jerk and acceleration models) and total variation:

=============================  =============  ===========  ===========
signal                         kalman (jerk)  kalman       tvr
                                              (accel.)
=============================  =============  ===========  ===========
sin 2t + 0.3 cos 5t, clean     2e-9 (2e-3)    2e-6 (5e-3)  0.012 (.013)
sin 2t + 0.3 cos 5t, σ = 1 %   0.044 (.05)    0.10 (0.11)  0.091 (.10)
sin 2t + 0.3 cos 5t, σ = 5 %   0.093 (.11)    0.16 (0.17)  0.12 (0.16)
sin(2π·68 t) at 610.35 Hz      0.053 (.054)   0.13 (0.13)  --
Duffing, 40 dB                 0.056 (.062)   0.11 (0.11)  0.084 (.11)
Duffing, 30 dB                 0.11 (0.11)    0.15 (0.15)  0.13 (0.19)
Duffing, 20 dB                 0.20 (0.25)    0.22 (0.23)  0.27 (0.29)
stick-slip, 30 dB              0.21 (0.24)    0.22 (0.24)  0.26 (0.28)
=============================  =============  ===========  ===========

On the paper's records (chaotic, not band-limited) the jerk-model Kalman smoother is the most
accurate, most of all over the whole record (its ends are the natural spline's, not a periodic
extension's); on band-limited signals ``spectral`` is. ``docs/differentiators.md`` has the
benchmark of every differentiator as the start of an equation-error fit.

``spectral`` is the most accurate on uniformly sampled noisy records (also over the whole record,
ends included) and takes about a millisecond, which is why ``auto`` picks it; the quintic
``spline`` is as good in the interior of the paper's records but worse in the first and last
~1 % of samples, takes ~0.4 s per 1000 samples, and is the choice for non-uniform sampling (and
the most accurate on clean data). A 31-sample Savitzky-Golay window spans ~1.2 s at the paper's
dt = 0.04 s, i.e. a whole period of cos 5t, and ~3.4 periods of a signal sampled at 9 points per
period, which it flattens almost completely. Every method is less accurate in the first and last
~1 % of the record than in the interior.
"""

from __future__ import annotations

import inspect
from typing import Any

# scipy is imported inside the functions that use it: importing charcurves.data must stay cheap
# for records with given derivatives (the five subpackages cost about a second).

from .._errors import ConfigError, DataError
from ._diff_base import _UNIFORM_TOL, Differentiator, Given
from ._diff_classic import FiniteDifference, SavitzkyGolay, SmoothingSpline
from ._diff_kalman import KalmanSmoother
from ._diff_spectral import Spectral
from ._diff_tv import TotalVariation
from ._trajectory import Trajectory

__all__ = [
    "Differentiator",
    "Given",
    "SavitzkyGolay",
    "SmoothingSpline",
    "Spectral",
    "FiniteDifference",
    "KalmanSmoother",
    "TotalVariation",
    "make_differentiator",
    "estimate_derivatives",
    "DIFFERENTIATOR_NAMES",
]

#: Names accepted by :func:`make_differentiator` (and ``--derivatives`` on the command line).
DIFFERENTIATOR_NAMES: tuple[str, ...] = (
    "given", "savgol", "spline", "spectral", "fd", "kalman", "tvr"
)

_ALIASES = {
    "given": "given",
    "savgol": "savgol",
    "savitzky-golay": "savgol",
    "savitzky_golay": "savgol",
    "sg": "savgol",
    "spline": "spline",
    "smoothing-spline": "spline",
    "smoothing_spline": "spline",
    "spectral": "spectral",
    "fft": "spectral",
    "fourier": "spectral",
    "fd": "fd",
    "finite-difference": "fd",
    "finite_difference": "fd",
    "gradient": "fd",
    "kalman": "kalman",
    "rts": "kalman",
    "kalman-smoother": "kalman",
    "kalman_smoother": "kalman",
    "tvr": "tvr",
    "tv": "tvr",
    "tvrdiff": "tvr",
    "total-variation": "tvr",
    "total_variation": "tvr",
}

# ---------------------------------------------------------------------------------- registry
_CLASSES: dict[str, type[Differentiator]] = {
    "given": Given,
    "savgol": SavitzkyGolay,
    "spline": SmoothingSpline,
    "spectral": Spectral,
    "fd": FiniteDifference,
    "kalman": KalmanSmoother,
    "tvr": TotalVariation,
}


def _param_names(cls: type[Differentiator]) -> list[str]:
    return [p for p in inspect.signature(cls.__init__).parameters if p != "self"]


def make_differentiator(name_or_obj: str | Differentiator, **params: Any) -> Differentiator:
    """A differentiator from its name (see :data:`DIFFERENTIATOR_NAMES`) and parameters.

    An instance is returned as it is (then no parameters may be given).

    Examples
    --------
    >>> from charcurves.data import make_differentiator
    >>> make_differentiator("savgol", window=51)
    SavitzkyGolay(window=51, order=3, mode='interp')
    >>> make_differentiator("spline")
    SmoothingSpline(lam=None, order=5)
    """
    if isinstance(name_or_obj, Differentiator):
        if params:
            raise ConfigError(
                f"parameters {sorted(params)} cannot be applied to the ready-made {name_or_obj!r}; "
                "pass a method name with parameters, or an instance without them"
            )
        return name_or_obj
    if not isinstance(name_or_obj, str):
        raise ConfigError(
            f"a differentiator is a name ({', '.join(DIFFERENTIATOR_NAMES)}) or a Differentiator "
            f"instance, got {type(name_or_obj).__name__}"
        )
    key = name_or_obj.strip().lower()
    if key == "auto":
        raise ConfigError(
            "'auto' depends on the data; use estimate_derivatives(traj, 'auto') or choose one of "
            + ", ".join(DIFFERENTIATOR_NAMES)
        )
    canonical = _ALIASES.get(key)
    if canonical is None:
        raise ConfigError(
            f"unknown differentiator {name_or_obj!r}; valid names are "
            + ", ".join(DIFFERENTIATOR_NAMES)
        )
    cls = _CLASSES[canonical]
    allowed = _param_names(cls)
    unknown = sorted(set(params) - set(allowed))
    if unknown:
        takes = f"its parameters are {', '.join(allowed)}" if allowed else "it takes no parameters"
        names = ", ".join(map(repr, unknown))
        raise ConfigError(f"differentiator {canonical!r} has no parameter {names}; {takes}")
    return cls(**params)


def estimate_derivatives(
    traj: Trajectory, method: str | Differentiator = "auto", **params: Any
) -> Trajectory:
    """Return ``traj`` with ``x`` replaced by the smoothed ``x̂`` and ``v``, ``a`` filled in.

    Parameters
    ----------
    traj : Trajectory
        The record.
    method : str or Differentiator
        ``"auto"`` (default), one of :data:`DIFFERENTIATOR_NAMES`, or an instance.
        ``"given"`` returns ``traj`` unchanged and needs its ``v`` and ``a``. ``"auto"`` is
        ``given`` when ``traj`` has ``v`` and ``a``, otherwise ``spectral`` when the sampling is
        uniform (most accurate and fastest in the measurements in this module's docstring) and
        ``spline`` when it is not.
    **params
        Parameters of the named method (e.g. ``window=51`` for ``savgol``).

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.data import Trajectory, estimate_derivatives
    >>> t = np.linspace(0, 20, 1000)
    >>> record = Trajectory(t=t, x=np.sin(t), F=np.cos(t))
    >>> smooth = estimate_derivatives(record, "savgol", window=31)
    >>> print(f"{np.max(np.abs(smooth.a + np.sin(t))):.1e}")
    3.0e-02
    >>> estimate_derivatives(record).has_derivatives
    True
    """
    if not isinstance(traj, Trajectory):
        raise DataError(
            f"estimate_derivatives needs a Trajectory, got {type(traj).__name__}; build one with "
            "Trajectory(t=..., x=..., F=...)"
        )
    if isinstance(method, str) and method.strip().lower() == "auto":
        if params:
            raise ConfigError(
                f"parameters {sorted(params)} need a named method; 'auto' picks its own "
                "(name one of " + ", ".join(DIFFERENTIATOR_NAMES) + ")"
            )
        if traj.has_derivatives:
            diff: Differentiator = Given()
        elif traj.sampling_nonuniformity() <= _UNIFORM_TOL:
            diff = Spectral()
        else:
            diff = SmoothingSpline()
    else:
        diff = make_differentiator(method, **params)

    if isinstance(diff, Given):
        if not traj.has_derivatives:
            missing = " and ".join(c for c in ("v", "a") if getattr(traj, c) is None)
            raise DataError(
                f"'given' derivatives need v and a columns, but {traj.name!r} has no {missing}; "
                "pass --derivatives savgol|spline|spectral to estimate them from x"
            )
        return traj
    x_hat, v, a = diff._apply(traj)
    return traj.replace(x=x_hat, v=v, a=a)
