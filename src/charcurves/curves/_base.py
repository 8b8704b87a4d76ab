"""The curve interface: a representation (what a curve may be) and its parametrisation (how it is trained).

A **representation** is a small settings object that a user composes into a template, e.g.
``Separable(f1=Polynomial(degree=3, symmetry="odd"), f2=Neural(symmetry="odd"))``. It keeps the
scikit-learn contract (``__init__`` stores, ``get_params``/``set_params``) and knows three things:

* :meth:`AbstractCurve.scaling` -- how the curve's argument ``z`` of one record is mapped onto the
  variable the parameters act on, ``u = (z - center) / half_width`` (per record, so that records
  of different amplitude train in one batch);
* :meth:`AbstractCurve.parametrisation` -- the parameter layout and the batched torch evaluation
  (values, parameter Jacobian and derivative in ``u``): every fitter and objective of charcurves
  (least squares, the batched Adam/Levenberg-Marquardt loop, output error) works through it;
* :meth:`AbstractCurve.fitted` -- the fitted curve (a callable on ``z`` that can be saved) from
  trained parameters.

The representations of the paper are :class:`~charcurves.curves.Neural`,
:class:`~charcurves.curves.Polynomial`, :class:`~charcurves.curves.SparseLibrary`,
:class:`~charcurves.curves.Basis` and :class:`~charcurves.curves.Symbolic` (found by symbolic
regression, so it has no parametrisation to train). A user-written representation that is linear
in its parameters subclasses :class:`LinearCurve` and implements :meth:`LinearCurve.features`; it
then works with every template, fitter and objective (see docs/architecture.md for a complete
example).
"""

from __future__ import annotations

import abc
import inspect
from typing import ClassVar

import numpy as np

from .._errors import ConfigError
from .._params import Params
from ._fitted import LinearFittedCurve
from ._loadable import registered_curve, remember_curve

__all__ = ["AbstractCurve", "LinearCurve", "LinearParametrisation", "register_curve", "registered_curve",
           "SYMMETRY_NAMES", "normalise_symmetry"]

#: Parity priors a representation may take (None means "none").
SYMMETRY_NAMES = ("none", "odd", "even")


def normalise_symmetry(value, owner: str) -> str:
    """``None``/"none"/"odd"/"even" -> "none"/"odd"/"even"; anything else is a ConfigError.

    Examples
    --------
    >>> from charcurves.curves import normalise_symmetry
    >>> normalise_symmetry(None, "Polynomial"), normalise_symmetry(" Odd ", "Polynomial")
    ('none', 'odd')
    """
    if value is None:
        return "none"
    text = str(value).strip().lower()
    if text not in SYMMETRY_NAMES:
        raise ConfigError(f"{owner}: unknown symmetry {value!r}; choose None, 'odd' or 'even'")
    return text


class AbstractCurve(Params, abc.ABC):
    """A curve representation: the interface every fitter and objective of charcurves uses.

    Subclasses store their settings in ``__init__`` (named like the parameters, nothing
    computed), check them in :meth:`check`, and implement :meth:`scaling`,
    :meth:`parametrisation` and :meth:`fitted`.

    Examples
    --------
    >>> from charcurves.curves import AbstractCurve, Neural, Polynomial
    >>> curve = Polynomial(degree=5)
    >>> isinstance(curve, AbstractCurve), curve.kind, isinstance(Neural(), AbstractCurve)
    (True, 'linear', True)
    >>> curve.set_params(symmetry="odd").get_params()
    {'degree': 5, 'symmetry': 'odd', 'rescaling': 'minmax', 'basis': None, 'expand_tol': 1e-09}
    """

    #: "neural" (trained by gradient), "linear" (least squares; also trainable by gradient) or
    #: "symbolic" (symbolic regression)
    kind: ClassVar[str] = ""

    def __repr__(self) -> str:
        sig = inspect.signature(type(self).__init__)
        shown = []
        for name in self._param_names():
            value = getattr(self, name)
            default = sig.parameters[name].default
            if default is inspect.Parameter.empty or not _same(value, default):
                shown.append(f"{name}={value!r}")
        return f"{type(self).__name__}({', '.join(shown)})"

    def __eq__(self, other: object) -> bool:
        return type(self) is type(other) and self.get_params() == other.get_params()  # type: ignore[union-attr]

    __hash__ = None  # type: ignore[assignment]  # mutable through set_params

    # ------------------------------------------------------------------ what fitters use
    @property
    def symmetry_name(self) -> str:
        """The parity prior as "none", "odd" or "even"."""
        return normalise_symmetry(getattr(self, "symmetry", None), type(self).__name__)

    def check(self) -> None:
        """Raise ConfigError for unusable settings (called before any work starts)."""
        self.symmetry_name  # noqa: B018 - validates

    @abc.abstractmethod
    def scaling(self, z: np.ndarray, preset) -> tuple[float, float]:
        """``(center, half_width)`` of the map ``u = (z - center) / half_width`` for one record."""

    @abc.abstractmethod
    def parametrisation(self, preset):
        """The parameter layout and batched torch evaluation (see :class:`LinearParametrisation`)."""

    @abc.abstractmethod
    def fitted(self, name: str, argument: str, domain, theta: np.ndarray, center: float, half_width: float,
               out_scale: float, constant: float = 0.0):
        """The fitted curve of trained parameters ``theta`` (one row per ensemble member), the curve's
        values scaled by ``out_scale``, plus ``constant``."""

    def describe(self) -> str:
        """One line for summaries: the representation with its settings."""
        return repr(self)


