"""The posterior of a fit as it is saved with the model (model.json ``posterior`` and arrays
``posterior.*``), so that a loaded model still has its bands, its ± and its predictive band.

Any posterior that gives each curve's values as a linear map of one standard normal vector ``u``
(``curve_factor(name, z) -> (value, G, infinite)`` and ``scalar_factor() -> (names, mean, G,
infinite)``; the least-squares posterior of :mod:`charcurves.train` does) is stored as that map on
a grid of :data:`GRID` points over each curve's training range: ``value(z) + G(z) u``. Between grid
points the map is interpolated by a cubic spline; outside the range the variance is infinite (the record
says nothing there). Curves and scalars share ``u``, so a stored posterior keeps their correlations
and can be sampled (:meth:`StoredPosterior.sample`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .._errors import ConfigError, ModelFileError
from ._posterior import posterior_label, sup_t_factor

__all__ = ["StoredPosterior", "posterior_to_spec", "posterior_from_spec", "GRID"]

#: Points per curve of a stored posterior (over the curve's training range).
GRID = 201
_PREFIX = "posterior."


class StoredPosterior:
    """A Gaussian posterior as a linear map of a standard normal vector, on a grid per curve.

    Examples
    --------
    >>> import numpy as np
    >>> import charcurves as cc
    >>> from charcurves.model import StoredPosterior
    >>> from charcurves.systems import get_system
    >>> model = cc.fit(cc.corrupt(get_system("duffing").simulate(), 20, seed=0), method="poly-cc")
    >>> stored = StoredPosterior.from_posterior(model.posterior, model)
    >>> z = np.array([0.5, 1.0])
    >>> bool(np.allclose(stored.curve_sd("f2", z)[1], model.posterior.curve_sd("f2", z)[1], rtol=1e-3))
    True
    """

    def __init__(self, *, meta: dict, curves: dict, scalars: tuple):
        self.kind = str(meta.get("kind", "hac"))
        self.method = str(meta.get("method", "laplace"))
        self.bandwidth = int(meta.get("bandwidth", 0))
        nv = meta.get("noise_variance")
        self.noise_variance = float("nan") if nv is None else float(nv)
        cn = meta.get("condition_number")
        self.condition_number = float("inf") if cn is None else float(cn)
        self._warnings = [str(w) for w in meta.get("warnings", [])]
        self.curves = curves  # name -> (z, value, G, infinite)
        self.scalars = scalars  # (names, mean, G, infinite)
        self._splines: dict = {}
        self.rank = int(next(iter(curves.values()))[2].shape[1]) if curves else int(scalars[2].shape[1])

    @classmethod
    def from_posterior(cls, post, model, n_grid: int = GRID) -> StoredPosterior | None:
        """The stored form of ``post`` on ``model``'s curve ranges; None when ``post`` gives no linear map."""
        if not (hasattr(post, "curve_factor") and hasattr(post, "scalar_factor")):
            return None
        from threadpoolctl import threadpool_limits

        with threadpool_limits(limits=1, user_api="blas"):  # the same bytes whatever OMP_NUM_THREADS says
            return cls._from_posterior(post, model, n_grid)

    @classmethod
    def _from_posterior(cls, post, model, n_grid: int) -> StoredPosterior:
        curves = {}
        for name, curve in model.curves.items():
            z = np.linspace(curve.domain[0], curve.domain[1], int(n_grid))
            value, G, inf = post.curve_factor(name, z)
            curves[name] = (z, np.asarray(value, dtype=float), np.asarray(G, dtype=float), np.asarray(inf, dtype=bool))
        names, mean, G, inf = post.scalar_factor()
        meta = {"kind": post.kind, "method": posterior_label(post),
                "bandwidth": getattr(post, "bandwidth", 0), "noise_variance": post.noise_variance,
                "condition_number": post.condition_number, "warnings": post.warnings()}
        return cls(meta=meta, curves=curves, scalars=(list(names), np.asarray(mean, dtype=float),
                                                      np.asarray(G, dtype=float), np.asarray(inf, dtype=bool)))

    # ------------------------------------------------------------------ the interface of model._posterior
    def with_kind(self, kind: str) -> StoredPosterior:
        if kind != self.kind:
            raise ConfigError(f"this saved posterior holds the {self.kind!r} covariance only; refit the model for "
                              f"{kind!r}")
        return self

    def warnings(self) -> list[str]:
        return list(self._warnings)

    def curve_factor(self, name: str, z) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(value, G, infinite)`` at ``z``, a cubic spline between the grid's points."""
        if name not in self.curves:
            raise ConfigError(f"unknown curve {name!r}; the posterior has {', '.join(self.curves)}")
        grid, value, G, inf = self.curves[name]
        z = np.asarray(z, dtype=float).reshape(-1)
        tol = 1e-12 * max(abs(grid[-1] - grid[0]), 1e-300)
        outside = (z < grid[0] - tol) | (z > grid[-1] + tol) | ~np.isfinite(z)
        zc = np.clip(np.nan_to_num(z), grid[0], grid[-1])
        i = np.clip(np.searchsorted(grid, zc, side="right") - 1, 0, grid.size - 2)
        w = (zc - grid[i]) / np.where(grid[i + 1] > grid[i], grid[i + 1] - grid[i], 1.0)
        if name not in self._splines:  # cubic between the grid's points (value and map together)
            from scipy.interpolate import CubicSpline

            self._splines[name] = CubicSpline(grid, np.column_stack([value, G]), axis=0)
        vg = self._splines[name](zc)
        infinite = outside | inf[i] | (inf[i + 1] & (w > 0))
        return vg[:, 0], vg[:, 1:], infinite

    def simultaneous_factor(self, grids: dict, level: float = 0.95, draws: int = 4000) -> float:
        """The sup-t multiplier over ``grids`` (curve name -> points), as the fit's posterior gives it
        (:func:`._posterior.sup_t_factor` on the stored map); ``inf`` past the stored range."""
        parts = [self.curve_factor(k, v) for k, v in grids.items()]
        if not parts:
            return 1.0
        G = np.concatenate([g for _, g, _ in parts])
        var = np.where(np.concatenate([inf for _, _, inf in parts]), np.inf, np.sum(G**2, axis=1))
        return sup_t_factor(G, var, level, draws)

    def curve_sd(self, name: str, z) -> tuple[np.ndarray, np.ndarray]:
        z = np.asarray(z, dtype=float)
        v, g, infinite = self.curve_factor(name, z)
        sd = np.where(infinite, np.inf, np.sqrt(np.sum(g**2, axis=1)))
        return v.reshape(z.shape), sd.reshape(z.shape)

    def scalar_factor(self) -> tuple[list, np.ndarray, np.ndarray, np.ndarray]:
        names, mean, G, inf = self.scalars
        return list(names), mean.copy(), G.copy(), inf.copy()

    def scalar_stats(self) -> dict[str, Any]:
        names, mean, G, inf = self.scalars
        if not names:
            return {"names": [], "mean": {}, "sd": {}, "correlation": []}
        cov = G @ G.T
        sd = np.where(inf, np.inf, np.sqrt(np.diag(cov)))
        with np.errstate(all="ignore"):
            corr = cov / np.outer(np.sqrt(np.diag(cov)), np.sqrt(np.diag(cov)))
        corr = np.where(np.isfinite(corr), corr, np.nan)
        return {"names": list(names), "mean": dict(zip(names, mean.tolist())), "sd": dict(zip(names, sd.tolist())),
                "correlation": corr.tolist()}

    def check_against(self, model, *, rtol: float = 1e-7) -> bool:
        """Whether ``model``'s curves are still the ones this posterior describes (on 5 grid points each)."""
        if set(model.curves) != set(self.curves):
            return False
        for name, curve in model.curves.items():
            grid, value, _, _ = self.curves[name]
            idx = np.linspace(0, grid.size - 1, 5).round().astype(int)
            ref = np.asarray(curve(grid[idx]), dtype=float)
            if not np.allclose(value[idx], ref, rtol=rtol, atol=rtol * (np.max(np.abs(ref)) + 1e-300)):
                return False
        return True

    def sample(self, n: int, seed: int = 0) -> np.ndarray:
        """``n`` draws of the standard normal vector ``u`` (rows), from ``seed``; curve ``name``'s draw ``k``
        on the grid is ``value + G @ u[k]`` (:meth:`curve_factor`)."""
        return np.random.default_rng(seed).standard_normal((int(n), self.rank))


