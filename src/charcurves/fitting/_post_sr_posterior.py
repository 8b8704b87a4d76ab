"""The posterior of post-SR closed forms' constants: the equation-error residual linearised in the
constants at their values, ``r(theta) ~ r + J dtheta``, with the covariance of that least-squares
problem (HAC sandwich by default, as :class:`charcurves.train.LinearPosterior`).

The parameters are the numbers of each closed form (sympy ``Float``), the gain when it is learned,
the learned scalars, and the free constant ``b`` where no curve carries a constant. A curve the
gauge anchors (``f(0) = 0`` and a constant term) keeps its gauge: its constant term is not a
parameter and its variation is ``e(z) - e(0)``. The closed forms' constants come from symbolic
regression on the curve, not from the record, so the posterior is centred on them rather than on
the record's own optimum; the linearisation holds while the record's optimum is near them.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .._lambdify import numpy_function

__all__ = ["closed_form_posterior", "ClosedFormPosterior"]


def _additive_float(expr):
    import sympy as sp

    const, _ = expr.as_coeff_Add()
    return const if isinstance(const, sp.Float) and const != 0 else None


class ClosedFormPosterior:
    """The linearised posterior of the closed forms' constants (:func:`closed_form_posterior`); the
    interface of :mod:`charcurves.model._posterior` (``curve_factor``, ``scalar_factor``, ...).

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.curves import SymbolicFittedCurve
    >>> from charcurves.fitting import FittedModel, closed_form_posterior
    >>> from charcurves.systems import get_system
    >>> from charcurves.templates import get_template
    >>> record = cc.corrupt(get_system("duffing").simulate(), 20, seed=0)
    >>> curves = {"f1": SymbolicFittedCurve("f1", "x'", (-1.5, 1.5), "0.3*z"),
    ...           "f2": SymbolicFittedCurve("f2", "x", (-1.5, 1.5), "z**3 - z")}
    >>> model = FittedModel(get_template("separable"), "demo", curves, 1.0, 0.0, 0.0)
    >>> post = closed_form_posterior(model, record)
    >>> value, sd = post.curve_sd("f1", [1.0])
    >>> f"{value[0]:.2f} +- {sd[0]:.4f}"
    '0.30 +- 0.0023'
    """

    method = "laplace (post-SR constants, linearised)"

    def __init__(self, model, params: list, jac: dict, factors: dict, kind: str = "hac"):
        self.params, self._jac, self._f = params, jac, factors
        self.kind = kind
        self.bandwidth, self.noise_variance = factors["bandwidth"], factors["noise_variance"]
        self.condition_number = factors["condition_number"]
        grids = {nm: np.linspace(c.domain[0], c.domain[1], 5) for nm, c in model.curves.items()}
        self._ref = {nm: (z, np.asarray(model.curves[nm](z), dtype=float)) for nm, z in grids.items()}
        self._curves = dict(model.curves)
        self._scalars = {k: v for k, v in (("gain", float(model.gain)), ("offset", float(model.offset)),
                                           *model.scalars.items()) if k in params}

    def with_kind(self, kind: str) -> ClosedFormPosterior:
        import copy

        new = copy.copy(self)
        new.kind = kind
        return new

    def _variance_mask(self, J: np.ndarray) -> np.ndarray:
        un = self._f["unidentified"]
        if not len(un):
            return np.zeros(J.shape[0], dtype=bool)
        load = np.abs(J @ (un / np.linalg.norm(un, axis=1, keepdims=True)).T).max(axis=1)
        return load > 1e-8 * (np.abs(J).max(axis=1) + 1e-300)

    def curve_factor(self, name: str, z):
        z = np.asarray(z, dtype=float).reshape(-1)
        J = np.zeros((z.size, len(self.params)))
        for j, fn in self._jac.get(name, []):
            with np.errstate(all="ignore"):
                J[:, j] = np.broadcast_to(np.asarray(fn(z), dtype=float), z.shape)
        value = np.asarray(self._curves[name](z), dtype=float)
        return value, np.nan_to_num(J @ self._f[self.kind]), self._variance_mask(J)

    def curve_sd(self, name: str, z):
        z = np.asarray(z, dtype=float)
        v, G, inf = self.curve_factor(name, z)
        return v.reshape(z.shape), np.where(inf, np.inf, np.sqrt(np.sum(G**2, axis=1))).reshape(z.shape)

    def scalar_factor(self):
        names = list(self._scalars)
        J = np.zeros((len(names), len(self.params)))
        for i, k in enumerate(names):
            J[i, self.params.index(k)] = 1.0
        return names, np.array([self._scalars[k] for k in names]), J @ self._f[self.kind], self._variance_mask(J)

    def scalar_stats(self) -> dict[str, Any]:
        names, mean, G, inf = self.scalar_factor()
        if not names:
            return {"names": [], "mean": {}, "sd": {}, "correlation": []}
        cov = G @ G.T
        sd = np.where(inf, np.inf, np.sqrt(np.diag(cov)))
        with np.errstate(all="ignore"):
            corr = cov / np.outer(np.sqrt(np.diag(cov)), np.sqrt(np.diag(cov)))
        return {"names": names, "mean": dict(zip(names, mean.tolist())), "sd": dict(zip(names, sd.tolist())),
                "correlation": np.where(np.isfinite(corr), corr, np.nan).tolist()}

    def check_against(self, model, *, rtol: float = 1e-7) -> bool:
        if set(model.curves) != set(self._ref):
            return False
        for nm, (z, ref) in self._ref.items():
            now = np.asarray(model.curves[nm](z), dtype=float)
            if not np.allclose(now, ref, rtol=rtol, atol=rtol * (np.max(np.abs(ref)) + 1e-300)):
                return False
        return True

    def warnings(self) -> list[str]:
        out = []
        if len(self._f["unidentified"]) or self._f["weak"] is not None:
            out.append(f"uncertainty: the record does not determine every constant of the closed forms (condition "
                       f"number {self.condition_number:.3g}); what depends on them has wide or infinite intervals")
        return out


def closed_form_posterior(model, traj, *, mask=None) -> ClosedFormPosterior | None:
    """The posterior of ``model``'s closed-form constants on the record ``traj`` (with derivatives) by
    equation error; None when a curve has no closed form, ``traj`` has no derivatives or a closed form's
    derivative cannot be evaluated. Post-SR (:func:`distill_model` given the record) attaches it.

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.curves import SymbolicFittedCurve
    >>> from charcurves.fitting import FittedModel, closed_form_posterior
    >>> from charcurves.systems import get_system
    >>> from charcurves.templates import get_template
    >>> record = cc.corrupt(get_system("duffing").simulate(), 20, seed=0)
    >>> curves = {"f1": SymbolicFittedCurve("f1", "x'", (-1.5, 1.5), "0.3*z"),
    ...           "f2": SymbolicFittedCurve("f2", "x", (-1.5, 1.5), "1.0*z**3 - 1.0*z")}
    >>> model = FittedModel(get_template("separable"), "demo", curves, 1.0, 0.0, 0.0)
    >>> model.posterior = closed_form_posterior(model, record)
    >>> print(model.to_sympy(curves=True, uncertainty=True)["f2"])
    (1 ± 0.0026)*z**3 - (1 ± 0.0034)*z
    """
    if not getattr(traj, "has_derivatives", False) or any(c.expression() is None for c in model.curves.values()):
        return None
    try:
        return _build(model, traj, mask)
    except (TypeError, ValueError, NameError, ZeroDivisionError, OverflowError, AttributeError, NotImplementedError):
        return None  # a closed form whose derivative numpy cannot evaluate (DiracDelta of a Heaviside): no posterior


def _build(model, traj, mask):
    import sympy as sp

    from ..templates import sticking_mask
    from ..train import covariance_factors

    D = model.template.design(traj)
    n, E = D["n"], D["E"]
    keep = ~sticking_mask(traj) if mask is None else np.asarray(mask, bool)
    rows = np.tile(keep, E)
    z = sp.Symbol("z")
    params: list = []
    cols: list = []
    jac: dict = {}
    carries_constant = False
    zr = sp.Symbol("z", real=True)  # the derivative of Abs(z) is sign(z) on a real z (numpy can print it)
    for name, curve in model.curves.items():
        expr = sp.sympify(curve.expression()).xreplace({z: zr})
        add = _additive_float(expr)
        anchored = add is not None and abs(float(curve(np.array([0.0]))[0])) <= 1e-9 * (
            float(np.max(np.abs(curve(np.linspace(curve.domain[0], curve.domain[1], 21))))) + 1e-300)
        body = expr - add if anchored else expr
        carries_constant = carries_constant or (add is not None and not anchored)
        floats = sorted(body.atoms(sp.Float), key=lambda f: (abs(float(f)), float(f)))
        thetas = sp.symbols(f"theta0:{len(floats)}", real=True) if floats else ()
        param = body.xreplace(dict(zip(floats, thetas)))
        values = [float(f) for f in floats]
        jac[name] = []
        for th in thetas:
            d = sp.diff(param, th)
            d = d - d.subs(zr, 0) if anchored else d
            fn = numpy_function([zr, *thetas], d)

            def col(u, fn=fn, values=values):
                return fn(u, *values)

            j = len(params)
            params.append((name, th.name))
            jac[name].append((j, col))
            with np.errstate(all="ignore"):
                g = np.broadcast_to(np.asarray(col(D["args"][name]), dtype=float), D["args"][name].shape)
            cols.append(D["mult"][name] * np.tile(g, E))
    for s, sig in D["scalars"].items():
        params.append(s)
        cols.append(sig)
    if model.template.free_gain:
        params.append("gain")
        cols.append(-D["F"])
    if not carries_constant:
        params.append("offset")
        offs = np.zeros(n * E)
        offs[:n] = 1.0
        cols.append(offs)
    if not cols:
        return None
    J = np.column_stack(cols)
    if not np.all(np.isfinite(J[rows])):
        return None
    r = np.asarray(model.force_residual(traj), dtype=float)
    r = (r.T if r.ndim == 2 else r).reshape(-1)
    factors = covariance_factors(J[rows], r[rows], rows, n)
    return ClosedFormPosterior(model, params, jac, factors)
