"""pysindy's ConstrainedSR3 with the constant matrices of its iteration computed once.

``ConstrainedSR3._reduce`` relaxes the same least-squares problem up to ``max_iter`` times (10 000
for SINDy-CC's defaults, which it usually runs to the end). Every iteration of pysindy 2.1's
``_update_full_coef_constraints`` inverts H, builds ``kron(inv(H), I)`` and inverts the
constraint's Schur complement again, although H and the constraint do not change between
iterations (without trimming): 65 % of a SINDy-CC fit's time. The subclass keeps those products
for as long as H and the constraint are the ones they were made from, and evaluates every
product in the same order as pysindy does, so the coefficients are bit-for-bit pysindy's (tested
against the parent class).
"""

from __future__ import annotations

import functools

import numpy as np

__all__ = ["constrained_sr3"]


@functools.lru_cache(maxsize=4)
def _subclass(parent: type) -> type:
    class CachedConstrainedSR3(parent):  # type: ignore[misc, valid-type]
        #: (n_targets, H, constraint_lhs) the products were made from, and (inv(H), lhs^T inv2, lhs inv1_mod)
        _cache: tuple | None = None

        def _update_full_coef_constraints(self, H, x_transpose_y, coef_sparse):
            n_targets, lhs = coef_sparse.shape[1], self.constraint_lhs
            c = self._cache
            if c is None or c[0] != n_targets or not np.array_equal(c[1], H) or not np.array_equal(c[2], lhs):
                inv1 = np.linalg.inv(H)
                inv1_mod = np.kron(inv1, np.eye(n_targets))
                inv2 = np.linalg.inv(lhs.dot(inv1_mod).dot(lhs.T))
                # pysindy's expression associates left to right: (lhs^T inv2) (...) and (lhs inv1_mod) g
                c = self._cache = (n_targets, np.array(H), np.array(lhs), inv1, lhs.T.dot(inv2), lhs.dot(inv1_mod))
            inv1, lhs_t_inv2, lhs_inv1_mod = c[3:]
            g = x_transpose_y + coef_sparse / self.relax_coeff_nu
            flat = g.flatten()
            rhs = flat + lhs_t_inv2.dot(self.constraint_rhs - lhs_inv1_mod.dot(flat))
            return inv1.dot(rhs.reshape(g.shape))

    CachedConstrainedSR3.__name__ = CachedConstrainedSR3.__qualname__ = "CachedConstrainedSR3"
    return CachedConstrainedSR3


def constrained_sr3(ps, **kwargs):
    """``ps.ConstrainedSR3(**kwargs)`` whose iterations reuse their constant matrices (same coefficients).

    Examples
    --------
    >>> import numpy as np
    >>> import pysindy as ps
    >>> from charcurves.train._sr3 import constrained_sr3
    >>> rng = np.random.default_rng(0)
    >>> X = rng.normal(size=(200, 3)); y = X @ np.array([0.5, 0.0, 1.0]) + 0.01 * rng.normal(size=200)
    >>> kw = dict(reg_weight_lam=1e-3, regularizer="l0", relax_coeff_nu=1.0, max_iter=200,
    ...           constraint_lhs=np.array([[0.0, 0.0, 1.0]]), constraint_rhs=np.array([1.0]),
    ...           constraint_order="feature", equality_constraints=True)
    >>> a = constrained_sr3(ps, **kw).fit(X, y.reshape(-1, 1)).coef_
    >>> b = ps.ConstrainedSR3(**kw).fit(X, y.reshape(-1, 1)).coef_
    >>> bool(np.array_equal(a, b)), (np.round(a, 2) + 0.0).tolist()  # + 0.0: no signed zeros
    (True, [[0.5, 0.0, 1.0]])
    """
    return _subclass(ps.ConstrainedSR3)(**kwargs)