def posterior_to_spec(model) -> tuple[dict | None, dict[str, np.ndarray]]:
    """model.json ``posterior`` and its arrays for ``model``'s posterior; ``(None, {})`` when it has none
    (or one that gives no linear map, or one that no longer describes the curves)."""
    from ._posterior import model_posterior

    post = model_posterior(model)
    stored = None if post is None else (post if isinstance(post, StoredPosterior)
                                        else StoredPosterior.from_posterior(post, model))
    if stored is None:
        return None, {}
    names, mean, G, inf = stored.scalars
    cn = stored.condition_number
    spec = {"form": "gaussian-grid", "kind": stored.kind, "method": stored.method, "bandwidth": stored.bandwidth,
            "noise_variance": stored.noise_variance if np.isfinite(stored.noise_variance) else None,
            "condition_number": cn if np.isfinite(cn) else None,
            "rank": stored.rank, "warnings": stored.warnings(), "curves": list(stored.curves), "scalars": list(names),
            "scalar_mean": mean.tolist()}
    arrays = {}
    for name, (z, value, Gc, infc) in stored.curves.items():
        arrays.update({f"{_PREFIX}{name}.z": z, f"{_PREFIX}{name}.value": value, f"{_PREFIX}{name}.factor": Gc,
                       f"{_PREFIX}{name}.infinite": infc.astype(float)})
    if names:
        arrays.update({f"{_PREFIX}scalars.factor": G, f"{_PREFIX}scalars.infinite": inf.astype(float)})
    return spec, arrays


