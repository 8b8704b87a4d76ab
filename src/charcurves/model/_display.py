"""Closed forms and numbers as people read them: rounded to the precision a fit supports, the terms
that change no printed digit dropped. The stored model keeps every digit; only what is printed is
rounded. The model's ``to_sympy(digits=...)``, its views and its figures use these.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from .._lambdify import numpy_function

__all__ = ["DISPLAY_DIGITS", "display_expression", "display_number", "format_closed_form", "curve_scale"]

#: Significant digits of the closed forms shown to people (the stored model keeps every digit).
DISPLAY_DIGITS = 4


def display_expression(expr, domain: Sequence[float] | None = None, *, digits: int = DISPLAY_DIGITS):
    """A closed form rounded to ``digits`` significant digits, without the terms that are zero at that precision.

    A term is dropped when its largest magnitude over ``domain`` (the curve's training range) is
    below ``10**-digits`` times the largest magnitude of the whole expression there, so that it
    changes no printed digit of the curve's values. Coefficients within rounding of an integer become
    that integer (``1.0*z**2`` is ``z**2``). Without ``domain`` no term is dropped.

    Parameters
    ----------
    expr : sympy expression or str
        The closed form, in one variable.
    domain : (low, high), optional
        Where the magnitudes are compared.
    digits : int
        Significant digits of the numbers.

    Returns
    -------
    sympy expression

    Examples
    --------
    >>> from charcurves.fitting import display_expression
    >>> str(display_expression("-1.27e-17*z**10 + 0.999999999*z**2 - 1.000000001", (-1.5, 1.5)))
    'z**2 - 1'
    """
    import sympy as sp

    if not isinstance(digits, int) or isinstance(digits, bool) or digits < 1:
        raise ValueError(f"digits must be a positive integer, got {digits!r}")
    expr = sp.sympify(expr)
    symbols = sorted(expr.free_symbols, key=lambda s: s.name)
    terms = list(sp.Add.make_args(expr))  # as found (an SR formula is not expanded)
    if domain is not None and len(symbols) == 1 and len(terms) > 1:
        z = symbols[0]
        grid = np.linspace(float(domain[0]), float(domain[1]), 257)

        def peak(e) -> float:
            with np.errstate(all="ignore"):
                values = np.broadcast_to(np.asarray(numpy_function(z, e)(grid), dtype=float), grid.shape)
            finite = values[np.isfinite(values)]
            return float(np.max(np.abs(finite))) if finite.size else math.inf

        sizes = [peak(t) for t in terms]
        scale = peak(expr) or max(sizes)
        kept = [t for t, s in zip(terms, sizes) if not s < 10.0 ** (-digits) * scale]
        expr = sp.Add(*kept) if kept else sp.Integer(0)
    rounded = sp.N(expr, digits)
    integers = {}
    for f in rounded.atoms(sp.Float):
        r = round(float(f))  # never to 0: whether a term is negligible is decided over the domain above
        if r != 0 and abs(float(f) - r) <= 0.5 * 10.0 ** (1 - digits) * abs(float(f)):
            integers[f] = sp.Integer(r)
    return rounded.xreplace(integers)


def format_closed_form(expr, domain: Sequence[float] | None = None, *, digits: int = DISPLAY_DIGITS,
                       argument: str | None = None) -> str:
    """:func:`display_expression` as text, with the variable written as ``argument`` (``"x'"``).

    Examples
    --------
    >>> from charcurves.fitting import format_closed_form
    >>> format_closed_form("0.299654627958613*z", (-1, 1), argument="x'")
    "0.2997*x'"
    """
    import sympy as sp

    rounded = display_expression(expr, domain, digits=digits)
    symbols = list(rounded.free_symbols)
    if argument is not None and len(symbols) == 1:
        rounded = rounded.subs(symbols[0], sp.Symbol(argument))
    return str(rounded)


def curve_scale(model) -> float:
    """The largest magnitude any curve of ``model`` reaches over its training range (257 points each).

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.fitting import curve_scale
    >>> from charcurves.systems import get_system
    >>> round(curve_scale(cc.fit(get_system("duffing").simulate(), method="parametric", basis="f1=z; f2=z, z**3")), 2)
    1.87
    """
    peaks = [0.0]
    for c in model.curves.values():
        with np.errstate(all="ignore"):
            values = np.asarray(c(np.linspace(c.domain[0], c.domain[1], 257)), dtype=float)
        finite = np.abs(values[np.isfinite(values)])
        peaks.append(float(finite.max()) if finite.size else 0.0)
    return max(peaks)


def display_number(value: float, scale: float, digits: int = DISPLAY_DIGITS):
    """``value`` as a sympy number rounded to ``digits`` significant digits; 0 when it is below
    ``10**-digits * scale`` (a constant that changes no printed digit of terms of size ``scale``).

    Examples
    --------
    >>> from charcurves.fitting import display_number
    >>> display_number(0.299654627958613, 1.0), display_number(2.0000001, 1.0), display_number(3e-9, 6.0)
    (0.2997, 2, 0)
    """
    import sympy as sp

    value = float(value)
    if value == 0 or abs(value) < 10.0 ** (-digits) * scale:
        return sp.Integer(0)
    r = float(f"{value:.{digits}g}")
    return sp.Integer(int(r)) if r == int(r) and abs(r) < 1e15 else sp.Float(r, digits)
