"""Grey-box benchmark systems with a hidden state: a two-tank process and the Bouc-Wen hysteresis.

Both return records of the measured signal only (a :class:`~charcurves.data.Trajectory` with ``x``
the measured state and ``F`` the input); :meth:`states` gives every state without noise, for
checking what a fit recovers. Inputs are sampled and linearly interpolated between samples (the
hold output error assumes), every random choice from ``seed``.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .._errors import ConfigError
from ..data import Trajectory

__all__ = ["TwoTank", "BoucWen"]


def _integrate(rhs, y0, t, u, max_step):
    from scipy.integrate import solve_ivp

    def f(tt, y):
        return rhs(y, float(np.interp(tt, t, u)))

    sol = solve_ivp(f, (t[0], t[-1]), np.asarray(y0, dtype=float), t_eval=t, method="RK45", rtol=1e-9, atol=1e-12,
                    max_step=max_step)
    if not sol.success:
        raise ConfigError(f"the simulation failed ({sol.message}); use a shorter record or a smaller input")
    return sol.y


@dataclasses.dataclass(frozen=True)
class TwoTank:
    """Two tanks in cascade, the lower level measured: ``x1' = g u - f1(x1); x2' = f1(x1) - f2(x2)``.

    The outflows are square-root-like, ``f_i(h) = k_i (sqrt(h + h0) - sqrt(h0))`` (Torricelli's
    law, with a laminar region of size ``h0`` near the empty tank that keeps the slope finite);
    with ``overflow`` the upper tank spills what exceeds ``h_max``. The input is a seeded staircase
    of pump levels (a new level every ``hold`` seconds on average), the tanks start empty, and
    Gaussian noise of standard deviation ``noise`` is added to the measured level only.

    Examples
    --------
    >>> from charcurves.systems import TwoTank
    >>> record = TwoTank().simulate(n_points=201, t_end=200.0, seed=0)
    >>> record.n_samples, round(float(record.x[0]), 3)
    (201, 0.001)
    >>> round(float(TwoTank().f1(4.0)), 4)
    1.7889
    """

    k1: float = 1.0
    k2: float = 0.8
    g: float = 1.0
    h0: float = 0.05
    u_low: float = 0.3
    u_high: float = 2.5
    hold: float = 25.0
    noise: float = 0.01
    overflow: bool = False
    h_max: float = 8.0

    def f1(self, h):
        return self.k1 * (np.sqrt(np.maximum(np.asarray(h, dtype=float), -self.h0) + self.h0) - math.sqrt(self.h0))

    def f2(self, h):
        return self.k2 * (np.sqrt(np.maximum(np.asarray(h, dtype=float), -self.h0) + self.h0) - math.sqrt(self.h0))

    def input(self, t, seed: int = 0) -> np.ndarray:
        rng = np.random.default_rng(seed)
        edges, at = [], float(t[0])
        while at < t[-1]:
            edges.append(at)
            at += rng.uniform(0.4, 1.6) * self.hold
        levels = rng.uniform(self.u_low, self.u_high, len(edges))
        return levels[np.searchsorted(np.asarray(edges), t, side="right") - 1]

    def states(self, n_points: int = 1000, t_end: float = 1000.0, seed: int = 0) -> dict:
        """Noise-free ``t, u, x1, x2``."""
        t = np.linspace(0.0, float(t_end), int(n_points))
        u = self.input(t, seed)

        def rhs(y, uu):
            inflow = self.g * uu
            if self.overflow and y[0] >= self.h_max and inflow > self.f1(y[0]):
                inflow = float(self.f1(y[0]))
            q1 = float(self.f1(y[0]))
            return [inflow - q1, q1 - float(self.f2(y[1]))]

        y = _integrate(rhs, [0.0, 0.0], t, u, max_step=t[1] - t[0])
        return {"t": t, "u": u, "x1": y[0], "x2": y[1]}

    def simulate(self, n_points: int = 1000, t_end: float = 1000.0, seed: int = 0) -> Trajectory:
        """The measured record: ``x`` the lower level with noise, ``F`` the pump input."""
        s = self.states(n_points, t_end, seed)
        noise = np.random.default_rng([seed, 1]).normal(0.0, self.noise, s["t"].size)
        return Trajectory(t=s["t"], x=s["x2"] + noise, F=s["u"], name="two-tank")


@dataclasses.dataclass(frozen=True)
class BoucWen:
    """The Bouc-Wen hysteretic benchmark (Noel & Schoukens 2016), the displacement measured.

    ``m y'' + c y' + k y + z = u``, ``z' = alpha y' - beta (gamma |y'| |z|^(nu-1) z + delta y' |z|^nu)``
    with m = 2, c = 10, k = 5e4, alpha = 5e4, beta = 1e3, gamma = 0.8, delta = -1.1, nu = 1 (the
    published definition). Per unit mass, with ``w = z / m`` (the state the template sees):
    ``y'' + (c/m) y' + (k/m) y + w = u/m`` and ``w' = (alpha/m) y' - beta gamma |y'| w - beta delta y' |w|``.

    Sampling at 750 Hz, the published rate. Not sourced here (the benchmark's description was not
    available to this session): the test inputs' exact definitions. :meth:`multisine` is a
    random-phase multisine of ``band`` (default 5-150 Hz) and RMS ``rms`` (default 50 N), one
    period of ``period`` samples (default 8192); :meth:`sweep` a linear sine sweep of amplitude
    ``amplitude`` (default 50 N) from 20 to 50 Hz; the output noise default (``noise``) is a
    standard deviation chosen here, not the benchmark's. Integration: RK45 at tight tolerances
    (the benchmark used Newmark's rule at 15 kHz). The benchmark's records as a split
    (estimation, multisine and sine-sweep tests): :func:`charcurves.datasets.bouc_wen`.

    Examples
    --------
    >>> from charcurves.systems import BoucWen
    >>> system = BoucWen()
    >>> record = system.simulate(system.multisine(seed=0, period=150), seed=0)
    >>> record.n_samples, round(record.dt * 750, 6)
    (150, 1.0)
    """

    m: float = 2.0
    c: float = 10.0
    k: float = 5e4
    alpha: float = 5e4
    beta: float = 1e3
    gamma: float = 0.8
    delta: float = -1.1
    nu: float = 1.0
    fs: float = 750.0
    noise: float = 8e-6

    def multisine(self, seed: int = 0, period: int = 8192, periods: int = 1, band=(5.0, 150.0), rms: float = 50.0):
        """A random-phase multisine (flat amplitude over ``band``), ``periods`` periods."""
        rng = np.random.default_rng(seed)
        n = int(period)
        freqs = np.fft.rfftfreq(n, 1.0 / self.fs)
        lines = np.flatnonzero((freqs >= band[0]) & (freqs <= band[1]))
        spec = np.zeros(freqs.size, dtype=complex)
        spec[lines] = np.exp(2j * np.pi * rng.uniform(size=lines.size))
        u = np.fft.irfft(spec, n)
        u *= rms / np.sqrt(np.mean(u ** 2))
        return np.tile(u, int(periods))

    def sweep(self, n: int = 8192, f0: float = 20.0, f1: float = 50.0, amplitude: float = 50.0):
        t = np.arange(int(n)) / self.fs
        T = t[-1] if t[-1] > 0 else 1.0
        return amplitude * np.sin(2 * np.pi * (f0 * t + 0.5 * (f1 - f0) / T * t ** 2))

    def curves(self) -> dict:
        """The template's curves per unit mass (see the class docstring)."""
        m, b = self.m, self.beta
        return {"f1": lambda v: self.c / m * np.asarray(v), "f2": lambda x: self.k / m * np.asarray(x),
                "f3": lambda w: -b * self.gamma * np.asarray(w),
                "f4": lambda w: self.alpha / m - b * self.delta * np.abs(w)}

    def states(self, u) -> dict:
        """Noise-free ``t, u, y, v, w`` (``w = z / m``) from rest."""
        u = np.asarray(u, dtype=float)
        t = np.arange(u.size) / self.fs

        def rhs(s, uu):
            y, v, z = s
            dz = self.alpha * v - self.beta * (self.gamma * abs(v) * abs(z) ** (self.nu - 1) * z
                                               + self.delta * v * abs(z) ** self.nu)
            return [v, (uu - self.c * v - self.k * y - z) / self.m, dz]

        s = _integrate(rhs, [0.0, 0.0, 0.0], t, u, max_step=1.0 / self.fs)
        return {"t": t, "u": u, "y": s[0], "v": s[1], "w": s[2] / self.m}

    def simulate(self, u, seed: int = 0) -> Trajectory:
        """The measured record: ``x`` the displacement with noise, ``F`` the input force."""
        s = self.states(u)
        noise = np.random.default_rng([seed, 2]).normal(0.0, self.noise, s["t"].size)
        return Trajectory(t=s["t"], x=s["y"] + noise, F=s["u"], name="bouc-wen")
