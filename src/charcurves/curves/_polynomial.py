"""Poly-CC's representation: a degree-N polynomial of the rescaled argument.

The paper's Poly-CC (method v): ``f(z) ~ sum_j c_j s^j`` with ``s`` the argument mapped onto a
reference interval ("domain rescaling"). Here:

* the default map sends each curve's training range ``[lo, hi]`` onto ``[-1, 1]``
  (``s = (z - c) / h``, ``c = (lo + hi) / 2``, ``h = (hi - lo) / 2``) and the columns are the
  Chebyshev polynomials ``T_1(s) ... T_N(s)`` (the same span as ``s ... s^N``, better conditioned);
* ``rescaling="scripts"`` reproduces the authors' scripts: ``A0 = (max|z| + min|z|)/2``,
  ``A1 = (max|z| - min|z|)/2`` from *absolute* values (which maps the range to about ``[-3, 1]``)
  with plain powers of ``s``;
* no constant column: constants that curves can trade are placed by the template's gauge (the
  paper's ``f2(0) = 0``; the scripts' ``f1(0) = 0`` with ``gauge="f1"``);
* an "odd"/"even" prior keeps only the odd/even powers of the *unmapped* argument (the map is then
  a pure scaling ``s = z / max|z|``, which preserves parity);
* the fitted polynomial is expanded into powers of ``z`` so that the curve's sympy expression is
  an ordinary polynomial; when the expansion does not reproduce the mapped polynomial to
  ``expand_tol`` (relative, default 1e-9) on the training range (far-from-zero ranges, where
  cancellation ruins the monomial form) the mapped form ``((z - c)/h)**k`` is stored instead.
"""

from __future__ import annotations

import numpy as np

from .._errors import ConfigError
from ._base import LinearCurve, normalise_symmetry
from ._loadable import remember_curve

__all__ = ["Polynomial", "RESCALINGS", "POLY_BASES", "poly_powers"]

#: Domain maps: "minmax" (training range -> [-1, 1]), "scripts" (the authors' |z|-based quirk), "none" (s = z).
RESCALINGS = ("minmax", "scripts", "none")
#: Column functions of the mapped variable.
POLY_BASES = ("chebyshev", "power")


def poly_powers(degree: int, sym: str) -> list[int]:
    """Powers of the mapped variable used as columns (the constant is not a column).

    Examples
    --------
    >>> from charcurves.curves import poly_powers
    >>> poly_powers(5, "none"), poly_powers(5, "odd"), poly_powers(5, "even")
    ([1, 2, 3, 4, 5], [1, 3, 5], [2, 4])
    """
    if sym == "odd":
        return list(range(1, degree + 1, 2))
    if sym == "even":
        return list(range(2, degree + 1, 2))
    return list(range(1, degree + 1))


