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

import abc
import inspect
import math
import warnings
from typing import Any, ClassVar, final

import numpy as np
# scipy is imported inside the functions that use it: importing charcurves.data must stay cheap
# for records with given derivatives (the five subpackages cost about a second).

from .._errors import ConfigError, DataError
from ._trajectory import Trajectory

__all__ = [
    "Differentiator",
    "Given",
    "SavitzkyGolay",
    "SmoothingSpline",
    "Spectral",
    "FiniteDifference",
    "make_differentiator",
    "estimate_derivatives",
    "DIFFERENTIATOR_NAMES",
]

#: Names accepted by :func:`make_differentiator` (and ``--derivatives`` on the command line).
DIFFERENTIATOR_NAMES: tuple[str, ...] = ("given", "savgol", "spline", "spectral", "fd")

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
}

# Relative tolerance on the time step for "uniform" sampling (same default as Trajectory).
_UNIFORM_TOL = 1e-3

Triple = tuple[np.ndarray, np.ndarray, np.ndarray]


# ---------------------------------------------------------------------------------- helpers
def _as_record(t: Any, x: Any) -> Trajectory:
    """Validate raw ``t``/``x`` arrays through :class:`Trajectory` (finite, 1-D, increasing t)."""
    return Trajectory(t=t, x=x, F=x, name="x(t)")


def _integer(name: str, owner: str, value: Any) -> int:
    if isinstance(value, (bool, np.bool_)):
        raise ConfigError(f"{owner} {name} must be an integer, got {value!r}")
    try:
        as_int = int(value)
        exact = as_int == value
    except (TypeError, ValueError, OverflowError):
        exact = False
    if not exact:
        raise ConfigError(f"{owner} {name} must be an integer, got {value!r}")
    return as_int


def _positive_or_none(name: str, owner: str, value: Any, allow_zero: bool) -> float | None:
    if value is None:
        return None
    bad = isinstance(value, (bool, np.bool_))
    try:
        val = float(value)
    except (TypeError, ValueError):
        bad = True
    if bad or not math.isfinite(val) or val < 0 or (val == 0 and not allow_zero):
        what = "a number >= 0" if allow_zero else "a positive number"
        raise ConfigError(f"{owner} {name} must be None (automatic) or {what}, got {value!r}")
    return val


# ---------------------------------------------------------------------------------- base
class Differentiator(abc.ABC):
    """Turns samples ``x(t)`` into a smoothed ``x̂`` and its derivatives ``x̂'`` and ``x̂''``.

    Call an instance on arrays, ``x_hat, v, a = diff(t, x)``, or give it to
    :func:`estimate_derivatives` together with a :class:`Trajectory`. Instances are plain,
    stateless configurations: :meth:`get_params` returns the constructor arguments, and two
    differentiators of the same class with the same parameters compare equal.
    """

    #: Registry name (see :data:`DIFFERENTIATOR_NAMES`).
    name: ClassVar[str] = ""
    #: Whether the method needs a uniform time step (checked by ``Trajectory.require_uniform``).
    requires_uniform: ClassVar[bool] = False

    def __call__(self, t: Any, x: Any) -> Triple:
        """Return ``(x_hat, v, a)``: smoothed state, first and second time derivative."""
        return self._apply(_as_record(t, x))

    def _apply(self, traj: Trajectory) -> Triple:
        self._check(traj)
        x_hat, v, a = self._differentiate(traj.t, traj.x)
        return (
            np.ascontiguousarray(x_hat, dtype=float),
            np.ascontiguousarray(v, dtype=float),
            np.ascontiguousarray(a, dtype=float),
        )

    def _check(self, traj: Trajectory) -> None:
        if self.requires_uniform:
            traj.require_uniform(f"the {self.name!r} differentiator", tol=_UNIFORM_TOL)

    @abc.abstractmethod
    def _differentiate(self, t: np.ndarray, x: np.ndarray) -> Triple:
        """The method itself, on validated arrays."""

    # -------------------------------------------------------------- parameters
    def get_params(self) -> dict[str, Any]:
        """The constructor arguments, ``{name: value}``."""
        sig = inspect.signature(type(self).__init__)
        return {p: getattr(self, p) for p in sig.parameters if p != "self"}

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.get_params().items())
        return f"{type(self).__name__}({args})"

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return self.get_params() == other.get_params()  # type: ignore[union-attr]

    def __hash__(self) -> int:
        return hash((type(self).__name__, tuple(sorted(self.get_params().items()))))


