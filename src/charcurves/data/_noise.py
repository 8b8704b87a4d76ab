"""Measurement-noise models: additive Gaussian noise at a given signal-to-noise ratio.

The paper defines SNR(dB) = 10 log10(σ_clean² / σ_n²) with σ_clean the standard deviation of
the clean signal, so σ_n = η σ_clean with the noise fraction η = 10^(−SNR/20). The authors'
scripts use the mean square of the clean forcing instead (``reference="rms"``); the two differ
only when the clean signal has a non-zero mean.
"""

from __future__ import annotations

import math
import numbers
from typing import Any

import numpy as np

from .._errors import ConfigError, DataError
from ._trajectory import Trajectory

__all__ = ["snr_to_eta", "noise_sigma", "add_noise", "corrupt", "as_rng", "NOISE_TARGETS", "NOISE_REFERENCES"]

#: Signals :func:`corrupt` can put noise on.
NOISE_TARGETS = ("force", "state")
#: Ways to measure the size of the clean signal.
NOISE_REFERENCES = ("std", "rms")


def _check_snr(snr_db: Any) -> float:
    # bool is an Integral; "True dB" is surely a mistake, so refuse it.
    if isinstance(snr_db, bool) or not isinstance(snr_db, numbers.Real):
        raise ConfigError(
            f"snr_db must be a real number of decibels (or inf for no noise), got {snr_db!r}; "
            "pass e.g. snr_db=20"
        )
    value = float(snr_db)
    if math.isnan(value):
        raise ConfigError("snr_db is NaN; pass a number of decibels, e.g. snr_db=20, or inf for no noise")
    if value == -math.inf:
        raise ConfigError("snr_db is -inf (infinitely large noise); pass a finite SNR or inf for no noise")
    if value == math.inf:
        return value
    from .._bounds import check_number

    return check_number("snr_db", value)


def _check_reference(reference: Any) -> str:
    if reference not in NOISE_REFERENCES:
        raise ConfigError(
            f"unknown noise reference {reference!r}; choose one of {', '.join(map(repr, NOISE_REFERENCES))} "
            "('std': the paper's standard deviation, 'rms': the scripts' mean square)"
        )
    return reference


def _as_signal(clean: Any) -> np.ndarray:
    try:
        arr = np.asarray(clean, dtype=float)
    except (TypeError, ValueError) as exc:
        raise DataError(f"the clean signal is not numeric ({exc}); give an array of numbers") from None
    if arr.size == 0:
        raise DataError("the clean signal is empty; give at least one sample")
    if not np.isfinite(arr).all():
        raise DataError("the clean signal has NaN or infinite values; clean it before adding noise")
    return arr


def as_rng(rng: Any) -> np.random.Generator:
    """A numpy Generator from a Generator, a non-negative integer seed or None (ConfigError otherwise).

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.data import as_rng
    >>> float(as_rng(0).normal()) == float(np.random.default_rng(0).normal())
    True
    >>> gen = np.random.default_rng(1)
    >>> as_rng(gen) is gen
    True
    """
    if isinstance(rng, np.random.Generator):
        return rng
    if rng is None or (isinstance(rng, numbers.Integral) and not isinstance(rng, bool)):
        try:
            return np.random.default_rng(None if rng is None else int(rng))
        except ValueError as exc:  # negative seeds
            raise ConfigError(f"bad random seed {rng!r} ({exc}); give a non-negative integer") from None
    raise ConfigError(
        f"rng must be a numpy.random.Generator or an integer seed, got {type(rng).__name__}; "
        "pass e.g. np.random.default_rng(0) or 0"
    )


def snr_to_eta(snr_db: float) -> float:
    """Noise fraction η = σ_n / σ_clean for a signal-to-noise ratio in dB.

    Parameters
    ----------
    snr_db : float
        Signal-to-noise ratio in decibels; ``inf`` means no noise.

    Returns
    -------
    float
        ``10 ** (-snr_db / 20)``, and 0 for ``inf``.

    Examples
    --------
    >>> from charcurves.data import snr_to_eta
    >>> snr_to_eta(20), snr_to_eta(float("inf"))
    (0.1, 0.0)
    """
    value = _check_snr(snr_db)
    if value == math.inf:
        return 0.0
    return float(10.0 ** (-value / 20.0))


