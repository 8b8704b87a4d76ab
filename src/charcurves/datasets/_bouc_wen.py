"""The Bouc-Wen hysteretic benchmark (Noel & Schoukens, 2016), generated from its published definition.

``m y'' + c y' + k y + z = u``, ``z' = alpha y' - beta (gamma |y'| |z|^(nu-1) z + delta y' |z|^nu)``
with m = 2, c = 10, k = 5e4, alpha = 5e4, beta = 1e3, gamma = 0.8, delta = -1.1, nu = 1; the input
u is a force (N), the measured output y a displacement (m), sampled at 750 Hz.

What is sourced and what is chosen here (the benchmark's own description, "Hysteretic benchmark
with a dynamic nonlinearity", could not be read beyond its introduction in the stored text):

* sourced: the equations and the parameters above (issue 47, and the same values in deepSI's
  reproduction ``deepSI.systems.Bouc_wen``); the sampling at 750 Hz, simulated at 20 times that rate
  (15 kHz; deepSI's ``dt = 1/750, integration_factor = 20``); the two test records, a multisine
  and a sine sweep (``uval_multisine``, ``uval_sinesweep`` of the benchmark's files); estimation
  data of 5 blocks of 8192 samples (users' code reshapes the distributed ``u`` to 8192 x 5);
  output noise of standard deviation 8e-6 m (deepSI's reproduction; it also low-pass filters it,
  which is not done here).
* chosen here, not read from the description: the multisines' band (5-150 Hz) and RMS (50 N),
  flat amplitudes and uniform random phases, the blocks being periods of one realisation, the
  sweep's range (20-50 Hz, linear), amplitude (50 N) and length (8192 samples), white noise, the
  initialisation window (50 samples, as the Silverbox's), and the integration: classical RK4 at 20
  steps per sample (15 kHz) reading the input as the smooth function of time it is (a sum of
  cosines, a chirp) at the half-steps; the description uses Newmark's rule at 15 kHz.

Every record starts from rest; every random choice comes from ``seed``.
"""

from __future__ import annotations

import numpy as np

from .._errors import ConfigError
from ._base import BenchmarkData

__all__ = ["bouc_wen", "BOUC_WEN_FS", "BOUC_WEN_PARAMETERS", "BOUC_WEN_INIT_WINDOW", "bouc_wen_output"]

#: sampling frequency, Hz
BOUC_WEN_FS = 750.0
#: the published parameters (SI units)
BOUC_WEN_PARAMETERS = {"m": 2.0, "c": 10.0, "k": 5e4, "alpha": 5e4, "beta": 1e3, "gamma": 0.8, "delta": -1.1,
                       "nu": 1.0}
#: samples at the start of each test that only fit its initial state (chosen here, see the module docstring)
BOUC_WEN_INIT_WINDOW = 50
#: samples of one multisine period
PERIOD = 8192
#: the integration's largest step: 20 steps per sample (15 kHz)
UPSAMPLE = 20


#: input values per sample the integration reads (RK4 at 20 steps per sample reads the half-steps)
FINE = 2 * UPSAMPLE


