"""Split an expression of several variables into univariate parts (SR's decomposability verdict)."""

from __future__ import annotations

__all__ = ["decompose"]


def decompose(expr, var_of_curve: dict[str, object]):
    """Split ``f(x, x')`` into univariate parts.

    Parameters
    ----------
    expr : sympy.Expr
    var_of_curve : dict
        Curve name -> its sympy variable, e.g. ``{"f1": v, "f2": x}``.

    Returns
    -------
    parts : dict[str, sympy.Expr]
        Per curve, the sum of the terms in its variable only (0 when none).
    constant : float
        The pure-number part.
    mixed : list of sympy.Expr
        Terms depending on more than one variable (after expansion).

    Examples
    --------
    >>> import sympy as sp
    >>> from charcurves.symbolic import decompose
    >>> x, v = sp.symbols("x v")
    >>> decompose(0.3 * v + x**3 - x + 0.1 + 0.2 * x * v, {"f1": v, "f2": x})
    ({'f1': 0.3*v, 'f2': x**3 - x}, 0.1, [0.2*v*x])
    """
    import sympy as sp

    expanded = sp.expand(expr, power_exp=False, power_base=False, log=False)
    parts = {name: sp.Integer(0) for name in var_of_curve}
    constant = 0.0
    mixed = []
    owner = {v: name for name, v in var_of_curve.items()}
    for term in sp.Add.make_args(expanded):
        syms = term.free_symbols & set(owner)
        if not syms:
            constant += float(term)
        elif len(syms) == 1:
            name = owner[next(iter(syms))]
            parts[name] = parts[name] + term
        else:
            mixed.append(term)
    return parts, constant, mixed
