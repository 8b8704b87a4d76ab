"""Total-variation regularised differentiation (TV of the jerk), solved with cvxpy."""

from __future__ import annotations

import math
from typing import Any, final

import numpy as np

from .._errors import ConfigError, DataError
from ._diff_base import Differentiator, Triple, _as_record, _integer, _positive_or_none
from ._trajectory import Trajectory

_TV_MIN_SAMPLES = 16
_INSTALL = 'pip install "charcurves[sindy]" (or pip install cvxpy)'
# bisection on log10(alpha) of the standardised problem (unit steps, unit-variance record)
_LOG_ALPHA_RANGE = (-6.0, 6.0)
_BISECTIONS = 14


def _import_cvxpy():
    try:
        import cvxpy
    except ImportError:
        raise ConfigError(
            f"total-variation differentiation needs cvxpy; install it with {_INSTALL}"
        ) from None
    return cvxpy


@final
class TotalVariation(Differentiator):
    """Total-variation regularised differentiation: a piecewise-polynomial fit with sparse kinks.

    Minimises ``||y - x̂||² + α TV(x̂^(order))`` over ``x̂``, where ``x̂^(order)`` is the discrete
    ``order``-th derivative (``order=3``, the default: the jerk, so that ``x̂''`` is continuous and
    piecewise linear; ``order=2``: the acceleration, ``x̂''`` piecewise constant). The unknowns are
    the ``order``-th differences and ``order`` integration constants (``x̂`` is their repeated
    cumulative sum), a convex problem handed to cvxpy (Clarabel, OSQP as fallback). ``x̂'`` and
    ``x̂''`` are then second-order central differences of ``x̂``. This is Chartrand's TV
    regularised differentiation (2011) raised to the derivative that the second-order template
    needs, in the form ``pynumdiff.tvrdiff`` uses.

    ``alpha=None`` (default) chooses ``α`` by the discrepancy principle: the residual
    ``||y - x̂||² / n`` must equal the noise variance, estimated by maximum likelihood with the
    default :class:`KalmanSmoother` (jerk model); bisection on ``log10 α`` in ``[-6, 6]`` (14
    solves; a record too clean for any ``α`` in that range gets the smallest). Measured on
    the paper's records the ``α`` that minimises the error of ``x''`` leaves a residual of 0.96-0.99
    times the noise variance, so the principle lands close to it.

    Parameters
    ----------
    alpha : float or None
        Regularisation weight for the standardised problem (record scaled to unit standard
        deviation, unit time steps); ``None`` chooses it as described above.
    order : {3, 2}
        The derivative whose total variation is penalised.

    Notes
    -----
    Needs uniform sampling and cvxpy (``pip install "charcurves[sindy]"``). Slow: about 1-3 s per
    1000 samples for the automatic choice (14 conic solves), and the solver's cost grows faster
    than linearly with the record length. Use :meth:`resolve_alpha` to see the chosen ``α``.

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.data import TotalVariation
    >>> t = np.linspace(0, 10, 200)
    >>> x = np.sin(t) + 0.01 * np.random.default_rng(0).standard_normal(200)
    >>> x_hat, v, a = TotalVariation(alpha=0.1)(t, x)
    >>> print(f"{np.sqrt(np.mean((v - np.cos(t))[10:-10] ** 2)):.2f}")
    0.02
    """

    name = "tvr"
    requires_uniform = True

    def __init__(self, alpha: float | None = None, order: int = 3) -> None:
        self.alpha = _positive_or_none("alpha", "total-variation", alpha, allow_zero=False)
        order = _integer("order", "total-variation", order)
        if order not in (2, 3):
            raise ConfigError(
                f"total-variation order must be 2 (TV of x'') or 3 (TV of x''', the default), "
                f"got {order}; a lower order gives no usable second derivative"
            )
        self.order = order

    def _check(self, traj: Trajectory) -> None:
        if traj.n_samples < _TV_MIN_SAMPLES:
            raise DataError(
                f"total-variation differentiation needs at least {_TV_MIN_SAMPLES} samples, the "
                f"record has {traj.n_samples}; give a longer record or use --derivatives fd"
            )
        super()._check(traj)

    def resolve_alpha(self, t: Any, x: Any) -> float:
        """The ``α`` (standardised problem) used for this record."""
        traj = _as_record(t, x)
        self._check(traj)
        return self._solve(traj.t, traj.x)[1]

    def _problem(self, n: int):
        cp = _import_cvxpy()
        jerk = cp.Variable(n)
        consts = cp.Variable(self.order)
        y = cp.Parameter(n)
        alpha = cp.Parameter(nonneg=True)
        fit = jerk
        for i in range(self.order):
            fit = cp.cumsum(fit) + consts[i]
        objective = cp.sum_squares(y - fit) + alpha * cp.norm1(cp.diff(jerk))
        return cp, cp.Problem(cp.Minimize(objective)), y, alpha, fit

    def _solve(self, t: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, float]:
        mean, scale = float(np.mean(x)), float(np.std(x)) or 1.0
        z = (x - mean) / scale
        cp, problem, y, alpha, fit = self._problem(x.shape[0])
        y.value = z

        def solve(log_alpha: float) -> np.ndarray | None:
            alpha.value = 10.0**log_alpha
            for solver in ("CLARABEL", "OSQP"):
                try:
                    problem.solve(solver=solver)
                except (cp.error.SolverError, ValueError):
                    continue
                if problem.status in ("optimal", "optimal_inaccurate") and fit.value is not None:
                    return np.asarray(fit.value, dtype=float)
            return None

        if self.alpha is not None:
            out = solve(math.log10(self.alpha))
            if out is None:
                raise DataError(
                    f"the total-variation problem with alpha={self.alpha} could not be solved; "
                    "try another alpha or --derivatives kalman"
                )
            return out * scale + mean, self.alpha

        from ._diff_kalman import noise_variance

        target = noise_variance(np.asarray(t, float), np.asarray(x, float)) / scale**2
        lo, hi = _LOG_ALPHA_RANGE
        best: tuple[np.ndarray, float] | None = None
        for _ in range(_BISECTIONS):
            mid = 0.5 * (lo + hi)
            out = solve(mid)
            if out is None or float(np.mean((out - z) ** 2)) > target:
                hi = mid  # too smooth (or failed, which happens at the smooth end)
            else:
                lo = mid
                best = (out, 10.0**mid)
        if best is None:  # even the least smoothing leaves more than the noise: a clean record
            out = solve(_LOG_ALPHA_RANGE[0])
            if out is not None:
                best = (out, 10.0 ** _LOG_ALPHA_RANGE[0])
        if best is None:
            raise DataError(
                "total-variation differentiation found no alpha that fits the record to its noise "
                "level; pass alpha=... explicitly or use --derivatives kalman"
            )
        return best[0] * scale + mean, best[1]

    def _differentiate(self, t: np.ndarray, x: np.ndarray) -> Triple:
        x_hat, _ = self._solve(t, x)
        v = np.gradient(x_hat, t, edge_order=2)
        return x_hat, v, np.gradient(v, t, edge_order=2)