# ---------------------------------------------------------------------------------- given
@final
class Given(Differentiator):
    """Marker: use the trajectory's own ``v`` and ``a`` columns as they are (no smoothing).

    Only meaningful in :func:`estimate_derivatives`; calling it on raw arrays raises
    :class:`DataError`, because there is nothing to take the derivatives from.
    """

    name = "given"

    def __call__(self, t: Any, x: Any) -> Triple:
        raise DataError(
            "'given' derivatives need v and a columns, which raw t, x arrays do not have; "
            "use a Trajectory with v and a (estimate_derivatives(traj, 'given')) or pick a "
            "differentiator that computes them: savgol, spline, spectral or fd"
        )

    def _differentiate(self, t: np.ndarray, x: np.ndarray) -> Triple:  # pragma: no cover
        raise DataError("'given' derivatives are taken from the trajectory, not computed")


# ---------------------------------------------------------------------------------- Savitzky-Golay
_SAVGOL_MODES = ("interp", "mirror", "nearest", "constant", "wrap")


@final
class SavitzkyGolay(Differentiator):
    """Savitzky-Golay filter: local least-squares polynomials (``scipy.signal.savgol_filter``).

    ``x̂, x̂', x̂''`` are the filter with ``deriv = 0, 1, 2`` and ``delta = dt``, as in the paper's
    Appendix F. The default ``window=31, order=3`` is what the authors' result scripts use; the
    paper's text states ``w = 51`` (pass ``window=51`` to follow the text).

    Parameters
    ----------
    window : int
        Odd number of samples in each local fit, larger than ``order``. The record needs at
        least ``2 * window`` samples.
    order : int
        Polynomial order, at least 2 (a second derivative is needed).
    mode : str
        Edge handling of ``savgol_filter``: ``"interp"`` (default: fit the last window),
        ``"mirror"``, ``"nearest"``, ``"constant"`` or ``"wrap"``.

    Notes
    -----
    Needs uniform sampling. The window is fixed in samples, so its bandwidth depends on the
    sampling rate: a 31-sample window spans ~3.4 periods of a signal sampled at 9 points per
    period and flattens it almost completely.
    """

    name = "savgol"
    requires_uniform = True

    def __init__(self, window: int = 31, order: int = 3, mode: str = "interp") -> None:
        owner = "Savitzky-Golay"
        window = _integer("window", owner, window)
        order = _integer("order", owner, order)
        if order < 2:
            raise ConfigError(
                "Savitzky-Golay order must be at least 2 to give a second derivative, "
                f"got {order}; use order=3 (the paper's choice)"
            )
        if window < 3 or window % 2 == 0:
            hint = f"; use {window - 1} or {window + 1}" if window >= 4 else "; e.g. window=31"
            raise ConfigError(
                f"Savitzky-Golay window must be an odd integer >= 3, got {window}{hint}"
            )
        if window <= order:
            raise ConfigError(
                f"Savitzky-Golay window ({window}) must be larger than the order ({order}); "
                f"use window >= {order + 2 if order % 2 else order + 1} or a lower order"
            )
        if not isinstance(mode, str) or mode not in _SAVGOL_MODES:
            raise ConfigError(
                f"Savitzky-Golay mode must be one of {', '.join(_SAVGOL_MODES)}, got {mode!r}"
            )
        self.window = window
        self.order = order
        self.mode = mode

    def _check(self, traj: Trajectory) -> None:
        need = 2 * self.window
        n = traj.n_samples
        if n < need:
            half = n // 2
            largest = half if half % 2 else half - 1
            if largest > self.order:
                fix = f"use a smaller window (window <= {largest}, odd) or a longer record"
            else:
                fix = "give a longer record or use --derivatives fd"
            raise DataError(
                f"Savitzky-Golay with window={self.window} needs at least {need} samples "
                f"(2 windows), the record has {n}; {fix}"
            )
        super()._check(traj)

    def _differentiate(self, t: np.ndarray, x: np.ndarray) -> Triple:
        from scipy.signal import savgol_filter

        dt = float(np.median(np.diff(t)))
        kw = dict(window_length=self.window, polyorder=self.order, mode=self.mode, delta=dt)
        return (
            savgol_filter(x, deriv=0, **kw),
            savgol_filter(x, deriv=1, **kw),
            savgol_filter(x, deriv=2, **kw),
        )


