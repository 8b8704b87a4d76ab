"""Kalman / Rauch-Tung-Striebel smoother with an integrated Wiener-process state model.

The state ``s = (x, x', x'')`` (``model="acceleration"``) or ``(x, x', x'', x''')``
(``model="jerk"``) follows a chain of integrators driven by white noise of intensity ``q`` in the
derivative of its last component, and the record measures ``x`` with white noise of variance
``r``. A forward Kalman filter and a backward RTS pass give the posterior mean of the state given
the whole record: ``x̂, x̂', x̂''``. That mean is the natural smoothing spline of degree ``2m - 1``
(``m`` states: quintic for the acceleration model, degree 7 for the jerk model; Wahba 1978,
Kohn & Ansley 1987), and the filter's innovations give the marginal likelihood that chooses
``λ = q/r``.

Written here because no library does it well: scipy has no Kalman smoother; ``derivative.Kalman``
is the constant-velocity model only (first derivatives), solved densely (``O(n³)``) with a fixed
``alpha``; ``pynumdiff.rtsdiff`` returns first derivatives only and needs its ``q/r`` ratio
supplied. A batched solve of the normal equations (banded Cholesky) was tried first and dropped:
with ``m = 4`` and heavy smoothing it is too ill-conditioned in float64 for its log-determinant to
be trusted, where the sequential filter is not.
"""

from __future__ import annotations

import math
from typing import Any, final

import numpy as np

from .._errors import ConfigError, DataError
from ._diff_base import Differentiator, Triple, _as_record, _positive_or_none
from ._trajectory import Trajectory

_MODELS = {"acceleration": 3, "jerk": 4}
_KALMAN_MIN_SAMPLES = 10