@remember_curve  # loadable as a LinearFittedCurve's representation (hidden-state fits keep that form)
class Polynomial(LinearCurve):
    """A polynomial curve (Poly-CC).

    Parameters
    ----------
    degree : int
        Highest power, 1 to 30 (the paper: 10).
    symmetry : {None, "odd", "even"}
        Keep only the odd or even powers of the argument (exact parity).
    rescaling : {"minmax", "scripts", "none"}
        The argument map (module docstring).
    basis : {"chebyshev", "power"}, optional
        Column functions of the mapped argument; default Chebyshev ("power" with the scripts' map).
    expand_tol : float
        Relative accuracy the expansion into powers of z must keep (else the mapped form is stored).

    Examples
    --------
    >>> from charcurves.curves import Polynomial
    >>> Polynomial(degree=3, symmetry="odd")
    Polynomial(degree=3, symmetry='odd')
    """

    def __init__(self, degree: int = 10, symmetry: str | None = None, rescaling: str = "minmax",
                 basis: str | None = None, expand_tol: float = 1e-9):
        self.degree = degree
        self.symmetry = symmetry
        self.rescaling = rescaling
        self.basis = basis
        self.expand_tol = expand_tol

    # ------------------------------------------------------------------ settings
    def check(self) -> None:
        sym = normalise_symmetry(self.symmetry, "Polynomial")
        d = self.degree
        if isinstance(d, bool) or not isinstance(d, (int, np.integer)) or not 1 <= int(d) <= 30:
            raise ConfigError(f"poly-cc degree must be an integer from 1 to 30, got {d!r}")
        if self.rescaling not in RESCALINGS:
            raise ConfigError(f"unknown poly-cc rescaling {self.rescaling!r}; choose one of {', '.join(RESCALINGS)}")
        if self.basis_name not in POLY_BASES:
            raise ConfigError(f"unknown poly-cc basis {self.basis!r}; choose one of {', '.join(POLY_BASES)}")
        try:
            tol = float(self.expand_tol)
        except (TypeError, ValueError):
            tol = float("nan")
        if not tol > 0:
            raise ConfigError(f"expand_tol must be positive, got {self.expand_tol!r}")
        if sym == "even" and int(d) < 2:
            raise ConfigError("an even polynomial needs degree >= 2; raise the degree")

    @property
    def basis_name(self) -> str:
        if self.basis is not None:
            return str(self.basis)
        return "power" if self.rescaling == "scripts" else "chebyshev"

    def powers(self) -> list[int]:
        return poly_powers(int(self.degree), self.symmetry_name)

    # ------------------------------------------------------------------ representation
    def scaling(self, z, preset=None):
        """Centre c and half-width h of ``s = (z - c) / h``."""
        z = np.asarray(z, dtype=float)
        if self.rescaling == "none":
            return 0.0, 1.0
        if self.symmetry_name in ("odd", "even"):  # parity in z survives only a pure scaling
            return 0.0, max(float(np.max(np.abs(z))), 1e-300)
        if self.rescaling == "scripts":
            az = np.abs(z)
            c, h = (az.max() + az.min()) / 2.0, (az.max() - az.min()) / 2.0
        else:
            c, h = (z.max() + z.min()) / 2.0, (z.max() - z.min()) / 2.0
        if not h > 0:
            h = max(abs(float(c)), 1.0)  # degenerate (constant) argument: the excitation check refuses it anyway
        return float(c), float(h)

    def monomial_powers(self) -> tuple[int, ...] | None:
        return tuple(self.powers()) if self.basis_name == "power" else None

    def features(self, u):
        import torch

        cols = [_column_torch(u, k, self.basis_name) for k in self.powers()]
        return torch.stack(cols, dim=-1)

    def feature_derivatives(self, u):
        import torch

        cols = [_column_derivative_torch(u, k, self.basis_name) for k in self.powers()]
        return torch.stack(cols, dim=-1)

    def feature_names(self) -> list[str]:
        prefix = "T" if self.basis_name == "chebyshev" else "s^"
        return [f"{prefix}{k}" for k in self.powers()]

    def n_features(self) -> int:
        return len(self.powers())

    @property
    def pinned_at_zero(self) -> bool:
        return self.symmetry_name == "odd"

    def fitted(self, name, argument, domain, theta, center, half_width, out_scale, constant: float = 0.0):
        coef = np.asarray(theta, dtype=float).mean(axis=0) * out_scale
        series = series_in_s(dict(zip(self.powers(), coef)), int(self.degree), self.basis_name)
        series[0] += constant
        curve, form, err = build_polynomial_curve(name, argument, domain, series, center, half_width,
                                                  self.symmetry_name, float(self.expand_tol))
        curve.poly_info = {"form": form, "expansion_error": err, "coefficients_in_s": series.tolist()}
        return curve


def _column_torch(s, k: int, basis: str):
    import torch

    if basis == "power":
        return s**k
    # Chebyshev T_k by the three-term recurrence (stable on [-1, 1])
    t0, t1 = torch.ones_like(s), s
    if k == 0:
        return t0
    for _ in range(k - 1):
        t0, t1 = t1, 2 * s * t1 - t0
    return t1


def _column_derivative_torch(s, k: int, basis: str):
    import torch

    if basis == "power":
        return k * s ** (k - 1) if k > 1 else torch.ones_like(s)
    # T_k' = k U_{k-1}, U by its recurrence
    u0, u1 = torch.ones_like(s), 2 * s
    if k == 1:
        return u0
    for _ in range(k - 2):
        u0, u1 = u1, 2 * s * u1 - u0
    return k * u1