class _Multisine:
    """``sum_k A cos(2 pi f_k t + phi_k)`` over the lines of ``band`` (period ``period / fs``),
    scaled to ``rms``, with uniform random phases from ``rng``."""

    def __init__(self, rng, band, rms: float, period: int = PERIOD):
        self.period = int(period)
        freqs = np.fft.rfftfreq(self.period, 1.0 / BOUC_WEN_FS)
        self.lines = np.flatnonzero((freqs >= band[0]) & (freqs <= band[1]))
        if self.lines.size == 0:
            raise ConfigError(f"the multisine band {band} holds no frequency line of a {self.period}-sample period; "
                              "give a wider band, e.g. (5.0, 150.0)")
        self.phi = rng.uniform(0.0, 2.0 * np.pi, self.lines.size)
        self.amp = float(rms) * np.sqrt(2.0 / self.lines.size)  # a sum of K unit cosines has RMS sqrt(K / 2)

    def fine(self, n: int) -> np.ndarray:
        """The input at ``t = j / (FINE fs)``, ``j = 0 .. FINE (n - 1)``: exact (an inverse FFT of
        the line spectrum on the fine grid), periodic over ``period`` samples."""
        size = self.period * FINE
        spec = np.zeros(size // 2 + 1, dtype=complex)
        spec[self.lines] = 0.5 * size * self.amp * np.exp(1j * self.phi)
        one = np.fft.irfft(spec, size)
        reps = -(-(FINE * (int(n) - 1) + 1) // size)
        return np.tile(one, reps)[:FINE * (int(n) - 1) + 1]


class _Sweep:
    """``A sin(2 pi (f0 t + (f1 - f0) t^2 / (2 T)))``: a linear sweep from f0 to f1 over T seconds."""

    def __init__(self, n: int, f0: float, f1: float, amplitude: float):
        self.T, self.f0, self.f1, self.A = (int(n) - 1) / BOUC_WEN_FS, float(f0), float(f1), float(amplitude)

    def fine(self, n: int) -> np.ndarray:
        t = np.arange(FINE * (int(n) - 1) + 1) / (FINE * BOUC_WEN_FS)
        return self.A * np.sin(2.0 * np.pi * (self.f0 * t + 0.5 * (self.f1 - self.f0) / self.T * t ** 2))


def bouc_wen_output(u_fine, parameters=None) -> dict:
    """Noise-free ``t, u, y, v, z`` of the Bouc-Wen system from rest, at 750 Hz.

    ``u_fine`` is the force at ``t = j / (40 * 750)`` s, ``j = 0 .. 40 (n - 1)`` (``n`` samples): the
    system is integrated by classical RK4 at 20 steps per sample (15 kHz), which reads the input
    at its half-steps; ``u`` is ``u_fine`` at the samples.

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.datasets import bouc_wen_output
    >>> t = np.arange(40 * 299 + 1) / (40 * 750.0)
    >>> s = bouc_wen_output(50.0 * np.sin(2 * np.pi * 10.0 * t))
    >>> s["y"].shape, float(s["y"][0]), bool(0 < np.abs(s["y"]).max() < 2e-3)
    ((300,), 0.0, True)
    """
    p = {**BOUC_WEN_PARAMETERS, **(parameters or {})}
    m, c, k, alpha, beta, gamma, delta, nu = (float(p[name]) for name in ("m", "c", "k", "alpha", "beta", "gamma",
                                                                           "delta", "nu"))
    u_fine = np.asarray(u_fine, dtype=float)
    if u_fine.ndim != 1 or (u_fine.size - 1) % FINE or u_fine.size < FINE + 1:
        raise ConfigError(f"u_fine must hold {FINE} values per sample plus one (the force at t = j / ({FINE} fs)), "
                          f"got {u_fine.size}; give {FINE} * (n - 1) + 1 values for n samples")
    n = (u_fine.size - 1) // FINE + 1
    h = 1.0 / (BOUC_WEN_FS * UPSAMPLE)
    uf = u_fine.tolist()
    out = np.zeros((n, 3))
    y = v = z = 0.0

    def f(y, v, z, u):
        az = abs(z)
        dz = alpha * v - beta * (gamma * abs(v) * az ** (nu - 1.0) * z + delta * v * az ** nu)
        return v, (u - c * v - k * y - z) / m, dz

    for j in range(n - 1):
        for s in range(UPSAMPLE):
            i = FINE * j + 2 * s
            u0, u1, u2 = uf[i], uf[i + 1], uf[i + 2]
            a1, b1, c1 = f(y, v, z, u0)
            a2, b2, c2 = f(y + 0.5 * h * a1, v + 0.5 * h * b1, z + 0.5 * h * c1, u1)
            a3, b3, c3 = f(y + 0.5 * h * a2, v + 0.5 * h * b2, z + 0.5 * h * c2, u1)
            a4, b4, c4 = f(y + h * a3, v + h * b3, z + h * c3, u2)
            y += h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
            v += h / 6.0 * (b1 + 2.0 * b2 + 2.0 * b3 + b4)
            z += h / 6.0 * (c1 + 2.0 * c2 + 2.0 * c3 + c4)
        out[j + 1] = y, v, z
    if not np.isfinite(out).all():
        raise ConfigError("the Bouc-Wen simulation diverged; give a smaller input amplitude")
    return {"t": np.arange(n) / BOUC_WEN_FS, "u": u_fine[::FINE].copy(), "y": out[:, 0], "v": out[:, 1],
            "z": out[:, 2]}


def bouc_wen(data_dir=None, *, seed: int = 0, periods: int = 5, noise: float = 8e-6, band=(5.0, 150.0),
             rms: float = 50.0, sweep=(20.0, 50.0), sweep_amplitude: float = 50.0,
             sweep_samples: int = PERIOD, period: int = PERIOD) -> BenchmarkData:
    """The Bouc-Wen benchmark generated from its published definition (module docstring: what is
    sourced, what is chosen here).

    Parameters
    ----------
    data_dir : ignored
        The records are simulated (the argument keeps the loaders' signature).
    seed : int
        The multisines' phases and the noise.
    periods : int
        Periods of the estimation multisine (default 5: 40960 samples).
    period : int
        Samples of one multisine period (default 8192, the benchmark's; fewer for a quick run).
    noise : float
        Standard deviation of white Gaussian noise on the measured displacement, m (0: clean).
    band, rms : the multisines' frequency band (Hz) and RMS (N).
    sweep, sweep_amplitude, sweep_samples : the sine sweep's start and end frequency (Hz),
        amplitude (N) and length.

    Returns
    -------
    BenchmarkData
        ``estimation`` (x: the displacement with noise, F: the force), ``tests`` ``"multisine"``
        (another realisation, one period) and ``"sinesweep"``, ``init_window`` 50, unit ``"m"``;
        ``literature`` is empty (no published figure of these generated records is quoted).

    Examples
    --------
    >>> from charcurves.datasets import bouc_wen
    >>> data = bouc_wen(seed=0, periods=1, sweep_samples=2000)
    >>> data.estimation.n_samples, list(data.tests), data.tests["sinesweep"].n_samples, data.init_window
    (8192, ['multisine', 'sinesweep'], 2000, 50)
    >>> round(1.0 / data.estimation.dt, 6)
    750.0
    """
    from ..data import Trajectory

    if isinstance(periods, bool) or not isinstance(periods, (int, np.integer)) or periods < 1:
        raise ConfigError(f"periods must be a whole number of at least 1, got {periods!r}; give e.g. periods=5")
    if not (np.isfinite(noise) and noise >= 0):
        raise ConfigError(f"noise must be a standard deviation >= 0 (m), got {noise!r}; give e.g. noise=8e-6")
    if isinstance(period, bool) or not isinstance(period, (int, np.integer)) or period < BOUC_WEN_INIT_WINDOW + 16:
        raise ConfigError(f"period must be a whole number of at least {BOUC_WEN_INIT_WINDOW + 16} samples, got "
                          f"{period!r}; give e.g. period=8192")
    if isinstance(sweep_samples, bool) or not isinstance(sweep_samples, (int, np.integer)) or \
            sweep_samples < BOUC_WEN_INIT_WINDOW + 16:
        raise ConfigError(f"sweep_samples must be a whole number of at least {BOUC_WEN_INIT_WINDOW + 16}, got "
                          f"{sweep_samples!r}; give e.g. sweep_samples=8192")
    rng = np.random.default_rng([int(seed), 47])
    inputs: dict[str, tuple[_Multisine | _Sweep, int]] = {
        "estimation": (_Multisine(rng, band, rms, period), int(period) * int(periods)),
        "multisine": (_Multisine(rng, band, rms, period), int(period)),
        "sinesweep": (_Sweep(int(sweep_samples), sweep[0], sweep[1], sweep_amplitude), int(sweep_samples))}
    records = {}
    for name, (source, n) in inputs.items():
        s = bouc_wen_output(source.fine(n))
        y = s["y"] + rng.normal(0.0, float(noise), n) if noise > 0 else s["y"]
        records[name] = Trajectory(t=s["t"], x=y, F=s["u"], name=f"bouc-wen {name}")
    return BenchmarkData(name="bouc-wen", estimation=records.pop("estimation"), tests=records,
                         init_window=BOUC_WEN_INIT_WINDOW, unit="m", literature={},
                         source=f"generated (seed {int(seed)}; charcurves.datasets.bouc_wen)")