def _step_blocks(h: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
    """Transition ``F(h)`` and unit-intensity process covariance ``Q(h)`` per step ``h``.

    ``F_ij = h^(j-i) / (j-i)!`` for ``j >= i``;
    ``Q_ij = h^(2m-1-i-j) / ((2m-1-i-j) (m-1-i)! (m-1-j)!)`` (white noise of unit intensity on the
    derivative of the last state, integrated over the step).
    """
    idx = np.arange(m)
    power = idx[None, :] - idx[:, None]
    fact = np.array([math.factorial(max(int(p), 0)) for p in power.ravel()]).reshape(m, m)
    F = np.where(power >= 0, h[:, None, None] ** np.maximum(power, 0) / fact, 0.0)
    e = 2 * m - 1 - idx[:, None] - idx[None, :]
    f = np.array([math.factorial(m - 1 - i) for i in idx], dtype=float)
    Q = h[:, None, None] ** e / (e * f[:, None] * f[None, :])
    return F, Q


def _filter(y: np.ndarray, F: np.ndarray, Q1: np.ndarray, lam: np.ndarray, keep: bool = False):
    """Kalman filter of ``y`` (unit measurement variance) for several ``λ`` at once.

    ``F`` and ``Q1`` are the per-step transitions and unit-intensity process covariances
    (``(n-1, m, m)``); the process covariance of step ``k`` is ``λ Q1[k]``. The first sample
    initialises ``x`` (variance 1), the other states start diffuse (variance ``κ = 1e6`` on the
    standardised record), and the innovations of samples ``1 .. m-1`` are left out of the
    likelihood (``n - m`` terms remain): de Jong's diffuse likelihood as ``κ → ∞``.

    Returns ``-2 log L`` per ``λ`` with the measurement variance profiled out, that variance's
    estimate ``r̂`` (relative to the unit one assumed) and, with ``keep=True``, the filtered means
    and covariances for the RTS pass.
    """
    n, m = y.shape[0], F.shape[1]
    g = lam.shape[0]
    x = np.zeros((g, m))
    x[:, 0] = y[0]
    P = np.broadcast_to(1e6 * np.eye(m), (g, m, m)).copy()
    P[:, 0, :] = 0.0
    P[:, :, 0] = 0.0
    P[:, 0, 0] = 1.0  # x0 measured with unit variance, the rest diffuse
    quad = np.zeros(g)
    logdet = np.zeros(g)
    if keep:
        xs_f, Ps_f = np.empty((n, g, m)), np.empty((n, g, m, m))
        xs_f[0], Ps_f[0] = x, P
    lamq = lam[:, None, None]
    for k in range(1, n):
        Fk = F[k - 1]
        x = x @ Fk.T
        P = Fk @ P @ Fk.T + lamq * Q1[k - 1]
        S = P[:, 0, 0] + 1.0
        e = y[k] - x[:, 0]
        K = P[:, :, 0] / S[:, None]
        x = x + K * e[:, None]
        P = P - K[:, :, None] * P[:, None, 0, :]
        P = 0.5 * (P + P.transpose(0, 2, 1))
        if k >= m:
            quad += e * e / S
            logdet += np.log(S)
        if keep:
            xs_f[k], Ps_f[k] = x, P
    nll = (n - m) * np.log(np.maximum(quad, 1e-300)) + logdet
    if keep:
        return nll, quad / (n - m), (xs_f, Ps_f)
    return nll, quad / (n - m), None


def _rts(F: np.ndarray, Q: np.ndarray, xs_f: np.ndarray, Ps_f: np.ndarray) -> np.ndarray:
    """Rauch-Tung-Striebel backward pass: smoothed means ``(n, m)`` from the filtered ones."""
    n = xs_f.shape[0]
    xs = np.empty_like(xs_f)
    xs[-1] = xs_f[-1]
    for k in range(n - 2, -1, -1):
        Pf = Ps_f[k]
        Pp = F[k] @ Pf @ F[k].T + Q[k]
        G = np.linalg.solve(Pp, F[k] @ Pf).T  # Pf Fᵀ Pp⁻¹ (Pp symmetric)
        xs[k] = xs_f[k] + G @ (xs[k + 1] - F[k] @ xs_f[k])
    return xs


@final
class KalmanSmoother(Differentiator):
    """Kalman / RTS smoother of an integrated Wiener process; ``q/r`` by maximum likelihood.

    The state model is a chain of integrators, ``x' = v, v' = a, a' = w`` (``"acceleration"``:
    constant acceleration between samples up to white jerk of intensity ``q``) or one integrator
    more (``"jerk"``); the record is ``y = x + e`` with white ``e`` of variance ``r``. The smoothed
    ``x̂, x̂', x̂''`` are the posterior means of the state given the whole record, i.e. the
    Rauch-Tung-Striebel smoother's output.

    The only smoothing parameter is ``λ = q/r`` (in the units of ``t``). ``lam=None`` (default)
    chooses it by maximum likelihood: the diffuse marginal likelihood of the record (prediction
    error decomposition of the Kalman filter, first ``m`` innovations left out), with ``r``
    profiled out, maximised over ``log10 λ`` on a grid of 0.1 decade spanning cutoffs from about
    one cycle per record to beyond the Nyquist frequency, then on a grid of 0.01 decade around
    the best point (each grid runs as one batched filter pass). This is Wahba's generalised
    maximum likelihood (GML) choice of the smoothing spline's parameter. On the paper's Duffing
    record it lands within a factor of ~3 of the ``λ`` that minimises the error of ``x''`` for the
    jerk model; for the acceleration model it smooths ~10x too little there (see
    ``docs/differentiators.md``), which is why ``"jerk"`` is the default.

    Parameters
    ----------
    lam : float or None
        Process-to-measurement noise ratio ``q/r`` in the units of ``t`` (``q`` is per unit time);
        ``None`` chooses it by maximum likelihood. Larger values follow the data more closely.
    model : {"jerk", "acceleration"}
        The state model: constant jerk (states x, x', x'', x'''; a smoothing spline of degree 7;
        the default) or constant acceleration (x, x', x''; a quintic smoothing spline).

    Notes
    -----
    Works with non-uniform sampling (each step has its own transition and process covariance).
    Cost: two batched filter passes for the likelihood search, one filter and one RTS pass for
    the result, Python loops over the samples: ~0.3 s per 1000 samples. Use :meth:`resolve_lam`
    to see the ``λ`` the automatic choice makes.

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.data import KalmanSmoother
    >>> t = np.linspace(0.0, 10.0, 400)
    >>> y = np.sin(t) + 0.01 * np.random.default_rng(0).standard_normal(400)
    >>> x_hat, v, a = KalmanSmoother()(t, y)
    >>> bool(np.sqrt(np.mean((a[20:-20] + np.sin(t[20:-20])) ** 2)) < 0.05)
    True
    """

    name = "kalman"

    def __init__(self, lam: float | None = None, model: str = "jerk") -> None:
        self.lam = _positive_or_none("lam", "Kalman smoother", lam, allow_zero=False)
        if not isinstance(model, str) or model not in _MODELS:
            raise ConfigError(
                f"Kalman smoother model must be 'acceleration' or 'jerk', got {model!r}; "
                "use model='jerk' (the default) or model='acceleration'"
            )
        self.model = model

    def _check(self, traj: Trajectory) -> None:
        if traj.n_samples < _KALMAN_MIN_SAMPLES:
            raise DataError(
                f"the Kalman smoother needs at least {_KALMAN_MIN_SAMPLES} samples, the record has "
                f"{traj.n_samples}; give a longer record or use --derivatives fd"
            )

    def resolve_lam(self, t: Any, x: Any) -> float:
        """The ``λ = q/r`` (units of ``t``) used for this record."""
        traj = _as_record(t, x)
        self._check(traj)
        _, step, blocks, y = self._setup(traj.t, traj.x)
        return self._lam_unit(blocks, y, step) / step ** (2 * blocks[0].shape[1] - 1)

    def _setup(self, t: np.ndarray, x: np.ndarray):
        # Unit-step abscissa (like the spline) and a standardised record keep the filter's
        # numbers of order one; the smoother is equivariant to both.
        step = float(np.median(np.diff(t)))
        scale = float(np.std(x)) or 1.0
        blocks = _step_blocks(np.diff(t) / step, _MODELS[self.model])
        return scale, step, blocks, (x - np.mean(x)) / scale

    def _lam_unit(self, blocks: tuple[np.ndarray, np.ndarray], y: np.ndarray, step: float) -> float:
        F, Q1 = blocks
        m, n = F.shape[1], y.shape[0]
        if self.lam is not None:  # λ has units time^-(2m-1): q is per unit time, r is not
            return self.lam * step ** (2 * m - 1)
        # equivalent low-pass in rad/sample: |H(ω)| ≈ 1 / (1 + ω^(2m) / λ); the grid spans
        # cutoffs from one cycle per record (ω = 2π/n) to beyond Nyquist (ω = π)
        lo = 2 * m * math.log10(2 * math.pi / n)
        hi = 2 * m * math.log10(math.pi) + 1.0
        grid = np.arange(lo, hi + 0.05, 0.1)
        nll, _, _ = _filter(y, F, Q1, 10.0**grid)
        if not np.isfinite(nll).any():
            raise DataError(
                "the Kalman smoother's likelihood is not finite for any smoothing level on this "
                "record; pass lam=... explicitly or use --derivatives spline"
            )
        best = int(np.nanargmin(np.where(np.isfinite(nll), nll, np.nan)))
        fine = grid[best] + np.arange(-0.1, 0.1001, 0.01)
        nll_f, _, _ = _filter(y, F, Q1, 10.0**fine)
        return float(10.0 ** fine[int(np.nanargmin(np.where(np.isfinite(nll_f), nll_f, np.nan)))])

    def _differentiate(self, t: np.ndarray, x: np.ndarray) -> Triple:
        scale, step, blocks, y = self._setup(t, x)
        lam = self._lam_unit(blocks, y, step)
        F, Q1 = blocks
        _, _, (xs_f, Ps_f) = _filter(y, F, Q1, np.array([lam]), keep=True)
        s = _rts(F, lam * Q1, xs_f[:, 0], Ps_f[:, 0]) * scale
        return s[:, 0] + np.mean(x), s[:, 1] / step, s[:, 2] / step**2


def noise_variance(t: np.ndarray, x: np.ndarray) -> float:
    """Maximum-likelihood variance of white measurement noise on ``x`` (jerk-model smoother).

    The measurement variance ``r̂`` that the default :class:`KalmanSmoother` estimates along with
    its ``λ``; used by other differentiators that need the noise level (total variation).
    """
    diff = KalmanSmoother()
    scale, step, blocks, y = diff._setup(t, x)
    lam = diff._lam_unit(blocks, y, step)
    _, r_hat, _ = _filter(y, blocks[0], blocks[1], np.array([lam]))
    return float(r_hat[0]) * scale**2
