"""Jumps at zero velocity in fitted curves (dry friction), for the ODE right-hand sides.

A jump is read from the curve's parametrisation (a network's ``mu * tanh(u / eps)`` term, a
symbolic ``c * tanh(k z)`` or ``c * sign(z)`` term) or, for other curves, detected numerically;
:func:`charcurves.simulate.prepare_curve` splits it off so that it can be integrated with events.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

__all__: list[str] = []


def _neural_jump(curve):
    """(mean height, largest width) of a network curve's jump term, else None."""
    spec = getattr(curve, "spec", None)
    if spec is None or not getattr(spec, "jump", False):
        return None
    mu, width = _jump_members(curve)
    return float(mu.mean()), float(width.max())


def _jump_members(curve) -> tuple[np.ndarray, np.ndarray]:
    """Per-member jump heights and widths of a network curve, in the curve's own units."""
    # imported here: the module loads torch, which a network curve has loaded already anyway
    from ..curves import jump_log_eps  # the raw width parameter is mapped, not exp'd

    sl = curve.spec.slices()
    mu = curve.theta[:, sl["jump_height"]].reshape(-1) * curve.out_scale
    width = np.exp(jump_log_eps(curve.theta[:, sl["jump_log_eps"]].reshape(-1))) * curve.in_scale
    return mu, width


def _symbolic_jump(expr, scale: float, sharp: float | None):
    """Split sympy ``expr`` (in z) into (smooth expression, height, width) by its sign/tanh terms.

    ``sharp`` is the widest tanh that counts as a jump (None: any tanh(k z) term).
    """
    import sympy as sp

    z = sp.Symbol("z")
    height, width, smooth_terms = 0.0, 0.0, []
    for term in sp.Add.make_args(expr):
        coeff, rest = term.as_coeff_Mul()
        k = None
        if isinstance(rest, sp.sign) and rest.args[0] == z:
            k = math.inf
        elif isinstance(rest, sp.tanh):
            arg = sp.expand(rest.args[0])
            kz = arg.coeff(z)
            if kz.is_number and sp.simplify(arg - kz * z) == 0 and kz != 0:
                k = float(kz)
        if k is not None and (sharp is None or abs(k) == math.inf or 1.0 / abs(k) <= sharp * scale):
            height += float(coeff) * (1.0 if k > 0 else -1.0)
            width = max(width, 0.0 if abs(k) == math.inf else 1.0 / abs(k))
            continue
        smooth_terms.append(term)
    if height == 0.0:
        return None
    return sp.Add(*smooth_terms), height, width


def _numeric_jump(f: Callable[[np.ndarray], np.ndarray], scale: float):
    """(height, width) of a jump at 0 that is narrower than 1e-9 of the scale, else None.

    A jump shows as a difference f(d) - f(-d) that does not shrink with d; for a smooth curve
    it halves when d halves.
    """
    d = 1e-9 * scale
    y = f(np.array([-2 * d, -d, d, 2 * d]))
    near, far = y[2] - y[1], y[3] - y[0]
    spread = float(np.ptp(f(np.linspace(-scale, scale, 201))))
    if not np.isfinite(near) or abs(near) <= 1e-6 * max(spread, 1e-300):
        return None
    if abs(far - near) > 1e-3 * abs(near):
        return None
    return 0.5 * float(near), 0.0


def _with_jump_term(value, slope, curve, outside=None):
    """Add a network's own ``mean_m mu_m tanh(z / w_m)`` to scalar value/slope functions.

    With ``outside=(lo, hi)``, beyond that range ``value``/``slope`` are the exact whole curve
    already and get nothing added.
    """
    members = list(zip(*(a.tolist() for a in _jump_members(curve))))
    n = len(members)
    lo, hi = outside if outside is not None else (-math.inf, math.inf)

    def v(z: float) -> float:
        base = value(z)
        if not (lo <= z <= hi):
            return base
        return base + sum(mu * math.tanh(z / w) for mu, w in members) / n

    def d(z: float) -> float:
        base = slope(z)
        if not (lo <= z <= hi):
            return base
        return base + sum(mu / w * (1.0 - math.tanh(z / w) ** 2) for mu, w in members) / n

    return v, d


def _jump_term_vector(curve, outside=None) -> Callable[[np.ndarray], np.ndarray]:
    """A network's own ``mean_m mu_m tanh(z / w_m)`` on arrays (0 outside ``outside``, as above)."""
    mu, w = _jump_members(curve)
    lo, hi = outside if outside is not None else (-math.inf, math.inf)

    def f(z: np.ndarray) -> np.ndarray:
        term = np.mean(mu[:, None] * np.tanh(z.reshape(1, -1) / w[:, None]), axis=0).reshape(z.shape)
        return np.where((z >= lo) & (z <= hi), term, 0.0)

    return f