# ---------------------------------------------------------------------------------- spline
_GCV_PROBES = 16
_GCV_SEED = 20240611


def _gcv_cubic(u: np.ndarray, y: np.ndarray, lam: float | None) -> tuple[float, float, float]:
    """GCV choice of the cubic smoothing-spline ``lam`` on the abscissa ``u`` (unit median step).

    Returns ``(lam, rss, edf)``. ``scipy.interpolate.make_smoothing_spline(lam=None)`` searches
    ``lam`` on a *linear* bounded interval ``[0, n]`` and lands on the oversmoothing end for
    records with few samples per period (it returns a straight line for sin(2π·68 t) sampled at
    610 Hz), so the search here runs on ``log10(lam)``: a half-decade grid, then a bounded Brent
    refinement around the best grid point. The trace of the smoother (the effective degrees of
    freedom) is a Hutchinson estimate from fixed Rademacher probes smoothed in the same call, so
    the GCV curve is smooth in ``lam`` and the result reproducible.
    """
    from scipy.interpolate import make_smoothing_spline
    from scipy.optimize import minimize_scalar

    n = y.shape[0]
    rng = np.random.default_rng(_GCV_SEED)
    probes = rng.choice((-1.0, 1.0), size=(n, _GCV_PROBES))
    stacked = np.column_stack([y, probes])

    def evaluate(log_lam: float) -> tuple[float, float, float]:
        spl = make_smoothing_spline(u, stacked, lam=10.0**log_lam)
        fitted = spl(u)
        rss = float(np.sum((fitted[:, 0] - y) ** 2))
        edf = float(np.mean(np.sum(probes * fitted[:, 1:], axis=0)))
        free = 1.0 - edf / n
        score = rss / n / free**2 if free > 1e-9 else math.inf
        return score, rss, edf

    if lam is not None:
        log_lam = math.log10(lam) if lam > 0 else -12.0
        _, rss, edf = evaluate(log_lam)
        return lam, rss, edf
    # lam ~ 1e-6: interpolation; lam ~ (n / 2π)^4 · 100: a straight line.
    hi = 4.0 * math.log10(max(n / (2.0 * math.pi), 1.0)) + 2.0
    grid = np.arange(-6.0, hi + 0.25, 0.5)
    scores = [evaluate(g)[0] for g in grid]
    best = int(np.argmin(scores))
    lo_b, hi_b = grid[max(best - 1, 0)], grid[min(best + 1, len(grid) - 1)]
    res = minimize_scalar(
        lambda g: evaluate(g)[0], bounds=(lo_b, hi_b), method="bounded", options={"xatol": 0.02}
    )
    log_lam = float(res.x) if res.fun <= scores[best] else float(grid[best])
    _, rss, edf = evaluate(log_lam)
    return 10.0**log_lam, rss, edf


