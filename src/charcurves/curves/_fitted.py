"""Fitted curves: callables on the original (unscaled) argument, serialisable without pickle."""

from __future__ import annotations

import abc
from typing import Any, ClassVar

import numpy as np

from .._errors import ModelFileError
from .._lambdify import numpy_function
from ._expr import monomial_power, parse_basis_function
from ._loadable import registered_curve
from ._neural import NeuralCurve, jump_log_eps

__all__ = ["FittedCurve", "NeuralFittedCurve", "BasisFittedCurve", "SymbolicFittedCurve", "LinearFittedCurve"]


class FittedCurve(abc.ABC):
    """A learned univariate curve ``f(z)`` with an additive gauge shift.

    Attributes
    ----------
    name : str          e.g. "f1"
    argument : str      the argument as written in the equation, e.g. "x'"
    domain : (float, float)  the training range of the argument
    shift : float       constant added to the raw representation (gauge)

    Examples
    --------
    >>> from charcurves.curves import FittedCurve, SymbolicFittedCurve
    >>> f2 = SymbolicFittedCurve("f2", "x", (-2.0, 2.0), "z**3 - z")
    >>> isinstance(f2, FittedCurve), f2.domain, f2([0.0, 2.0]).tolist()
    (True, (-2.0, 2.0), [0.0, 6.0])
    """

    kind: ClassVar[str]

    def __init__(self, name: str, argument: str, domain: tuple[float, float], shift: float = 0.0):
        self.name = name
        self.argument = argument
        self.domain = (float(domain[0]), float(domain[1]))
        self.shift = float(shift)
        if not (np.all(np.isfinite(self.domain)) and self.domain[0] <= self.domain[1]):
            raise ModelFileError(f"curve {name}: domain {list(domain)} must be two finite numbers, low <= high; the "
                                 "model file is corrupted or was edited by hand, re-fit the model")
        if not np.isfinite(self.shift):
            raise ModelFileError(f"curve {name}: shift {shift!r} is not finite; the model file is corrupted, "
                                 "re-fit the model")

    @abc.abstractmethod
    def raw(self, z: np.ndarray) -> np.ndarray:
        """The representation's value before the gauge shift."""

    @property
    @abc.abstractmethod
    def pinned_at_zero(self) -> bool:
        """True when the representation forces f(0) = 0 exactly."""

    def __call__(self, z) -> np.ndarray:
        z = np.asarray(z, dtype=float)
        return self.raw(z) + self.shift

    #: True for curves whose :meth:`expression` is a closed form (known without building it)
    closed_form: ClassVar[bool] = False

    def expression(self):
        """A sympy expression in the symbol ``z`` when the curve is symbolic, else None."""
        return None

    def float_function(self):
        """The curve as a function of one Python float (fast in fixed-step free runs): closed forms
        compiled with ``math``, other curves through their numpy evaluation."""
        expr = self.expression()
        if expr is not None:
            import sympy as sp

            try:
                fn = sp.lambdify(sp.Symbol("z"), expr, modules="math")
                fn(0.5)
                return fn
            except (TypeError, ValueError, NameError, AttributeError, OverflowError, ZeroDivisionError):
                pass  # e.g. sign() has no math counterpart: fall back to numpy

        def f(z):
            return float(np.asarray(self(np.array([z], dtype=float))).reshape(-1)[0])

        return f

    def grid(self, n: int = 1000) -> np.ndarray:
        return np.linspace(self.domain[0], self.domain[1], n)

    def components(self) -> dict[str, float]:
        """Named parts worth reporting (e.g. a jump's height and width)."""
        return {}

    @abc.abstractmethod
    def to_spec(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """JSON-able description and named arrays."""

    def _base_spec(self) -> dict[str, Any]:
        return {
            "kind": self.kind,
            "name": self.name,
            "argument": self.argument,
            "domain": list(self.domain),
            "shift": self.shift,
        }


class NeuralFittedCurve(FittedCurve):
    """A trained neural curve: ``out_scale * mean_m f_net_m((z - in_center) / in_scale) + shift``.

    ``in_center`` is 0 unless the curve's data range excluded 0 (see
    :func:`~charcurves.curves.neural_input_map`); model files without it read as 0.

    ``theta`` holds one row of weights per ensemble member (several starts of the same fit
    are averaged: it cancels most of the initialisation-dependent part of the error).

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.curves import NeuralCurve, NeuralFittedCurve
    >>> spec = NeuralCurve(hidden=(4,), symmetry="odd")
    >>> theta = np.random.default_rng(0).normal(size=(3, spec.n_params))  # 3 members
    >>> f1 = NeuralFittedCurve("f1", "x'", (-1.0, 1.0), spec, theta, in_scale=1.0, out_scale=2.0)
    >>> f1.theta.shape, f1.pinned_at_zero, bool(np.isclose(f1(-0.5), -f1(0.5)))
    ((3, 14), True, True)
    """

    kind = "neural"

    def __init__(self, name, argument, domain, spec: NeuralCurve, theta: np.ndarray,
                 in_scale: float, out_scale: float, shift: float = 0.0, in_center: float = 0.0):
        super().__init__(name, argument, domain, shift)
        self.spec = spec
        self.theta = np.atleast_2d(np.asarray(theta, dtype=np.float64))
        if self.theta.ndim != 2 or self.theta.shape[1] != spec.n_params:
            raise ModelFileError(f"curve {name}: weights of shape {self.theta.shape} stored but the network needs "
                                 f"{spec.n_params} per member; the model file is corrupted")
        self.in_scale = float(in_scale)
        self.out_scale = float(out_scale)
        self.in_center = float(in_center)
        if not (np.isfinite(self.in_scale) and self.in_scale > 0 and np.isfinite(self.out_scale)
                and np.isfinite(self.in_center)
                and self.out_scale != 0 and np.all(np.isfinite(self.theta))):
            raise ModelFileError(f"curve {name}: input scale {in_scale!r} must be finite and positive, output scale "
                                 f"{out_scale!r} finite and non-zero, and the weights finite; the model file is "
                                 "corrupted or was edited by hand, re-fit the model")

    @property
    def pinned_at_zero(self) -> bool:
        return self.spec.pinned_at_zero

    def numpy_function(self):
        """A pure-numpy evaluation of the raw curve (no torch call per point: fast in ODE right-hand sides)."""
        spec = self.spec
        layers = []
        o = 0
        sizes = (1, *spec.hidden, 1)
        for fan_in, fan_out in zip(sizes[:-1], sizes[1:]):
            W = self.theta[:, o:o + fan_in * fan_out].reshape(-1, fan_in, fan_out)
            o += fan_in * fan_out
            b = self.theta[:, o:o + fan_out].reshape(-1, 1, fan_out)
            o += fan_out
            layers.append((W, b))
        act = _NUMPY_ACTIVATIONS[spec.activation]
        sl = spec.slices()
        lin = self.theta[:, sl["linear"]].reshape(-1, 1) if "linear" in sl else None
        poly = [(self.theta[:, sl["poly"].start + j].reshape(-1, 1), k) for j, k in enumerate(spec.poly_powers)]
        harm = [(self.theta[:, sl["harmonic"].start + j].reshape(-1, 1), np.sin if kind == "sin" else np.cos, w)
                for j, (kind, w) in enumerate(spec.harmonic_columns)]
        mu = self.theta[:, sl["jump_height"]].reshape(-1, 1) if spec.jump else None
        eps = np.exp(jump_log_eps(self.theta[:, sl["jump_log_eps"]])).reshape(-1, 1) if spec.jump else None
        sym = spec.exact_symmetry
        s_in, s_out, c_in = self.in_scale, self.out_scale, self.in_center

        def net(u):  # u: (n,) -> (members, n)
            h = u.reshape(1, -1, 1)
            for i, (W, b) in enumerate(layers):
                h = h @ W + b
                if i < len(layers) - 1:
                    h = act(h)
            return h[..., 0]

        def f(z):
            z = np.asarray(z, dtype=np.float64)
            u = (z.reshape(-1) - c_in) / s_in if c_in else z.reshape(-1) / s_in
            if sym == "none":
                y = net(u)
            else:
                y = 0.5 * (net(u) - net(-u)) if sym == "odd" else 0.5 * (net(u) + net(-u))
            if lin is not None:
                y = y + lin * u
            for c, k in poly:
                y = y + c * u**k
            for c, fn, w in harm:
                y = y + c * fn(w * u)
            if mu is not None:
                y = y + mu * np.tanh(u / eps)
            return (y.mean(axis=0) * s_out).reshape(z.shape)

        return f

    def raw(self, z):
        if getattr(self, "_np_fn", None) is None:
            self._np_fn = self.numpy_function()
        return self._np_fn(z)

    def raw_torch(self, z):
        """The same curve evaluated through torch (the training code path), for checks."""
        import torch

        z = np.asarray(z, dtype=np.float64)
        shape = z.shape
        with torch.no_grad():
            th = torch.as_tensor(self.theta, dtype=torch.float64)
            u = torch.as_tensor((z.reshape(-1) - self.in_center) / self.in_scale, dtype=torch.float64)
            y = self.spec.evaluate(th, u).mean(dim=0).numpy()
        return (y * self.out_scale).reshape(shape)

    def components(self):
        sl = self.spec.slices()
        out = {}
        if "linear" in sl:
            out["linear_slope"] = float(self.theta[:, sl["linear"]].mean() * self.out_scale / self.in_scale)
        if self.spec.jump:
            out["jump_height"] = float(self.theta[:, sl["jump_height"]].mean() * self.out_scale)
            out["jump_width"] = float(np.exp(jump_log_eps(self.theta[:, sl["jump_log_eps"]])).mean() * self.in_scale)
        if self.spec.harmonics:  # angular frequencies in the curve's own argument
            out["harmonic_frequencies"] = [w / self.in_scale for w in self.spec.harmonics]
        out["ensemble_members"] = int(self.theta.shape[0])
        return out

    def to_spec(self):
        d = self._base_spec()
        d.update(
            network={
                "hidden": list(self.spec.hidden),
                "activation": self.spec.activation,
                "symmetry": self.spec.symmetry,
                "symmetry_mode": self.spec.symmetry_mode,
                "linear_term": self.spec.linear_term,
                "jump": self.spec.jump,
                **({"powers": list(self.spec.powers)} if self.spec.powers else {}),
                **({"harmonics": list(self.spec.harmonics)} if self.spec.harmonics else {}),
            },
            in_scale=self.in_scale,
            out_scale=self.out_scale,
            **({"in_center": self.in_center} if self.in_center else {}),
        )
        return d, {f"{self.name}.theta": self.theta}

    @classmethod
    def from_spec(cls, d, arrays):
        net = d["network"]
        spec = NeuralCurve(hidden=tuple(net["hidden"]), activation=net["activation"], symmetry=net["symmetry"],
                           symmetry_mode=net["symmetry_mode"], linear_term=bool(net["linear_term"]),
                           jump=bool(net["jump"]), powers=tuple(int(k) for k in net.get("powers", ())),
                           harmonics=tuple(float(w) for w in net.get("harmonics", ())))
        key = f"{d['name']}.theta"
        if key not in arrays:
            raise ModelFileError(f"the weights of curve {d['name']} are missing from the model file")
        return cls(d["name"], d["argument"], tuple(d["domain"]), spec, arrays[key],
                   d["in_scale"], d["out_scale"], d["shift"], in_center=d.get("in_center", 0.0))


def _np_gelu(z):
    from scipy.special import erf

    return 0.5 * z * (1.0 + erf(z / np.sqrt(2.0)))


_NUMPY_ACTIVATIONS = {
    "tanh": np.tanh,
    "relu": lambda z: np.maximum(z, 0.0),
    "softplus": lambda z: np.logaddexp(0.0, z),
    "gelu": _np_gelu,
    "silu": lambda z: z / (1.0 + np.exp(-z)),
}


class BasisFittedCurve(FittedCurve):
    """A linear combination of closed-form basis functions of ``z``: ``sum c_j b_j(z) + shift``.

    Examples
    --------
    >>> from charcurves.curves import BasisFittedCurve
    >>> f1 = BasisFittedCurve("f1", "x'", (-1.0, 1.0), ["z", "tanh(50*z)"], [0.3, 0.8])
    >>> f1.expression(), round(float(f1(0.5)), 4)
    (0.3*z + 0.8*tanh(50*z), 0.95)
    """

    kind = "basis"
    closed_form = True

    def __init__(self, name, argument, domain, basis: list[str], coefficients, shift: float = 0.0):
        super().__init__(name, argument, domain, shift)
        import sympy as sp

        self.basis = [str(b) for b in basis]
        self.coefficients = np.asarray(coefficients, dtype=float).reshape(-1)
        if not np.all(np.isfinite(self.coefficients)):
            raise ModelFileError(f"curve {name}: its coefficients are not all finite; the model file is corrupted or "
                                 "the fit failed, re-fit the model")
        if self.coefficients.shape[0] != len(self.basis):
            raise ModelFileError(f"curve {name}: {len(self.basis)} basis functions but "
                                 f"{self.coefficients.shape[0]} coefficients; the model file is corrupted")
        powers = [monomial_power(b) for b in self.basis]
        # plain monomials (fitted polynomials and libraries) evaluate without sympy
        self._powers = None if any(k is None for k in powers) else tuple(int(k or 0) for k in powers)
        self._exprs_cache: list | None = None
        if self._powers is None:
            z = sp.Symbol("z")
            self._funcs = [numpy_function(z, e) for e in self._exprs]
            self._pinned = all(sp.simplify(e.subs(z, 0)) == 0 for e in self._exprs)
        else:
            self._funcs = [(lambda z, k=k: z**k if k != 1 else z) if k else (lambda z: 1) for k in self._powers]
            self._pinned = all(k > 0 for k in self._powers)

    @property
    def _exprs(self) -> list:
        if self._exprs_cache is None:
            self._exprs_cache = [parse_basis_function(b) for b in self.basis]
        return self._exprs_cache

    @property
    def pinned_at_zero(self) -> bool:
        return self._pinned

    def monomial_powers(self) -> tuple[int, ...] | None:  # each basis function's power of z if all are monomials
        return self._powers

    def raw(self, z):
        z = np.asarray(z, dtype=float)
        out = np.zeros_like(z)
        for c, f in zip(self.coefficients, self._funcs):
            fz = f(z)  # broadcast only what needs it (a constant term): a free run calls this per stage
            out = out + c * (fz if np.shape(fz) == z.shape else np.broadcast_to(fz, z.shape))
        return out

    def float_function(self):
        if self._powers is None:
            return super().float_function()
        terms = [(float(c), k) for c, k in zip(self.coefficients, self._powers)]
        shift = float(self.shift)

        def f(z):
            s = shift
            for c, k in terms:
                s += c * z**k
            return s

        return f

    def expression(self):
        import sympy as sp

        expr = sum((sp.Float(c) * e for c, e in zip(self.coefficients, self._exprs)), sp.Integer(0))
        if self.shift != 0.0:
            expr = expr + sp.Float(self.shift)
        return expr

    def to_spec(self):
        d = self._base_spec()
        d["basis"] = list(self.basis)
        return d, {f"{self.name}.coefficients": self.coefficients}

    @classmethod
    def from_spec(cls, d, arrays):
        key = f"{d['name']}.coefficients"
        if key not in arrays:
            raise ModelFileError(f"the coefficients of curve {d['name']} are missing from the model file")
        return cls(d["name"], d["argument"], tuple(d["domain"]), d["basis"], arrays[key], d["shift"])


class SymbolicFittedCurve(FittedCurve):
    """A closed-form curve ``expr(z) + shift`` (from symbolic regression or post-SR).

    ``sign`` and ``Abs`` evaluate exactly here; simulation code may smooth them (documented there).

    Examples
    --------
    >>> from charcurves.curves import SymbolicFittedCurve
    >>> f2 = SymbolicFittedCurve("f2", "x", (-2.0, 2.0), "1.274*z", shift=0.1)
    >>> f2.expression(), f2.pinned_at_zero, round(float(f2(1.0)), 3)
    (1.274*z + 0.1, True, 1.374)
    """

    kind = "symbolic"
    closed_form = True

    def __init__(self, name, argument, domain, expression, shift: float = 0.0, meta: dict | None = None):
        super().__init__(name, argument, domain, shift)
        import sympy as sp

        self._expr = parse_basis_function(str(expression)) if not isinstance(expression, sp.Expr) else expression
        extra = self._expr.free_symbols - {sp.Symbol("z")}
        if extra:
            from .._errors import ConfigError

            raise ConfigError(f"curve {name}: expression uses {sorted(map(str, extra))}; it must depend on z only")
        self._func = numpy_function(sp.Symbol("z"), self._expr)
        self._pinned = bool(self._expr.subs(sp.Symbol("z"), 0) == 0)
        self.meta = dict(meta or {})

    @property
    def pinned_at_zero(self) -> bool:
        return self._pinned

    def raw(self, z):
        z = np.asarray(z, dtype=float)
        return np.broadcast_to(np.asarray(self._func(z), dtype=float), z.shape).copy()

    def expression(self):
        import sympy as sp

        return self._expr + sp.Float(self.shift) if self.shift != 0.0 else self._expr

    def to_spec(self):
        d = self._base_spec()
        d["expression"] = str(self._expr)
        d["meta"] = self.meta
        return d, {}

    @classmethod
    def from_spec(cls, d, arrays):
        return cls(d["name"], d["argument"], tuple(d["domain"]), d["expression"], d["shift"], d.get("meta"))


class LinearFittedCurve(FittedCurve):
    """A fitted :class:`~charcurves.curves.LinearCurve` of any kind (also user-written ones):
    ``constant + sum_k c_k phi_k((z - center) / half_width) + shift``.

    The model file stores the representation's class name and parameters and the coefficients;
    loading rebuilds the representation through :func:`~charcurves.curves.register_curve` (no code
    is imported from the file).

    Examples
    --------
    >>> from charcurves.curves import Basis, LinearFittedCurve
    >>> f2 = LinearFittedCurve("f2", "x", (-2.0, 2.0), Basis("z, z**3"), [-2.0, 8.0], half_width=2.0)
    >>> [round(float(v), 6) for v in f2([1.0, 2.0])]
    [0.0, 6.0]
    """

    kind = "linear"

    def __init__(self, name, argument, domain, representation, coefficients, center: float = 0.0,
                 half_width: float = 1.0, constant: float = 0.0, shift: float = 0.0):
        super().__init__(name, argument, domain, shift)
        self.representation = representation
        self.coefficients = np.asarray(coefficients, dtype=float).reshape(-1)
        self.center = float(center)
        self.half_width = float(half_width)
        self.constant = float(constant)
        if not (np.isfinite(self.half_width) and self.half_width > 0 and np.isfinite(self.center)):
            raise ModelFileError(f"curve {name}: the argument scaling (center {center!r}, half width {half_width!r}) "
                                 "must be finite with a positive half width; the model file is corrupted")

    @property
    def pinned_at_zero(self) -> bool:
        return self.center == 0.0 and self.constant == 0.0 and bool(self.representation.pinned_at_zero)

    def raw(self, z):
        import torch

        z = np.asarray(z, dtype=float)
        u = torch.as_tensor((z.reshape(-1) - self.center) / self.half_width, dtype=torch.float64)
        with torch.no_grad():
            phi = self.representation.features(u).double().numpy()
        return (phi @ self.coefficients + self.constant).reshape(z.shape)

    def to_spec(self):
        d = self._base_spec()
        params = self.representation.get_params()
        if any(hasattr(v, "get_params") for v in params.values()):  # a representation (or estimator) inside
            raise ModelFileError(f"curve {self.name}: nested representations cannot be saved")
        d.update(representation=type(self.representation).__name__, parameters=_plain(params),
                 center=self.center, half_width=self.half_width, constant=self.constant)
        return d, {f"{self.name}.coefficients": self.coefficients}

    @classmethod
    def from_spec(cls, d, arrays):
        rep = registered_curve(str(d.get("representation")))(**dict(d.get("parameters") or {}))
        key = f"{d['name']}.coefficients"
        if key not in arrays:
            raise ModelFileError(f"the coefficients of curve {d['name']} are missing from the model file")
        return cls(d["name"], d["argument"], tuple(d["domain"]), rep, arrays[key], d.get("center", 0.0),
                   d.get("half_width", 1.0), d.get("constant", 0.0), d["shift"])


def _plain(obj):
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, (np.floating, np.integer)):
        return obj.item()
    return obj