def noise_sigma(clean: Any, snr_db: float, reference: str = "std") -> float:
    """Standard deviation σ_n of the noise that gives ``snr_db`` on ``clean``.

    Parameters
    ----------
    clean : array_like
        The clean signal.
    snr_db : float
        Signal-to-noise ratio in dB (``inf``: 0).
    reference : {"std", "rms"}
        Size of the clean signal: its standard deviation (the paper's definition) or its root
        mean square (the authors' scripts, σ_n² = mean(F²) / 10^(SNR/10)).

    Returns
    -------
    float
        σ_n = η · σ_clean.

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.data import noise_sigma
    >>> F = 2 * np.sin(np.linspace(0, 20 * np.pi, 4000))
    >>> print(f"{noise_sigma(F, 20):.4f}")
    0.1414
    >>> print(f"{noise_sigma(F + 1, 20, reference='rms'):.4f}")
    0.1732
    """
    eta = snr_to_eta(snr_db)
    reference = _check_reference(reference)
    arr = _as_signal(clean)
    if eta == 0.0:
        return 0.0
    scale = float(np.std(arr)) if reference == "std" else float(np.sqrt(np.mean(arr**2)))
    if scale == 0.0:
        what = "constant" if reference == "std" else "identically zero"
        fix = " or use reference='rms'" if reference == "std" else ""
        raise DataError(
            f"the clean signal is {what}, so an SNR relative to its {reference} is undefined; "
            f"give a varying signal{fix}"
        )
    return eta * scale


def add_noise(clean: Any, snr_db: float, rng: Any = None, reference: str = "std") -> np.ndarray:
    """Return ``clean`` plus i.i.d. Gaussian noise of standard deviation :func:`noise_sigma`.

    Parameters
    ----------
    clean : array_like
        The clean signal (any shape).
    snr_db : float
        Signal-to-noise ratio in dB; ``inf`` returns an unchanged copy.
    rng : numpy.random.Generator or int, optional
        Random source or seed (``None``: fresh entropy, not reproducible).
    reference : {"std", "rms"}
        See :func:`noise_sigma`.

    Returns
    -------
    numpy.ndarray
        A new float array of the same shape.

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.data import add_noise
    >>> y = add_noise(np.sin(np.linspace(0, 10, 1000)), 20, rng=0)
    >>> y.shape
    (1000,)
    """
    sigma = noise_sigma(clean, snr_db, reference)
    gen = as_rng(rng)
    arr = np.array(clean, dtype=float)  # a copy, also for SNR = inf
    if sigma == 0.0:
        return arr
    return arr + gen.normal(0.0, sigma, size=arr.shape)


def corrupt(
    traj: Trajectory,
    snr_db: float,
    *,
    on: str = "force",
    seed: Any = None,
    reference: str | None = None,
) -> Trajectory:
    """A copy of ``traj`` with Gaussian measurement noise on the forcing or on the state.

    Parameters
    ----------
    traj : Trajectory
        The clean record.
    snr_db : float
        Signal-to-noise ratio in dB (``inf``: no noise added).
    on : {"force", "state"}
        ``"force"``: ``F`` is replaced by a noisy copy, ``x``, ``v``, ``a`` kept (the paper's main
        text). ``"state"``: ``x`` is replaced by a noisy copy and ``v``, ``a`` are dropped, so they
        must be estimated by a differentiator (the paper's Appendix F).
    seed : None, int or numpy.random.Generator
        Random source.
    reference : {"std", "rms"}, optional
        Size of the clean signal (see :func:`noise_sigma`); default ``"std"``. State noise is
        always relative to the standard deviation of ``x``.

    Returns
    -------
    Trajectory

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.data import corrupt
    >>> from charcurves.systems import get_system
    >>> clean = get_system("duffing").simulate()
    >>> noisy = corrupt(clean, 20, seed=0)
    >>> print(f"{np.std(noisy.F - clean.F) / np.std(clean.F):.2f}")
    0.10
    >>> corrupt(clean, 30, on="state", seed=0).v is None
    True
    """
    if not isinstance(traj, Trajectory):
        raise DataError(f"corrupt() needs a Trajectory, got {type(traj).__name__}")
    if on not in NOISE_TARGETS:
        raise ConfigError(
            f"unknown noise target on={on!r}; choose one of {', '.join(map(repr, NOISE_TARGETS))}"
        )
    if on == "force":
        ref = _check_reference("std" if reference is None else reference)
        return traj.replace(F=add_noise(traj.F, snr_db, seed, ref))
    if reference not in (None, "std"):
        raise ConfigError(
            f"state noise is always relative to the standard deviation of x, got reference={reference!r}; "
            "leave reference unset (or 'std') with on='state'"
        )
    # The clean derivatives would leak the noise-free state into the fit, so drop them.
    return traj.replace(x=add_noise(traj.x, snr_db, seed, "std"), v=None, a=None)
