"""The noise floor of an equation's loss: what a perfect fit leaves, from the record's own noise
(Savitzky-Golay residuals of the forcing and the acceleration) or from a given SNR. Every fit
compares its loss with it (``info["self_check"]``), and so does selection's inner loop."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np

from .._errors import DataError

__all__ = ["NoiseFloor", "noise_floor", "equation_floors", "noise_variance", "REL_FLOOR", "NOISE_SETTINGS"]


#: floor on the noise floor, relative to the forcing's variance (a noise-free record is at 40 dB)
REL_FLOOR = 1e-4


# --------------------------------------------------------------------------- noise floor
@dataclasses.dataclass
class NoiseFloor:
    """Variance of the measurement noise in the equation's units (what a perfect fit leaves).

    ``floor = g² σ_F² + σ_a² + REL_FLOOR · g² var(F)``; ``source`` says where σ_F came from.

    Examples
    --------
    >>> from charcurves.data import NoiseFloor, noise_floor
    >>> from charcurves.systems import get_system
    >>> nf = noise_floor(get_system("duffing").simulate(), snr_db=20)
    >>> isinstance(nf, NoiseFloor), nf.source
    (True, 'given SNR 20 dB')
    >>> print(f"{nf.floor:.5f}")
    0.00126
    """

    sigma2_force: float
    sigma2_acceleration: float
    floor: float
    source: str

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def _local_polynomial_weights(window: int, order: int) -> np.ndarray:
    """Weights of the value at the centre of a least-squares polynomial of ``order`` fitted to
    ``window`` samples (the Savitzky-Golay smoothing weights): the first row of the pseudo-inverse
    of the window's Vandermonde matrix.

    numpy.polynomial's Vandermonde and numpy's pseudo-inverse instead of scipy.signal.savgol_coeffs:
    the same weights (to rounding), without importing scipy.signal, which costs about 0.5-1 s of the
    fit process (a sixth of a whole 1 000-sample ``charcurves fit``) for these few numbers.
    """
    z = (np.arange(window, dtype=float) - window // 2) / max(window // 2, 1)  # on [-1, 1]: well conditioned
    return np.linalg.pinv(np.polynomial.polynomial.polyvander(z, order))[0]


def _savgol_noise_variance(y: np.ndarray, window: int, order: int) -> float:
    """White-noise variance of ``y`` from the residual of a local polynomial (Savitzky-Golay) fit.

    For white noise of variance s² the residual of a linear smoother with central weight h0
    has variance s² (1 - h0) at interior points, hence the division. Only interior points (a
    window away from either end) are used, so the filter's edge handling plays no part.
    """
    y = np.asarray(y, dtype=float)
    if y.size < 3 * window:
        raise DataError(f"a record of {y.size} samples is too short to estimate its noise floor "
                        f"(needs {3 * window}); give a longer record or the noise level (snr_db)")
    weights = _local_polynomial_weights(window, order)
    half = window // 2
    smooth = np.correlate(y, weights, mode="valid")  # smooth[i - half] is the fit's value at sample i
    resid = y[window:-window] - smooth[window - half:y.size - window - half]
    return float(np.mean(resid**2) / (1.0 - float(weights[half])))


#: (window, polynomial order) pairs of the Savitzky-Golay noise estimate; the smallest estimate
#: is kept: every one is unbiased for white noise, and the smallest has the least signal leakage
NOISE_SETTINGS = ((7, 3), (11, 4), (15, 5))


def _noise_variance(y: np.ndarray, settings) -> float:
    return min(_savgol_noise_variance(y, w, o) for w, o in settings)


def noise_variance(y, settings: Sequence[tuple[int, int]] = NOISE_SETTINGS) -> float:
    """Variance of the white noise on a signal sampled finely enough to be smooth over a few samples:
    the residual of Savitzky-Golay fits, the smallest over ``settings`` (window, order) pairs.

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.data import noise_variance
    >>> t = np.linspace(0, 10, 2000)
    >>> y = np.sin(t) + np.random.default_rng(0).normal(scale=0.1, size=t.size)
    >>> round(noise_variance(y), 3)   # 0.1 ** 2
    0.01
    """
    return _noise_variance(np.asarray(y, dtype=float), settings)


def noise_floor(record, *, gain: float = 1.0, snr_db: float | None = None,
                settings: Sequence[tuple[int, int]] = NOISE_SETTINGS,
                acceleration_given: bool | None = None) -> NoiseFloor:
    """Estimate the loss a perfect model would leave on ``record``.

    Parameters
    ----------
    record : Trajectory
        With derivatives when ``acceleration_given``.
    gain : float
        The model's input gain g (the loss is in units of x'').
    snr_db : float, optional
        Known signal-to-noise ratio of the forcing (the paper's definition, on its standard
        deviation); otherwise σ_F² is estimated from Savitzky-Golay residuals of F (the smallest
        over ``settings``, pairs of window and polynomial order), which assumes the noise white
        and F smooth over a few samples.
    acceleration_given : bool, optional
        Whether x'' was measured (its noise then adds to the floor); default: the record has it.

    Examples
    --------
    >>> from charcurves.systems import get_system
    >>> from charcurves.data import corrupt, noise_floor
    >>> record = corrupt(get_system("duffing").simulate(), 20, seed=0)
    >>> nf = noise_floor(record)
    >>> round(nf.sigma2_force, 5)   # the noise added has variance 0.00120
    0.00118
    """
    if getattr(record, "forces", None) is not None:
        return _multi_noise_floor(record, gain, snr_db, settings, acceleration_given)
    F = np.asarray(record.F, dtype=float)
    g2 = float(gain) ** 2
    if snr_db is not None:
        from ._noise import snr_to_eta

        eta2 = snr_to_eta(snr_db) ** 2
        s2f = float(np.var(F)) * eta2 / (1.0 + eta2)  # var(F) = var(clean) (1 + eta²)
        source = f"given SNR {snr_db:g} dB"
    else:
        s2f = _noise_variance(F, settings)
        source = "Savitzky-Golay residual of F (smallest of windows " + ", ".join(f"{w}/{o}" for w, o in settings) + ")"
    s2a = 0.0
    if acceleration_given is None:
        acceleration_given = record.a is not None
    if acceleration_given and record.a is not None and snr_db is None:
        s2a = _noise_variance(np.asarray(record.a), settings)
    floor = g2 * s2f + s2a + REL_FLOOR * g2 * float(np.var(F))
    return NoiseFloor(sigma2_force=s2f, sigma2_acceleration=s2a, floor=floor, source=source)


def equation_floors(record, *, gain: float = 1.0, snr_db: float | None = None,
                    settings: Sequence[tuple[int, int]] = NOISE_SETTINGS,
                    acceleration_given: bool | None = None) -> list[NoiseFloor]:
    """The noise floor of each equation of ``record``: one for a one-DOF record, one per forcing
    column (with its state's x'') for a :class:`MultiTrajectory`; arguments as :func:`noise_floor`.

    Examples
    --------
    >>> from charcurves.systems import get_system
    >>> from charcurves.data import corrupt, equation_floors
    >>> record = corrupt(get_system("duffing").simulate(), 20, seed=0)
    >>> [round(nf.floor, 5) for nf in equation_floors(record, snr_db=20)]
    [0.00127]
    """
    if getattr(record, "forces", None) is None:
        return [noise_floor(record, gain=gain, snr_db=snr_db, settings=settings,
                            acceleration_given=acceleration_given)]
    from ._trajectory import Trajectory

    accs = record.accelerations or {}
    states = list(record.states)
    parts = []
    for k, name in enumerate(record.forces):
        state = states[min(k, len(states) - 1)]
        a = accs.get(state)
        one = Trajectory(record.t, record.states[state], record.forces[name], None if a is None else
                         record.velocities[state], a, name=record.name)
        parts.append(noise_floor(one, gain=gain, snr_db=snr_db, settings=settings,
                                 acceleration_given=acceleration_given))
    return parts


def _multi_noise_floor(record, gain, snr_db, settings, acceleration_given) -> NoiseFloor:
    """Several equations, each with its forcing column (and its state's x''): the model's loss is
    the mean squared residual over all of them, so the floor is the mean of their floors."""
    parts = equation_floors(record, gain=gain, snr_db=snr_db, settings=settings,
                            acceleration_given=acceleration_given)
    return NoiseFloor(sigma2_force=float(np.mean([p.sigma2_force for p in parts])),
                      sigma2_acceleration=float(np.mean([p.sigma2_acceleration for p in parts])),
                      floor=float(np.mean([p.floor for p in parts])),
                      source=parts[0].source + f", mean over the {len(parts)} forcing columns")