def _same(a, b) -> bool:
    try:
        return bool(a == b) and type(a) is type(b)
    except Exception:  # noqa: BLE001 - arrays and other odd values compare as different
        return False


# ---------------------------------------------------------------------------------------------- linear
class LinearCurve(AbstractCurve):
    """A representation linear in its parameters: ``f(u) = sum_k c_k phi_k(u)``.

    Implement :meth:`features` (torch, elementwise in ``u``); optionally :meth:`feature_derivatives`
    (by default torch's forward-mode autodiff), :meth:`scaling` (default ``u = z / max|z|``) and
    :meth:`fitted` (default a :class:`LinearFittedCurve`, which saves the representation's
    parameters and the coefficients; register the class with :func:`register_curve` to load it).
    Constants are not features: the template adds one where a curve must carry a constant.

    Examples
    --------
    >>> import torch
    >>> import charcurves as cc
    >>> from charcurves.curves import LinearCurve, Polynomial
    >>> from charcurves.systems import get_system
    >>> from charcurves.templates import Separable
    >>> class Cubic(LinearCurve):  # f(u) = c1 u + c3 u**3, u = z / max|z|
    ...     def __init__(self):
    ...         pass
    ...     def features(self, u):
    ...         return torch.stack([u, u**3], dim=-1)
    >>> Cubic().n_features(), Cubic().pinned_at_zero
    (2, True)
    >>> template = Separable(f1=Polynomial(degree=1), f2=Cubic())
    >>> model = cc.CharacteristicCurves(template=template).fit(get_system("duffing").simulate()).model_
    >>> [round(float(model.curves["f2"](x)), 6) + 0.0 for x in (1.0, 2.0)]  # x**3 - x (+ 0.0: no -0.0)
    [0.0, 6.0]
    """

    kind = "linear"

    @abc.abstractmethod
    def features(self, u):
        """``(..., p)`` torch tensor of the feature functions at ``u`` (any shape)."""

    def monomial_powers(self) -> tuple[int, ...] | None:
        """The powers ``k`` when every feature is ``u**k`` (a fast path evaluates them at once), else None."""
        return None

    def feature_derivatives(self, u):
        """``(..., p)``: derivatives of the features in ``u``."""
        import torch

        flat = u.reshape(-1)
        ones = torch.ones_like(flat)
        _, tangent = torch.func.jvp(lambda s: self.features(s), (flat,), (ones,))
        return tangent.reshape(*u.shape, -1)

    def feature_names(self) -> list[str]:
        """Names of the features (for reports); default ``phi1, phi2, ...``."""
        return [f"phi{k + 1}" for k in range(self.n_features())]

    def n_features(self) -> int:
        import torch

        return int(self.features(torch.zeros(1, dtype=torch.float64)).shape[-1])

    def scaling(self, z, preset):
        return 0.0, max(float(np.max(np.abs(z))), 1e-300)

    def parametrisation(self, preset):
        return LinearParametrisation(self)

    @property
    def pinned_at_zero(self) -> bool:
        """True when every feature vanishes at ``u = 0`` (with ``center = 0``: f(0) = 0 exactly)."""
        import torch

        return bool(torch.all(self.features(torch.zeros(1, dtype=torch.float64)).abs() < 1e-300))

    def fitted(self, name, argument, domain, theta, center, half_width, out_scale, constant: float = 0.0):
        coef = np.asarray(theta, dtype=float).mean(axis=0) * out_scale
        return LinearFittedCurve(name, argument, domain, self, coef, center, half_width, constant)