@final
class SmoothingSpline(Differentiator):
    """Smoothing spline through the samples; derivatives from the spline's ``.derivative()``.

    Works with non-uniform sampling. ``scipy.interpolate.make_smoothing_spline`` only fits the
    cubic penalised spline (penalty ``lam ∫ x''² dt``), so:

    * ``order=3``: that cubic spline, ``lam`` given or chosen by generalized cross-validation
      (GCV, searched on a log scale; see :func:`_gcv_cubic` for why scipy's own search is not
      used). Its ``x''`` is piecewise linear and, with the natural end conditions, forced to 0
      at both ends.
    * ``order=5`` (default): a quintic smoothing spline (FITPACK ``UnivariateSpline(k=5)``) with
      residual budget ``s = n σ̂²``, where ``σ̂² = RSS / (n - edf)`` is the noise variance left
      by the GCV cubic fit (``lam`` given: by the cubic fit with that ``lam``). Measured on the
      test signals, the quintic's ``x''`` is 2-4x more accurate than the cubic's (e.g. relative
      RMSE of ``x''`` 0.031 vs 0.13 for sin 2t + 0.3 cos 5t with 1 % noise; 0.14 vs 0.22 on
      the paper's Duffing record at 30 dB), since GCV tunes the cubic for ``x``, not ``x''``.
      Its weak spots: the first and last ~1 % of samples (whole-record error ~2-4x the interior
      one on noisy data) and records with < ~10 samples per period, where it smooths little.
      Cost: ~0.4 s per 1000 samples (about 40 banded spline solves for the GCV search).

    Parameters
    ----------
    lam : float or None
        Smoothing parameter of the cubic spline in the units of ``t`` (as in
        ``make_smoothing_spline``); ``None`` chooses it by GCV.
    order : {5, 3}
        Degree of the spline.
    """

    name = "spline"
    _MIN_SAMPLES = 10

    def __init__(self, lam: float | None = None, order: int = 5) -> None:
        self.lam = _positive_or_none("lam", "smoothing spline", lam, allow_zero=True)
        order = _integer("order", "smoothing spline", order)
        if order not in (3, 5):
            raise ConfigError(
                f"smoothing spline order must be 3 (cubic) or 5 (quintic), got {order}"
            )
        self.order = order

    def _check(self, traj: Trajectory) -> None:
        if traj.n_samples < self._MIN_SAMPLES:
            raise DataError(
                f"the smoothing spline needs at least {self._MIN_SAMPLES} samples, the record has "
                f"{traj.n_samples}; give a longer record or use --derivatives fd"
            )

    #: Records longer than this are smoothed in overlapping blocks: FITPACK's quintic fit grows
    #: roughly with n^2 when cross-validation asks for little smoothing (43 s at 8000 samples).
    _BLOCK = 2048
    _OVERLAP = 256

    def _differentiate(self, t: np.ndarray, x: np.ndarray) -> Triple:
        n = x.shape[0]
        if n <= self._BLOCK + self._OVERLAP:
            return self._differentiate_block(t, x)
        out = [np.empty(n) for _ in range(3)]
        start = 0
        while start < n:
            lo = max(0, start - self._OVERLAP)
            hi = min(n, start + self._BLOCK + self._OVERLAP)
            if n - hi < self._OVERLAP:  # do not leave a short last block
                hi = n
            parts = self._differentiate_block(t[lo:hi], x[lo:hi])
            stop = hi if hi == n else start + self._BLOCK
            for o, p in zip(out, parts):  # keep each block's interior, away from its own ends
                o[start:stop] = p[start - lo:stop - lo]
            start = stop
        return out[0], out[1], out[2]

    def _differentiate_block(self, t: np.ndarray, x: np.ndarray) -> Triple:
        from scipy.interpolate import UnivariateSpline, make_smoothing_spline

        # Fit on a unit-step abscissa so that lam's search range is independent of the time
        # unit; derivatives are scaled back by 1/step^k.
        step = float(np.median(np.diff(t)))
        u = (t - t[0]) / step
        lam_u = None if self.lam is None else self.lam / step**3
        lam_u, rss, edf = _gcv_cubic(u, x, lam_u)
        n = x.shape[0]
        spl = None
        if self.order == 5:
            s = n * rss / max(n - edf, 1.0)
            with warnings.catch_warnings():
                # FITPACK warns when it cannot meet s exactly; the spline it returns is still
                # the best it found, and a non-finite result falls back to the cubic below.
                warnings.simplefilter("ignore", UserWarning)
                quintic = UnivariateSpline(u, x, k=5, s=s)
                trial = quintic(u)
            if np.all(np.isfinite(trial)):
                spl = quintic
        if spl is None:
            cubic = make_smoothing_spline(u, x, lam=lam_u)
            return cubic(u), cubic.derivative(1)(u) / step, cubic.derivative(2)(u) / step**2
        return spl(u), spl.derivative(1)(u) / step, spl.derivative(2)(u) / step**2