def column_numpy(s: np.ndarray, k: int, basis: str) -> np.ndarray:
    """The column ``T_k(s)`` or ``s**k`` in numpy (what the least-squares design uses).

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.curves import column_numpy
    >>> s = np.array([-1.0, 0.0, 0.5, 1.0])
    >>> column_numpy(s, 3, "chebyshev").tolist(), column_numpy(s, 3, "power").tolist()
    ([-1.0, 0.0, -1.0, 1.0], [-1.0, 0.0, 0.125, 1.0])
    """
    from numpy.polynomial import chebyshev as cheb

    if basis == "chebyshev":
        e = np.zeros(k + 1)
        e[k] = 1.0
        return cheb.chebval(s, e)
    return s**k


def series_in_s(coef_by_power: dict[int, float], degree: int, basis: str) -> np.ndarray:
    """Power-series coefficients (index = power of s) of sum_k c_k B_k(s); no constant included.

    Examples
    --------
    >>> from charcurves.curves import series_in_s
    >>> series_in_s({1: 1.0, 3: 1.0}, 3, "chebyshev").tolist()
    [0.0, -2.0, 0.0, 4.0]
    """
    from numpy.polynomial import chebyshev as cheb

    c = np.zeros(degree + 1)
    for k, v in coef_by_power.items():
        c[k] = v
    return cheb.cheb2poly(c) if basis == "chebyshev" else c


def _expand(series_s: np.ndarray, c: float, h: float) -> np.ndarray:
    """Coefficients in powers of z of sum_k a_k ((z - c)/h)^k."""
    from numpy.polynomial import polynomial as poly

    out = np.zeros(1)
    lin = np.array([-c / h, 1.0 / h])  # s as a polynomial in z
    for a in series_s[::-1]:  # Horner in polynomial arithmetic
        out = poly.polyadd(poly.polymul(out, lin), [a])
    full = np.zeros(len(series_s))
    full[: min(len(out), len(full))] = out[: len(full)]
    return full


def build_polynomial_curve(name: str, argument: str, domain, series_s: np.ndarray, c: float, h: float, sym: str,
                           expand_tol: float):
    """``(BasisFittedCurve, form, error)`` for sum_k a_k s^k: in powers of z when accurate, else mapped.

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.curves import build_polynomial_curve
    >>> series = np.array([0.0, 0.0, 1.0])  # s**2 with s = (z - 1) / 1
    >>> curve, form, error = build_polynomial_curve("f2", "x", (0.0, 2.0), series, 1.0, 1.0, "none", 1e-9)
    >>> curve.expression(), form, error < 1e-12
    (1.0*z**2 - 2.0*z + 1.0, 'power', True)
    """
    from numpy.polynomial import polynomial as poly

    from ._fitted import BasisFittedCurve

    degree = len(series_s) - 1
    keep = [k for k in range(degree + 1)
            if not (sym == "odd" and k % 2 == 0) and not (sym == "even" and k % 2 == 1)]
    grid = np.linspace(domain[0], domain[1], 1000)
    mapped_vals = poly.polyval((grid - c) / h, series_s)
    scale = max(float(np.max(np.abs(mapped_vals))), 1e-300)

    pz = _expand(series_s, c, h)
    # parity of the unmapped variable is exact when c = 0: drop the (zero) opposite powers
    basis = ["1" if k == 0 else ("z" if k == 1 else f"z**{k}") for k in keep]
    curve = BasisFittedCurve(name, argument, domain, basis, [pz[k] for k in keep])
    err = float(np.max(np.abs(curve.raw(grid) - mapped_vals))) / scale
    if err <= expand_tol:
        return curve, "power", err
    if c == 0.0:
        s_txt = f"(z/{float(h)!r})"
    else:
        s_txt = f"((z - {float(c)!r})/{float(h)!r})" if c > 0 else f"((z + {float(-c)!r})/{float(h)!r})"
    basis = ["1" if k == 0 else (s_txt if k == 1 else f"{s_txt}**{k}") for k in keep]
    curve = BasisFittedCurve(name, argument, domain, basis, [series_s[k] for k in keep])
    err = float(np.max(np.abs(curve.raw(grid) - mapped_vals))) / scale
    return curve, "mapped", err