class LinearParametrisation:
    """The parametrisation of a :class:`LinearCurve`: ``f = features(u) @ theta``.

    The protocol every parametrisation follows (the neural one is
    :class:`~charcurves.curves.NeuralCurve`): ``n_params``, ``init(K, generator, dtype)``,
    ``evaluate(theta, u, u_both=None)`` -> ``(K, N)``, ``evaluate_jacobian`` -> values and
    ``(K, N, P)``, ``evaluate_all`` -> values, Jacobian and ``d f / d u``, ``decay_groups()``
    (parameter slices under Bayesian weight decay, with labels), ``linear_parts(theta, u, u_both)``
    (parameters that enter linearly and their columns, for least-squares starts),
    ``pinned_at_zero``, ``symmetry``, ``symmetry_mode``, ``exact_symmetry``.

    Examples
    --------
    >>> import torch
    >>> from charcurves.curves import Basis, LinearParametrisation
    >>> param = LinearParametrisation(Basis("z, z**3"))
    >>> param.n_params, param.pinned_at_zero
    (2, True)
    >>> theta = torch.tensor([[-1.0, 1.0]], dtype=torch.float64)
    >>> param.evaluate(theta, torch.tensor([0.5, 2.0], dtype=torch.float64)).tolist()
    [[-0.375, 6.0]]
    """

    symmetry_mode = "exact"

    def __init__(self, curve: LinearCurve):
        self.curve = curve
        self.n_params = int(curve.n_features())
        self.symmetry = curve.symmetry_name
        self.exact_symmetry = self.symmetry
        self.pinned_at_zero = bool(curve.pinned_at_zero)

    def init(self, K: int, generator, dtype):
        import torch

        return torch.zeros(K, self.n_params, dtype=dtype)

    def _features(self, u):
        return self.curve.features(u).to(u.dtype)

    def evaluate(self, theta, u, u_both=None):
        if u.dim() == 1:
            u = u.unsqueeze(0).expand(theta.shape[0], -1)
        return (self._features(u) * theta.unsqueeze(1)).sum(-1)

    def evaluate_jacobian(self, theta, u, u_both=None):
        if u.dim() == 1:
            u = u.unsqueeze(0).expand(theta.shape[0], -1)
        phi = self._features(u)
        return (phi * theta.unsqueeze(1)).sum(-1), phi

    def evaluator(self, theta):
        """``u -> evaluate(theta, u)`` for fixed ``theta`` (``u``: ``(K, N)``), with the per-call work
        done once: the coefficients as a column, monomials as one power of the argument."""
        import torch

        own = getattr(self.curve, "evaluator", None)  # a representation's own fast form (ContinuedPolynomial)
        if own is not None:
            return own(theta)
        col = theta.unsqueeze(-1)  # (K, p, 1)
        powers = self.curve.monomial_powers()
        if powers is not None:
            pw = torch.tensor(powers, dtype=theta.dtype, device=theta.device)
            return lambda u: torch.bmm(u.unsqueeze(-1).pow(pw), col).squeeze(-1)
        return lambda u: torch.bmm(self._features(u), col).squeeze(-1)

    def evaluate_all(self, theta, u):
        f, J = self.evaluate_jacobian(theta, u)
        d = (self.curve.feature_derivatives(u).to(u.dtype) * theta.unsqueeze(1)).sum(-1)
        return f, J, d

    def decay_groups(self) -> list:
        return []

    def linear_parts(self, theta, u, u_both=None) -> list:
        if u.dim() == 1:
            u = u.unsqueeze(0).expand(theta.shape[0], -1)
        phi = self._features(u)
        return [(k, phi[..., k], False) for k in range(self.n_params)]


def register_curve(cls: type) -> type:
    """Make a user-written :class:`LinearCurve` subclass loadable from model files (by class name).

    Model files never import code: a saved ``LinearFittedCurve`` names its representation, and
    only registered (or built-in) classes are rebuilt. Usable as a decorator.

    Examples
    --------
    >>> import os, tempfile
    >>> import torch
    >>> import charcurves as cc
    >>> from charcurves.curves import LinearCurve, Polynomial, register_curve
    >>> from charcurves.systems import get_system
    >>> from charcurves.templates import Separable
    >>> @register_curve
    ... class Cubic(LinearCurve):  # f(u) = c1 u + c3 u**3
    ...     def __init__(self):
    ...         pass
    ...     def features(self, u):
    ...         return torch.stack([u, u**3], dim=-1)
    >>> template = Separable(f1=Polynomial(degree=1), f2=Cubic())
    >>> model = cc.fit(get_system("duffing").simulate(), template=template)
    >>> path = os.path.join(tempfile.mkdtemp(), "cubic-model")
    >>> model.save(path)
    >>> round(float(cc.load_model(path).curves["f2"](2.0)), 6)
    6.0
    """
    if not (isinstance(cls, type) and issubclass(cls, LinearCurve)):
        raise ConfigError(f"register_curve takes a LinearCurve subclass, got {cls!r}")
    return remember_curve(cls)