# ---------------------------------------------------------------------------------- spectral
_SPECTRAL_MIN_SAMPLES = 16
_FALSE_ALARM = 0.01  # chance that pure noise pushes the automatic cutoff above the signal band


def _odd_spectrum(r: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray, int]:
    """rfft of the odd (point-symmetric) periodic extension of ``r`` (``r[0] ≈ r[-1] ≈ 0``)."""
    from scipy import fft as _fft

    ext = np.concatenate([r, -r[-2:0:-1]])
    m = ext.shape[0]
    return _fft.rfft(ext), _fft.rfftfreq(m, dt), m


def _cubic_end_trend(tt: np.ndarray, ends: tuple[float, float, float, float]) -> Triple:
    """Cubic ``p`` with ``p(0)=y0, p(T)=y1, p''(0)=a0, p''(T)=a1``; returns ``p, p', p''``."""
    y0, y1, a0, a1 = ends
    T = tt[-1]
    d = (a1 - a0) / (6.0 * T)
    b = (y1 - y0 - 0.5 * a0 * T**2 - d * T**3) / T
    return (
        y0 + b * tt + 0.5 * a0 * tt**2 + d * tt**3,
        b + a0 * tt + 3.0 * d * tt**2,
        a0 + 6.0 * d * tt,
    )


