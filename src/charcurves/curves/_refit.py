"""Fitted curves opened up for further training (output error, refinement of closed forms).

:func:`trainable` turns any fitted curve into a :class:`CurveRefit`: a parametrisation (the
protocol of :class:`~charcurves.curves.LinearParametrisation`), its current parameters (one row
per ensemble member), the argument map and output scale, and a function that rebuilds the fitted
curve from new parameters. For closed forms (post-SR, SR-CC) every numeric coefficient is a
parameter: one per additive term (also an implicit 1 or an integer, as in ``z**3 - z``) and every
Float inside a term (``tanh(50.0*z)``); the additive constant (it trades with the equation's free
constant) and exponents stay fixed.

A curve on plain monomials (``z``, ``z**3``: a polynomial in powers of its argument, a polynomial
basis) is trained in the powers of ``z / h``, ``h`` the largest ``|z|`` of its domain, so that the
fit does not depend on the units of its argument: in raw powers a record in millimetres has
coefficients 1e30 apart, which the damping floor of Levenberg-Marquardt and the evidence's one
weight decay per curve treat as directions the data do not see. ``CurveRefit.unscale`` gives the
factors from the trained parameters back to the curve's own coefficients.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np

from .._errors import ConfigError

__all__ = ["CurveRefit", "trainable", "SymbolicParametrisation"]


@dataclasses.dataclass
class CurveRefit:
    """A fitted curve as ``shift + out_scale * param.evaluate(theta, (z - center) / half_width)``.

    Examples
    --------
    >>> from charcurves.curves import CurveRefit, SymbolicFittedCurve, trainable
    >>> refit = trainable(SymbolicFittedCurve("f1", "x'", (-1.0, 1.0), "0.3*z + 0.8*tanh(50.0*z)"))
    >>> isinstance(refit, CurveRefit), refit.param.n_params, sorted(refit.labels)
    (True, 3, ['f1:tanh(50.0*z)', 'f1:tanh(50.0*z)#0', 'f1:z'])
    """

    param: Any  # a parametrisation (NeuralCurve, LinearParametrisation, SymbolicParametrisation, ...)
    theta: np.ndarray  # (members, n_params)
    center: float
    half_width: float
    out_scale: float
    shift: float
    rebuild: Callable  # theta (members, n_params) -> FittedCurve (same name, argument, domain, shift)
    labels: list
    unscale: np.ndarray | None = None  # per parameter: the curve's own coefficient over the trained one


def trainable(curve) -> CurveRefit:
    """The :class:`CurveRefit` of a fitted curve (ConfigError for kinds that cannot be trained).

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.curves import BasisFittedCurve, trainable
    >>> refit = trainable(BasisFittedCurve("f2", "x", (-2.0, 2.0), ["z", "z**3"], [-1.0, 1.0]))
    >>> refit.half_width, refit.out_scale, refit.labels  # powers of z / 2, in units of max |f| = 6
    (2.0, 6.0, ['f2:z', 'f2:z**3'])
    >>> (refit.theta * 6).tolist(), refit.rebuild(refit.theta).coefficients.tolist()
    ([[-2.0, 8.0]], [-1.0, 1.0])
    """
    from ._base import LinearParametrisation
    from ._fitted import BasisFittedCurve, LinearFittedCurve, NeuralFittedCurve, SymbolicFittedCurve
    from ._specs import Basis

    if isinstance(curve, NeuralFittedCurve):
        def rebuild(theta):
            return NeuralFittedCurve(curve.name, curve.argument, curve.domain, curve.spec, np.asarray(theta),
                                     curve.in_scale, curve.out_scale, curve.shift, in_center=curve.in_center)

        labels = [f"{curve.name}:w{i}" for i in range(curve.spec.n_params)]
        return CurveRefit(curve.spec, np.array(curve.theta, dtype=float), curve.in_center, curve.in_scale,
                          curve.out_scale, curve.shift, rebuild, labels)
    if isinstance(curve, BasisFittedCurve):
        param = LinearParametrisation(Basis(list(curve.basis)))
        powers = curve.monomial_powers()
        h = max(abs(float(curve.domain[0])), abs(float(curve.domain[1])))
        h = h if powers is not None and np.isfinite(h) and h > 0 else 1.0
        # coefficient of z**k = (trained coefficient of (z/h)**k) / h**k (1 for a basis that is not monomials)
        unscale = np.array([h ** -float(k) for k in powers], dtype=float) if powers is not None else \
            np.ones(len(curve.basis))

        # and in units of the curve's largest value on its domain, so that the parameters are numbers of order one
        with np.errstate(all="ignore"):
            out = float(np.max(np.abs(curve.raw(np.linspace(curve.domain[0], curve.domain[1], 201)))))
        out = out if np.isfinite(out) and out > 0 else 1.0
        unscale = unscale * out

        def rebuild(theta):
            return BasisFittedCurve(curve.name, curve.argument, curve.domain, curve.basis,
                                    np.asarray(theta, dtype=float).mean(axis=0) * unscale, curve.shift)

        return CurveRefit(param, (curve.coefficients / unscale)[None, :], 0.0, h, out, curve.shift, rebuild,
                          [f"{curve.name}:{b}" for b in curve.basis], unscale)
    if isinstance(curve, LinearFittedCurve):
        param = LinearParametrisation(curve.representation)

        def rebuild(theta):
            return LinearFittedCurve(curve.name, curve.argument, curve.domain, curve.representation,
                                     np.asarray(theta, dtype=float).mean(axis=0), curve.center, curve.half_width,
                                     curve.constant, curve.shift)

        return CurveRefit(param, curve.coefficients[None, :].copy(), curve.center, curve.half_width, 1.0,
                          curve.shift + curve.constant, rebuild,
                          [f"{curve.name}:{n}" for n in curve.representation.feature_names()])
    if isinstance(curve, SymbolicFittedCurve):
        sym_param = SymbolicParametrisation(curve._expr)

        def rebuild(theta):
            from ._fitted import SymbolicFittedCurve as S

            return S(curve.name, curve.argument, curve.domain, sym_param.expression(np.asarray(theta).mean(axis=0)),
                     curve.shift, dict(curve.meta))

        return CurveRefit(sym_param, sym_param.theta0[None, :].copy(), 0.0, 1.0, 1.0, curve.shift, rebuild,
                          [f"{curve.name}:{lab}" for lab in sym_param.labels])
    raise ConfigError(f"curve {getattr(curve, 'name', '?')} of kind {getattr(curve, 'kind', type(curve).__name__)!r} "
                      "cannot be trained further")


class SymbolicParametrisation:
    """A closed form with its numeric coefficients as parameters (module docstring).

    Examples
    --------
    >>> import sympy as sp
    >>> from charcurves.curves import SymbolicParametrisation
    >>> param = SymbolicParametrisation(sp.sympify("z**3 - z + 0.5*tanh(20.0*z)"))
    >>> sorted(zip(param.labels, param.theta0.tolist()))
    [('tanh(20.0*z)', 0.5), ('tanh(20.0*z)#0', 20.0), ('z', -1.0), ('z**3', 1.0)]
    >>> param.expression(2 * param.theta0)
    2.0*z**3 - 2.0*z + 1.0*tanh(40.0*z)
    """

    symmetry = "none"
    exact_symmetry = "none"
    symmetry_mode = "exact"

    def __init__(self, expr) -> None:
        import sympy as sp

        self.z = sp.Symbol("z")
        const, rest = expr.as_coeff_Add()
        floats: list[float] = []
        labels: list[str] = []
        terms = []
        for term in sp.Add.make_args(rest) if rest != 0 else ():
            coeff, body = term.as_coeff_Mul()
            holder = sp.Symbol(f"__c{len(floats)}")
            floats.append(float(coeff))
            labels.append(str(body))
            inner = len(floats)
            body = _replace_floats(body, floats)
            labels += [f"{labels[-1]}#{k}" for k in range(len(floats) - inner)]
            terms.append(holder * body)
        self.template = sp.Add(*terms)
        self.const = const
        self.theta0 = np.asarray(floats, dtype=float)
        self.labels = labels
        self.n_params = len(floats)
        self.symbols = [sp.Symbol(f"__c{i}") for i in range(self.n_params)]
        full = self.template + const
        self.pinned_at_zero = bool(sp.simplify(full.subs({self.z: 0})) == 0) if self.n_params else bool(const == 0)
        args = (self.z, *self.symbols)
        clean = lambda e: e.replace(sp.DiracDelta, lambda *a: sp.Integer(0))  # noqa: E731 - d sign/dz = 0 off 0
        self._f = sp.lambdify(args, full, modules="torch")
        # derivatives on real symbols: Abs(z)' is sign(z), also inside Abs(c*z) for a constant c (on
        # complex symbols sympy leaves Derivative(re(.)), which the torch printer can only hand to autograd)
        real = {s: sp.Dummy(str(s), real=True) for s in args}
        back = {v: k for k, v in real.items()}

        def derivative(s):
            return clean(sp.diff(full.xreplace(real), real[s]).xreplace(back))

        self._grads = [sp.lambdify(args, derivative(s), modules="torch") for s in self.symbols]
        self._dz = sp.lambdify(args, derivative(self.z), modules="torch")

    def expression(self, values):
        import sympy as sp

        return self.template.xreplace({s: sp.Float(float(v)) for s, v in zip(self.symbols, values)}) + self.const

    def init(self, K, generator, dtype):  # pragma: no cover - closed forms start from their own values
        import torch

        return torch.as_tensor(self.theta0, dtype=dtype).expand(K, -1).clone()

    def _call(self, fn, theta, u):
        import torch

        if u.dim() == 1:
            u = u.unsqueeze(0).expand(theta.shape[0], -1)
        cols = [theta[:, i:i + 1] for i in range(self.n_params)]
        return torch.broadcast_to(torch.as_tensor(fn(u, *cols), dtype=u.dtype), u.shape)

    def evaluate(self, theta, u, u_both=None):
        return self._call(self._f, theta, u)

    def evaluate_jacobian(self, theta, u, u_both=None):
        import torch

        f = self._call(self._f, theta, u)
        if not self.n_params:
            return f, f.new_zeros(*f.shape, 0)
        return f, torch.stack([self._call(g, theta, u) for g in self._grads], dim=-1)

    def evaluate_all(self, theta, u):
        import torch

        f, J = self.evaluate_jacobian(theta, u)
        d = self._call(self._dz, theta, u)
        bad = ~torch.isfinite(d)
        if bool(bad.any()):  # 0/0 where a term such as z*sqrt(|z|) has its limit: the slope just beside
            d = torch.where(bad, self._call(self._dz, theta, u + 1e-9 * (1.0 + u.abs())), d)
        return f, J, d

    def decay_groups(self) -> list:
        return []

    def linear_parts(self, theta, u, u_both=None) -> list:
        return []


def _replace_floats(expr, out: list):
    """``expr`` with every Float (not exponents) replaced by a placeholder ``__c<i>``."""
    import sympy as sp

    if isinstance(expr, sp.Float):
        sym = sp.Symbol(f"__c{len(out)}")
        out.append(float(expr))
        return sym
    if not expr.args:
        return expr
    if isinstance(expr, sp.Pow):
        base, exp = expr.args
        return sp.Pow(_replace_floats(base, out), exp)  # exponents are structure, not coefficients
    return expr.func(*[_replace_floats(a, out) for a in expr.args])
