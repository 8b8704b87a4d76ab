"""A polynomial that continues as a straight line outside its fitted range.

A polynomial of degree 10 fitted on ``[-1, 1]`` (the argument's training range, mapped) grows like
``s**10`` beyond it: one step of a free run past the range (a hysteresis state that the test input
drives further than the training input did) and the simulation diverges. :class:`ContinuedPolynomial`
has the same basis inside ``[-1, 1]`` and continues each basis function by its tangent at the
nearer end outside: ``phi(s) = phi(c) + (s - c) phi'(c)``, ``c = clip(s, -1, 1)``. It stays linear
in its coefficients, so every linear fitter and the output-error problem take it unchanged.
"""

from __future__ import annotations

from ._loadable import remember_curve
from ._polynomial import Polynomial

__all__ = ["ContinuedPolynomial"]


@remember_curve
class ContinuedPolynomial(Polynomial):
    """:class:`Polynomial` inside the mapped range ``[-1, 1]``, its tangent line outside it.

    Parameters are :class:`Polynomial`'s. The fitted curve's ``center`` and ``half_width`` map
    the range to ``[-1, 1]``; beyond it the curve is linear with the slope it has at the end.

    Examples
    --------
    >>> import torch
    >>> from charcurves.curves import ContinuedPolynomial
    >>> rep = ContinuedPolynomial(degree=3, basis="power")
    >>> [round(float(v), 6) for v in rep.features(torch.tensor([0.5, 3.0]))[:, 2]]  # s**3, then 1 + 3 (s - 1)
    [0.125, 7.0]
    """

    def monomial_powers(self):
        return None  # not plain powers outside [-1, 1]: no fast path

    def evaluator(self, theta):
        """``s -> values`` at fixed coefficients ``theta`` (``(K, p)``; ``s``: ``(K, N)``): the polynomial
        at ``clip(s)`` plus the end slopes times the overshoot (the free run's per-stage form)."""
        import torch

        col = theta.unsqueeze(-1)  # (K, p, 1)
        if self.basis_name != "power":
            return lambda s: torch.bmm(self.features(s), col).squeeze(-1)
        pw = torch.tensor(self.powers(), dtype=theta.dtype, device=theta.device)
        ends = torch.tensor([-1.0, 1.0], dtype=theta.dtype, device=theta.device)
        slopes = (pw * ends.unsqueeze(-1).pow(torch.clamp(pw - 1, min=0))) @ theta.T  # (2, K): p'(-1), p'(1)
        low, high = slopes[0].unsqueeze(-1), slopes[1].unsqueeze(-1)

        def f(s):
            inside = torch.clamp(s, -1.0, 1.0)
            value = torch.bmm(inside.unsqueeze(-1).pow(pw), col).squeeze(-1)
            return value + torch.clamp(s - 1.0, min=0.0) * high - torch.clamp(-1.0 - s, min=0.0) * low

        return f

    def features(self, u):
        import torch

        inside = torch.clamp(u, -1.0, 1.0)
        if self.basis_name == "power":  # all powers at once (the free run evaluates this per RK4 stage)
            pw = torch.tensor(self.powers(), dtype=u.dtype, device=u.device)
            c = inside.unsqueeze(-1)
            return c.pow(pw) + (u - inside).unsqueeze(-1) * (pw * c.pow(torch.clamp(pw - 1, min=0)))
        return super().features(inside) + (u - inside).unsqueeze(-1) * super().feature_derivatives(inside)

    def feature_derivatives(self, u):
        import torch

        inside = torch.clamp(u, -1.0, 1.0)
        if self.basis_name == "power":
            pw = torch.tensor(self.powers(), dtype=u.dtype, device=u.device)
            return pw * inside.unsqueeze(-1).pow(torch.clamp(pw - 1, min=0))
        return super().feature_derivatives(inside)
