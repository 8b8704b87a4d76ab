"""FFT differentiation with an automatic noise-floor cutoff."""

from __future__ import annotations

from typing import Any, final

import numpy as np

from .._errors import DataError
from ._diff_base import Differentiator, Triple, _as_record, _positive_or_none
from ._trajectory import Trajectory


# ---------------------------------------------------------------------------------- spectral
_SPECTRAL_MIN_SAMPLES = 16
_FALSE_ALARM = 0.01  # chance that pure noise pushes the automatic cutoff above the signal band
# The highest exceedance is taken for noise, not signal, when it lies more than an octave and more than
# this fraction of the band above every other one, and below this multiple of the threshold: pure noise
# reaches twice the threshold with a chance of about 4e-7 in a band of 1000 bins, and a false alarm lands
# anywhere in the band, most often far above the signal
_LONE_GAP = 0.05
_LONE_FACTOR = 2.0


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


def _lone_false_alarm(f: np.ndarray, power: np.ndarray, above: np.ndarray, threshold: float) -> bool:
    """True when the highest exceedance ``above[-1]`` lies more than an octave and more than
    ``_LONE_GAP`` of the band above the next one and below ``_LONE_FACTOR`` times the threshold."""
    top, below = above[-1], above[-2]
    return bool(f[top] > 2.0 * f[below] and top - below > _LONE_GAP * power.shape[0]
                and power[top] < _LONE_FACTOR * threshold)


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
       that pure noise exceeds with probability 1 % anywhere in the band. That 1 % is the chance
       of one false alarm, which lands anywhere in the band: the highest exceedance is taken for
       noise when it lies more than an octave and more than 5 % of the band above every other
       one and below twice the level (a genuine component far above the signal band passes
       that level; noise, with a chance of about 4e-7). A first pass with a straight-line trend
       sets this cutoff and the end-fit length.
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

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.data import Spectral
    >>> t = np.linspace(0, 20, 1000)
    >>> x = np.sin(t) + 0.01 * np.random.default_rng(0).standard_normal(1000)
    >>> x_hat, v, a = Spectral()(t, x)
    >>> print(f"{np.sqrt(np.mean((a + np.sin(t))[50:-50] ** 2)):.3f}")
    0.061
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
        if above.size >= 2 and _lone_false_alarm(f, power, above, threshold):
            above = above[:-1]
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
