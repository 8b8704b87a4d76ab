"""A posterior widened by the lack of fit of the curves whose representation cannot take the record's
law (a degree-limited polynomial for a soft clip, an odd library for a Stribeck curve).

The Laplace posterior of a fit is the posterior of the best curve its representation can take: where
that curve is not the truth, its band is centred off the truth by the representation's bias and holds
it only where the bias is smaller than the noise's spread. The bias of curve ``k`` at ``z`` is
estimated from the residual, linear between the medians of quantile bins of ``k``'s argument
(:func:`charcurves.fitting.lack_of_fit_bias`), ``b_k(z)``; the corrected posterior adds it as one more
standard normal direction per curve,

    ``f_k(z) = value_k(z) + G_k(z) u + b_k(z) u_k'``,

so that the band's variance is ``sd_k(z)^2 + b_k(z)^2`` (a mean squared error band) and the added
directions are independent of the scalars and of each other. Everything else (scalars, warnings, the
check against the model) is the wrapped posterior's; saving the model stores the widened map.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ._posterior import posterior_label, sup_t_factor

__all__ = ["LackOfFitPosterior"]


class LackOfFitPosterior:
    """``inner`` (any posterior with ``curve_factor`` and ``scalar_factor``) plus, for each curve of
    ``bias``, a lack-of-fit direction ``b(z)``: ``bias[name] = (centres, values)``, linear between the
    centres, constant past the outer ones.

    Examples
    --------
    >>> import numpy as np
    >>> import charcurves as cc
    >>> from charcurves.model import LackOfFitPosterior
    >>> from charcurves.systems import get_system
    >>> model = cc.fit(cc.corrupt(get_system("duffing").simulate(), 20, seed=0), method="poly-cc")
    >>> plain = model.posterior.inner if isinstance(model.posterior, LackOfFitPosterior) else model.posterior
    >>> wide = LackOfFitPosterior(plain, {"f2": (np.array([-1.0, 1.0]), np.array([0.3, 0.4]))})
    >>> z = np.array([-2.0, 0.0, 1.0])
    >>> sd0, sd1 = plain.curve_sd("f2", z)[1], wide.curve_sd("f2", z)[1]
    >>> np.round(np.sqrt(sd1**2 - sd0**2), 3).tolist()   # the bias's size added in quadrature
    [0.3, 0.35, 0.4]
    >>> bool(np.allclose(wide.curve_sd("f1", z)[1], plain.curve_sd("f1", z)[1]))   # f1 is unchanged
    True
    """

    def __init__(self, inner, bias: dict, *, note: str = "lack of fit (binned residual)"):
        self.inner = inner
        self.bias = {k: (np.asarray(c, dtype=float), np.abs(np.asarray(v, dtype=float))) for k, (c, v) in bias.items()}
        self._order = list(self.bias)
        self.note = note

    def __getattr__(self, name: str) -> Any:  # kind, bandwidth, noise_variance, condition_number, ...
        if name == "inner":
            raise AttributeError(name)
        return getattr(self.inner, name)

    @property
    def label(self) -> str:
        return f"{posterior_label(self.inner)} + {self.note}"

    @property
    def method(self) -> str:
        return self.label

    def with_kind(self, kind: str) -> LackOfFitPosterior:
        return LackOfFitPosterior(self.inner.with_kind(kind), self.bias, note=self.note)

    def lack_of_fit(self, name: str, z) -> np.ndarray:
        """``|b(z)|``, the lack-of-fit sd of curve ``name`` at ``z`` (zeros for a curve without one)."""
        z = np.asarray(z, dtype=float).reshape(-1)
        if name not in self.bias:
            return np.zeros(z.size)
        c, v = self.bias[name]
        return np.interp(np.nan_to_num(z), c, v)

    def curve_factor(self, name: str, z) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        value, G, inf = self.inner.curve_factor(name, z)
        G = np.asarray(G, dtype=float)
        extra = np.zeros((G.shape[0], len(self._order)))
        if name in self.bias:
            extra[:, self._order.index(name)] = self.lack_of_fit(name, z)
        return value, np.hstack([G, extra]), inf

    def curve_sd(self, name: str, z) -> tuple[np.ndarray, np.ndarray]:
        value, sd = self.inner.curve_sd(name, z)
        return value, np.sqrt(np.asarray(sd, dtype=float) ** 2 + self.lack_of_fit(name, z) ** 2)

    def scalar_factor(self) -> tuple[list, np.ndarray, np.ndarray, np.ndarray]:
        names, mean, G, inf = self.inner.scalar_factor()
        G = np.asarray(G, dtype=float)
        if G.ndim != 2:  # no scalar at all: an empty factor
            G = G.reshape(len(names), -1) if len(names) else G.reshape(0, 0)
        return names, mean, np.hstack([G, np.zeros((G.shape[0], len(self._order)))]), inf

    def simultaneous_factor(self, grids: dict, level: float = 0.95, draws: int = 4000) -> float:
        """The sup-t multiplier of the widened posterior over ``grids`` (curve name -> points)."""
        parts = [self.curve_factor(k, v) for k, v in grids.items()]
        if not parts:
            return 1.0
        G = np.concatenate([g for _, g, _ in parts])
        var = np.where(np.concatenate([inf for _, _, inf in parts]), np.inf, np.sum(G**2, axis=1))
        return sup_t_factor(G, var, level, draws)