@final
class Spectral(Differentiator):
    """FFT differentiation (multiply the spectrum by ``(iω)^k``) with a low-pass cutoff.

    Steps, for a uniformly sampled record:

    1. End treatment. A record is not periodic, so a cubic trend ``p(t)`` is removed first: it
       matches the record's values and curvatures at both ends (from a least-squares cubic over
       one cutoff period at each end), and the residual is extended point-symmetrically (odd
       extension, length ``2n - 2``). The extension is then continuous with continuous first and
       (up to the error of the end-curvature estimate) second derivative, so the spectrum decays
       fast and the derivatives show little Gibbs ringing. ``p, p', p''`` are added back exactly.
    2. Cutoff. ``cutoff=None`` chooses it from the data: the noise floor is the median power of
       the upper half of the frequency band (white noise gives χ²₁-distributed powers in the odd
       extension), and the cutoff is the highest frequency whose power stands above the level
       that pure noise exceeds with probability 1 % anywhere in the band. A first pass with a
       straight-line trend sets this cutoff and the end-fit length.
    3. Derivatives: ``x̂ = p + IFFT(R)``, ``x̂' = p' + IFFT(iω R)``, ``x̂'' = p'' + IFFT(-ω² R)``
       with ``R`` zeroed above the cutoff (scipy.fft).

    Parameters
    ----------
    cutoff : float or None
        Low-pass cutoff in cycles per unit of ``t`` (Hz when ``t`` is in seconds); ``None``
        (default) chooses it from the noise floor as described above. Values at or above the
        Nyquist frequency keep every component.

    Notes
    -----
    Needs uniform sampling and assumes roughly white noise. The first and last ~one cutoff
    period carry larger errors than the rest (typically several times the interior RMSE).
    Use :meth:`resolve_cutoff` to see the cutoff the automatic choice makes.
    """

    name = "spectral"
    requires_uniform = True

    def __init__(self, cutoff: float | None = None) -> None:
        self.cutoff = _positive_or_none("cutoff", "spectral", cutoff, allow_zero=False)

    def _check(self, traj: Trajectory) -> None:
        if traj.n_samples < _SPECTRAL_MIN_SAMPLES:
            raise DataError(
                f"spectral differentiation needs at least {_SPECTRAL_MIN_SAMPLES} samples, the "
                f"record has {traj.n_samples}; give a longer record or use --derivatives fd"
            )
        super()._check(traj)

    def resolve_cutoff(self, t: Any, x: Any) -> float:
        """The cutoff frequency (cycles per unit of ``t``) used for this record."""
        traj = _as_record(t, x)
        self._check(traj)
        dt = float(np.median(np.diff(traj.t)))
        tt = np.arange(traj.n_samples) * dt
        return self._first_pass(tt, traj.x, dt)

    def _first_pass(self, tt: np.ndarray, x: np.ndarray, dt: float) -> float:
        if self.cutoff is not None:
            return self.cutoff
        from scipy.stats import chi2

        line = x[0] + (x[-1] - x[0]) * tt / tt[-1]
        R, f, _ = _odd_spectrum(x - line, dt)
        power = np.abs(R[1:]) ** 2
        f = f[1:]
        noise_mean = float(np.median(power[power.shape[0] // 2 :])) / chi2.median(1)
        threshold = noise_mean * chi2.isf(_FALSE_ALARM / power.shape[0], 1)
        above = np.flatnonzero(power > threshold)
        return float(f[above[-1]]) if above.size else float(f[0])

    def _differentiate(self, t: np.ndarray, x: np.ndarray) -> Triple:
        from scipy import fft as _fft

        n = x.shape[0]
        dt = float(np.median(np.diff(t)))
        tt = np.arange(n) * dt
        fc = self._first_pass(tt, x, dt)

        # End values and curvatures from least-squares cubics over ~one cutoff period.
        w = int(min(max(round(1.0 / (fc * dt)), 6), n // 2))
        k = np.arange(w, dtype=float)
        c0 = np.polynomial.polynomial.polyfit(k, x[:w], 3)
        c1 = np.polynomial.polynomial.polyfit(k - (w - 1), x[n - w :], 3)
        trend = _cubic_end_trend(tt, (c0[0], c1[0], 2.0 * c0[2] / dt**2, 2.0 * c1[2] / dt**2))

        R, f, m = _odd_spectrum(x - trend[0], dt)
        R[f > fc] = 0.0
        iw = 2j * np.pi * f
        R1 = R * iw
        if m % 2 == 0:
            R1[-1] = 0.0  # the Nyquist term has no well-defined odd derivative
        x_hat = _fft.irfft(R, m)[:n] + trend[0]
        v = _fft.irfft(R1, m)[:n] + trend[1]
        a = _fft.irfft(R * iw * iw, m)[:n] + trend[2]
        return x_hat, v, a


# ---------------------------------------------------------------------------------- finite diff.
@final
class FiniteDifference(Differentiator):
    """Second-order central differences (``np.gradient`` twice, second-order one-sided at the ends).

    No smoothing: ``x̂ = x``. The naive baseline; noise of standard deviation σ becomes noise of
    order ``σ / dt²`` in ``x''``. Works with non-uniform sampling.
    """

    name = "fd"

    def __init__(self) -> None:
        pass

    def _check(self, traj: Trajectory) -> None:
        if traj.n_samples < 3:
            raise DataError(
                f"finite differences need at least 3 samples, the record has {traj.n_samples}; "
                "give a longer record"
            )

    def _differentiate(self, t: np.ndarray, x: np.ndarray) -> Triple:
        v = np.gradient(x, t, edge_order=2)
        a = np.gradient(v, t, edge_order=2)
        return x.copy(), v, a


# ---------------------------------------------------------------------------------- registry
_CLASSES: dict[str, type[Differentiator]] = {
    "given": Given,
    "savgol": SavitzkyGolay,
    "spline": SmoothingSpline,
    "spectral": Spectral,
    "fd": FiniteDifference,
}


def _param_names(cls: type[Differentiator]) -> list[str]:
    return [p for p in inspect.signature(cls.__init__).parameters if p != "self"]


def make_differentiator(name_or_obj: str | Differentiator, **params: Any) -> Differentiator:
    """A differentiator from its name (see :data:`DIFFERENTIATOR_NAMES`) and parameters.

    An instance is returned as it is (then no parameters may be given).

    >>> make_differentiator("savgol", window=51)
    SavitzkyGolay(window=51, order=3, mode='interp')
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
