"""The curves of a hidden-state fit across its seeded starts (:func:`~._fit.fit_state_space`):
representation, per-row argument normalisation and coefficients, and the fitted curves they give."""

from __future__ import annotations

import numpy as np

from .._errors import ConfigError
from ..curves import ContinuedPolynomial, LinearCurve, Polynomial

__all__: list[str] = []


class _Curve:
    """One curve across the starts: representation, per-row normalisation and coefficients."""

    def __init__(self, name, rep, argument, arg_layout, center, half, theta):
        self.name, self.rep, self.argument, self.arg_layout = name, rep, argument, arg_layout
        self.center, self.half, self.theta = center, half, theta  # (B,), (B,), (B, p)

    def param(self):
        from ..curves import LinearParametrisation

        return LinearParametrisation(_WithConstant(self.rep) if _needs_constant(self.rep) else self.rep)

    def values(self, u):
        """``(B, N)`` values at arguments ``u`` ``(B, N)``."""
        import torch

        z = torch.as_tensor((u - self.center[:, None]) / self.half[:, None])
        return self.param().evaluate(torch.as_tensor(self.theta), z).numpy()

    def argument_values(self, fm, traj, cols):
        from ..templates import evaluate_signal

        B = traj.shape[0]
        out = []
        for b in range(B):
            c = dict(cols)
            c.update({name: traj[b, :, d] for d, name in enumerate(fm.layout)})
            out.append(evaluate_signal(fm.curves[self.name].expr, c, traj.shape[1]))
        return np.stack(out)

    def fitted(self, b):
        from ..curves import LinearFittedCurve

        lo, hi = self.domain[b]
        theta, constant = self.theta[b], 0.0
        if _needs_constant(self.rep):
            theta, constant = theta[1:], float(theta[0])
        rep = self.rep
        if isinstance(rep, (_Anchored, _AnchoredPlain)):  # the same basis; a model file names a registered class
            rep = (ContinuedPolynomial if isinstance(rep, _Anchored) else Polynomial)(**rep.get_params())
        return LinearFittedCurve(self.name, self.argument, (float(lo), float(hi)), rep, theta,
                                 float(self.center[b]), float(self.half[b]), constant)


def _needs_constant(rep) -> bool:
    """A polynomial's constant lives outside its basis (in the fitted curve's ``constant``): here it
    is a coefficient, since output error has no other place for it."""
    from ..curves import Polynomial

    return isinstance(rep, Polynomial) and not rep.pinned_at_zero


class _WithConstant(LinearCurve):
    """``1`` and the basis of a representation (the constant trainable)."""

    def __init__(self, rep):
        self.rep = rep

    def features(self, u):
        import torch

        return torch.cat([torch.ones_like(u).unsqueeze(-1), self.rep.features(u)], dim=-1)

    def feature_derivatives(self, u):
        import torch

        return torch.cat([torch.zeros_like(u).unsqueeze(-1), self.rep.feature_derivatives(u)], dim=-1)

    def n_features(self) -> int:
        return int(self.rep.n_features()) + 1

    @property
    def pinned_at_zero(self) -> bool:
        return False

    @property
    def symmetry_name(self):
        return None

    def monomial_powers(self):
        powers = self.rep.monomial_powers()
        return None if powers is None else (0, *powers)


def _representations(template, structure, degree, continued: bool = False, given: dict | None = None):
    out = {}
    for name in structure.curve_names:
        rep = given[name] if given is not None else getattr(template, name, None)
        if rep is None:
            rep = Polynomial(degree=int(degree), basis="power")
        if continued and type(rep) is Polynomial:  # a free run past the fitted range continues the tangent
            rep = ContinuedPolynomial(**rep.get_params())
        if not isinstance(rep, LinearCurve):
            raise ConfigError(f"{name}: hidden-state fits take curves linear in their parameters (Polynomial, Basis, "
                              f"SparseLibrary), not {type(rep).__name__}; give {name}=Polynomial(degree=6)")
        out[name] = rep
    return out


def _pinned(degree, continued: bool = False):
    return (_Anchored if continued else _AnchoredPlain)(degree=int(degree), basis="power")


class _AnchoredPlain(Polynomial):
    """A polynomial without its constant: ``f(0) = 0`` (the argument is centred at 0)."""

    @property
    def pinned_at_zero(self) -> bool:
        return True


class _Anchored(ContinuedPolynomial):
    """A polynomial without its constant: ``f(0) = 0`` (the argument is centred at 0)."""

    @property
    def pinned_at_zero(self) -> bool:
        return True
