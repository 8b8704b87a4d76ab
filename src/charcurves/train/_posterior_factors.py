"""Square-root factors of the covariance of a (linearised) least-squares problem: the iid formula
and the Newey-West (HAC) sandwich of :mod:`._posterior_linear`, for a Jacobian ``J`` and residual ``r``.

Used for the constants of post-SR closed forms: the linearised problem ``r(theta) ~ r + J dtheta``
at the closed forms' constants (:func:`charcurves.fitting.closed_form_posterior`).
"""

from __future__ import annotations

import numpy as np

from ._posterior_linear import ILL_CONDITIONED, bartlett_sum, hac_bandwidth

__all__ = ["covariance_factors"]


def covariance_factors(J: np.ndarray, r: np.ndarray, rows: np.ndarray, n: int) -> dict:
    """``{"hac", "gauss"}`` factors ``R`` (``cov = R R^T``, parameters x rank), ``noise_variance``, ``bandwidth``,
    ``condition_number``, ``unidentified`` (directions with infinite variance, rows) and ``weak`` (the
    weakest direction of an ill-conditioned problem, or None).

    ``J`` and ``r`` are on the selected rows (``rows``, a mask over ``E * n`` equation-major rows);
    equations at the same instant share a score row, as in :class:`LinearPosterior`.

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.train import covariance_factors
    >>> rng = np.random.default_rng(0)
    >>> J = np.column_stack([np.ones(500), np.linspace(-1, 1, 500)])
    >>> f = covariance_factors(J, rng.normal(scale=0.1, size=500), np.ones(500, bool), 500)
    >>> sd = np.sqrt(np.sum(f["gauss"] ** 2, axis=1))
    >>> bool(np.allclose(sd, np.sqrt(np.diag(f["noise_variance"] * np.linalg.inv(J.T @ J)))))
    True
    """
    N, p = J.shape
    norms = np.linalg.norm(J, axis=0)
    norms[norms == 0] = 1.0
    U, s, Vt = np.linalg.svd(J / norms, full_matrices=False)
    cond = float(s[0] / s[-1]) if s.size and s[-1] > 0 else float("inf")
    finite = s > (s[0] if s.size else 0.0) * 1e-13
    Vf = Vt[finite].T / s[finite]
    k = int(finite.sum())
    noise_variance = float(r @ r / max(N - k, 1))
    full = np.zeros((rows.size, k))
    full[rows] = U[:, finite] * r[:, None]
    score = full.reshape(-1, n, k).sum(axis=0)
    res = np.zeros(rows.size)
    res[rows] = r
    L = hac_bandwidth(res.reshape(-1, n).sum(axis=0))
    S = bartlett_sum(score, L)
    w, Q = np.linalg.eigh((S + S.T) / 2)
    C = Q * np.sqrt(np.clip(w, 0.0, None) * (N / max(N - k, 1)))
    return {"gauss": np.sqrt(noise_variance) * Vf / norms[:, None], "hac": (Vf @ C) / norms[:, None],
            "noise_variance": noise_variance, "bandwidth": int(L), "condition_number": cond,
            "unidentified": Vt[~finite] / norms if (~finite).any() else np.zeros((0, p)),
            "weak": Vt[-1] if cond > ILL_CONDITIONED else None}