def posterior_from_spec(spec, arrays: dict, jpath: str = "model.json") -> StoredPosterior:
    """The :class:`StoredPosterior` of a model file; ModelFileError naming the problem when it is damaged."""
    def bad(what: str):
        return ModelFileError(f"{jpath!r}: the saved posterior is damaged ({what}); the model file is corrupted, "
                              "re-save or re-fit the model")

    if not isinstance(spec, dict) or spec.get("form") != "gaussian-grid":
        raise bad("model.posterior is not a gaussian-grid posterior")
    try:
        rank = int(spec["rank"])
        curves = {}
        for name in spec["curves"]:
            z, value, G, inf = (np.asarray(arrays[f"{_PREFIX}{name}.{k}"], dtype=float)
                                for k in ("z", "value", "factor", "infinite"))
            if (z.ndim != 1 or z.size < 2 or value.shape != z.shape or inf.shape != z.shape
                    or G.shape != (z.size, rank) or np.any(np.diff(z) <= 0)):
                raise bad(f"the arrays of curve {name!r} do not fit together")
            curves[str(name)] = (z, value, G, inf > 0.5)
        names = [str(s) for s in spec["scalars"]]
        mean = np.asarray(spec["scalar_mean"], dtype=float)
        if names:
            G = np.asarray(arrays[f"{_PREFIX}scalars.factor"], dtype=float)
            inf = np.asarray(arrays[f"{_PREFIX}scalars.infinite"], dtype=float) > 0.5
        else:
            G, inf = np.zeros((0, rank)), np.zeros(0, dtype=bool)
        if mean.shape != (len(names),) or G.shape != (len(names), rank) or inf.shape != (len(names),):
            raise bad("the scalars' arrays do not fit together")
        if not curves and not names:
            raise bad("it describes no curve and no scalar")
        meta = {k: spec[k] for k in ("kind", "method", "bandwidth", "noise_variance", "condition_number", "warnings")}
    except KeyError as exc:
        raise bad(f"{exc.args[0]!r} is missing") from None
    except (TypeError, ValueError) as exc:
        raise bad(f"{type(exc).__name__}") from None
    return StoredPosterior(meta=meta, curves=curves, scalars=(names, mean, G, inf))
