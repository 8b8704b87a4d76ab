"""Expression utilities shared by the engines, the selection and the fitters: complexity, term
split, safe evaluation, constant polishing, simplification of saturated steps, infix parsing."""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from .._lambdify import numpy_function

__all__ = ["expression_complexity", "numeric_atoms", "n_constants", "canonical", "split_terms", "lambdify_numpy",
           "eval_expression", "polish_constants", "reevaluate", "desaturate", "tidy", "parse_infix", "INFIX_FUNCS"]

def expression_complexity(expr) -> int:
    """Size of an expression tree, counted as a search without ``pow`` would build it.

    Every symbol, constant and operator counts 1; ``b**n`` for an integer n >= 2 counts as the
    n-fold product (``z**3`` = z*z*z = 5), so a cubic is not mistaken for something as simple as
    a linear term.

    Examples
    --------
    >>> import sympy as sp
    >>> from charcurves.symbolic import expression_complexity
    >>> z = sp.Symbol("z")
    >>> expression_complexity(z), expression_complexity(z**3 - z), expression_complexity(0.8 * sp.tanh(50 * z))
    (1, 9, 6)
    """
    import sympy as sp

    if expr.is_Atom:
        return 1
    if expr.is_Pow:
        base, ex = expr.args
        if ex.is_Integer and int(ex) >= 2:
            n = int(ex)
            return n * expression_complexity(base) + n - 1
        if ex.is_Integer and int(ex) == -1:
            return 2 + expression_complexity(base)
        return 1 + expression_complexity(base) + expression_complexity(ex)
    if isinstance(expr, (sp.Add, sp.Mul)):
        return sum(expression_complexity(a) for a in expr.args) + len(expr.args) - 1
    return 1 + sum(expression_complexity(a) for a in expr.args)


def numeric_atoms(expr) -> list:
    """The Floats of ``expr`` (the fitted constants; integer exponents are structure)."""
    import sympy as sp

    return sorted(expr.atoms(sp.Float), key=lambda f: sp.default_sort_key(f))


def n_constants(expr) -> int:
    import sympy as sp

    return len([a for a in sp.preorder_traversal(expr) if isinstance(a, sp.Float)])


def canonical(expr):
    """Expand products and merge constants (``(a z)(b z) + c`` -> ``ab z**2 + c``).

    ``exp``/``log`` rules are off: they would only trade one form for another.
    """
    import sympy as sp

    # expanded on real symbols of the same names (the variables are real), as parse_infix parses: with
    # plain symbols, rebuilding tanh(long argument) asks whether the argument is real, which sympy may
    # answer by a gcd of polynomials in its expanded imaginary part (one stick-slip SR-CC job of the
    # scripts' study spent 10 minutes there); names sort alike, so the canonical order is kept. Trees of
    # + - * and tanh come out as on plain symbols; where sympy rebuilds a node of sqrt, abs, exp or log,
    # real-variable rules apply (sqrt(z**2) -> Abs(z)), as when parse_infix read the search's output
    try:
        out = _on_real_symbols(expr, lambda e: sp.expand(e, power_exp=False, power_base=False, log=False))
    except Exception:  # pragma: no cover - sympy failures on exotic trees
        return expr
    # sympy keeps exact 1.0 factors as Floats: fold Float(1)*b into b only via the term split
    return out


def split_terms(expr) -> list[tuple[float, Any]]:
    """``sum c_j b_j`` -> [(c_j, b_j)] with numeric c_j (b_j = 1 for the constant).

    Examples
    --------
    >>> import sympy as sp
    >>> from charcurves.symbolic import split_terms
    >>> z = sp.Symbol("z")
    >>> split_terms(2.0 * z**3 - z + 0.5)
    [(0.5, 1), (-1.0, z), (2.0, z**3)]
    """
    import sympy as sp

    terms = sp.Add.make_args(expr)
    merged: dict[Any, float] = {}
    for t in terms:
        c, rest = t.as_coeff_Mul()
        if not c.is_Number:
            c, rest = sp.Integer(1), t
        merged[rest] = merged.get(rest, 0.0) + float(c)
    return [(c, b) for b, c in merged.items()]


def lambdify_numpy(expr, symbols):
    """``sympy.lambdify(symbols, expr, modules="numpy")``, remembered per (symbols, expression).

    The selection evaluates the same expressions many times (every search's front, its sub-models,
    the polishing of each candidate, SR-CC's outer iterations); building the function is what
    costs (sympy prints and compiles it), so it is built once per process. The docstring that
    lambdify renders by default (the expression printed a second time) is left out.
    """
    return _lambdify_numpy(tuple(symbols), expr)


@functools.lru_cache(maxsize=4096)
def _lambdify_numpy(symbols: tuple, expr):
    return numpy_function(list(symbols), expr)


def eval_expression(expr, symbols, X) -> np.ndarray | None:
    """Values of ``expr`` on the columns of X; None when not finite.

    Examples
    --------
    >>> import numpy as np
    >>> import sympy as sp
    >>> from charcurves.symbolic import eval_expression
    >>> x, v = sp.symbols("x v")
    >>> eval_expression(x**3 + 0.3 * v, [x, v], np.array([[1.0, 2.0], [2.0, 0.0]])).tolist()
    [1.6, 8.0]
    >>> eval_expression(1 / x, [x], np.array([[0.0]])) is None
    True
    """
    n = X.shape[0]
    if not (expr.free_symbols & set(symbols)):
        try:
            val = float(expr)
        except (TypeError, ValueError):
            return None
        return np.full(n, val) if math.isfinite(val) else None
    f = lambdify_numpy(expr, symbols)
    with np.errstate(all="ignore"):
        try:
            out = np.asarray(f(*[X[:, i] for i in range(X.shape[1])]), dtype=float)
        except (TypeError, ValueError, ZeroDivisionError, OverflowError, AttributeError):
            return None
    out = np.broadcast_to(out, (n,)).astype(float)
    if not np.all(np.isfinite(out)):
        return None
    return out


def reevaluate(expr):
    """``expr`` rebuilt bottom-up with sympy's evaluation (the canonical form of an expression built
    with ``evaluate(False)``).

    Examples
    --------
    >>> import sympy as sp
    >>> from charcurves.symbolic._expressions import reevaluate
    >>> z = sp.Symbol("z")
    >>> with sp.core.parameters.evaluate(False):
    ...     raw = sp.Float(2.0) * sp.tanh(sp.Float(-3.0) * z)
    >>> reevaluate(raw)
    -2.0*tanh(3.0*z)
    """
    # evaluated on real symbols of the same names, as canonical() expands (see there): with plain ones,
    # rebuilding tanh(long argument) may take minutes in sympy's realness queries
    return _on_real_symbols(expr, _rebuild)


def _rebuild(expr):
    if not expr.args:
        return expr
    return expr.func(*[_rebuild(a) for a in expr.args])


def _on_real_symbols(expr, transform):
    """``transform(expr)`` with its plain symbols swapped for real twins and swapped back unevaluated."""
    real = _real_twins(expr)
    if not real:
        return transform(expr)
    out = transform(xreplace_unevaluated(expr, real))
    return xreplace_unevaluated(out, {r: s for s, r in real.items()})


def _real_twins(expr) -> dict:
    """Plain symbols of ``expr`` -> real symbols of the same names (the variables are real).

    Empty (work on the symbols as they are) unless every free symbol is a plain ``Symbol`` with a
    name of its own: a symbol with assumptions, a Dummy or two symbols sharing a name keep sympy's
    own treatment, and the canonical order, which compares symbols' assumptions, stays as it was.
    """
    import sympy as sp

    symbols = expr.free_symbols
    plain = all(type(s) is sp.Symbol and s.assumptions0 == {"commutative": True} for s in symbols)
    if not plain or len({s.name for s in symbols}) != len(symbols):
        return {}
    return {s: sp.Symbol(s.name, real=True) for s in symbols}


def xreplace_unevaluated(expr, mapping):
    """``expr.xreplace(mapping)`` with the changed nodes rebuilt without sympy's evaluation.

    The same tree as ``xreplace`` inside ``sympy.core.parameters.evaluate(False)``, without
    switching that global flag: every switch clears sympy's whole cache (``clear_cache``), and the
    selection, which polishes hundreds of candidates a fit, then recomputed the assumptions of
    every expression it had seen (a third of its time on noisy stick-slip records).

    Examples
    --------
    >>> import sympy as sp
    >>> from charcurves.symbolic._expressions import xreplace_unevaluated
    >>> z, c = sp.symbols("z c")
    >>> xreplace_unevaluated(2.0 * sp.tanh(3.0 * z), {sp.Float(3.0): c, sp.Float(2.0): sp.Float(-1.0)})
    -1.0*tanh(c*z)
    """
    if expr in mapping:
        return mapping[expr]
    if not expr.args:
        return expr
    args = [xreplace_unevaluated(a, mapping) for a in expr.args]
    if all(new is old for new, old in zip(args, expr.args)):
        return expr
    try:
        return expr.func(*args, evaluate=False)
    except TypeError:  # pragma: no cover - a node without the keyword (none among the search's operators)
        import sympy as sp

        with sp.core.parameters.evaluate(False):
            return expr.func(*args)


def polish_constants(expr, symbols, X, y, *, max_nfev: int = 200, canonical: bool = True):
    """Least-squares refinement of every numeric constant of ``expr`` on (X, y).

    Parameters
    ----------
    expr : sympy.Expr
    symbols : sequence of sympy.Symbol
        The variables, in the column order of X.
    X : (N, d) array
    y : (N,) array

    max_nfev : int
        Most evaluations of the residuals.
    canonical : bool
        False: the polished expression is built without sympy's evaluation (its values are the
        same; :func:`reevaluate` gives the canonical form). Building it canonically is most of a
        polish's cost for nested expressions, so the selection polishes every candidate this way
        and makes canonical only the members of its Pareto front.

    Returns
    -------
    (sympy.Expr, float)
        The polished expression and its MSE; the input unchanged when polishing does not lower
        the MSE (or fails).

    Examples
    --------
    >>> import numpy as np
    >>> import sympy as sp
    >>> from charcurves.symbolic import polish_constants
    >>> z = sp.Symbol("z")
    >>> X = np.linspace(-2, 2, 100)[:, None]
    >>> polished = polish_constants(0.9 * z**3 - 1.1 * z, [z], X, 2 * X[:, 0] ** 3 - X[:, 0])
    >>> sp.nsimplify(polished, tolerance=1e-9, rational=True)
    (2*z**3 - z, 0)
    """
    import sympy as sp
    from scipy.optimize import least_squares

    y = np.asarray(y, dtype=float)
    base = eval_expression(expr, symbols, X)
    mse0 = float(np.mean((base - y) ** 2)) if base is not None else math.inf
    consts = numeric_atoms(expr)
    if not consts:
        return expr, mse0
    params = sp.symbols(f"__c0:{len(consts)}")
    # the template is only compiled, never shown: building it unevaluated skips sympy's
    # canonicalisation (assumption queries on every nested tanh: most of a polish's time)
    template = xreplace_unevaluated(expr, dict(zip(consts, params)))
    f = lambdify_numpy(template, list(symbols) + list(params))
    cols = [X[:, i] for i in range(X.shape[1])]
    p0 = np.array([float(c) for c in consts])

    def resid(p):
        with np.errstate(all="ignore"):
            r = np.broadcast_to(np.asarray(f(*cols, *p), dtype=float), y.shape) - y
        return np.where(np.isfinite(r), r, 1e6)

    try:
        sol = least_squares(resid, p0, method="trf", x_scale="jac", max_nfev=max_nfev)
    except (ValueError, FloatingPointError, OverflowError):  # pragma: no cover - defensive
        return expr, mse0
    # a polish that cannot win (beyond the rounding of its constants to 15 digits) is not built
    if not float(np.mean(resid(sol.x) ** 2)) <= mse0 * (1.0 + 1e-6):
        return expr, mse0
    values = {c: sp.Float(v, 15) for c, v in zip(consts, sol.x)}
    if not canonical:
        new = xreplace_unevaluated(expr, values)
    elif sp.core.parameters.global_parameters.evaluate:
        new = expr.xreplace(values)
    else:  # a caller inside evaluate(False) still gets the canonical form it asked for
        with sp.core.parameters.evaluate(True):
            new = expr.xreplace(values)
    vals = eval_expression(new, symbols, X)
    if vals is None:
        return expr, mse0
    mse = float(np.mean((vals - y) ** 2))
    return (new, mse) if mse <= mse0 else (expr, mse0)


def desaturate(expr, symbols, X):
    """Simplify saturated steps: ``tanh(k s)`` with ``|k s| >= 20`` on every sample.

    A jump sampled without points inside it leaves k bounded only from below, and polishing
    drifts it to absurd values (1e8); at ``|k s| >= 20`` tanh equals sign(s) to double precision,
    so k is lowered to ``20 / min|s|`` (same values on the data, a less stiff forward model), and
    ``tanh(c tanh(k s))`` of a saturated step is rewritten ``tanh(c) tanh(k s)`` (equal wherever
    the step is +-1 or 0).
    """
    import sympy as sp

    cols = {s: X[:, i] for i, s in enumerate(symbols)}
    saturated = set()
    rep = {}
    for t in expr.atoms(sp.tanh):
        c, s = t.args[0].as_coeff_Mul()
        if s not in cols or not c.is_Float:
            continue
        a = np.abs(cols[s])
        a = a[a > 0]
        if a.size == 0:
            continue
        k_min = 20.0 / float(a.min())
        if abs(float(c)) >= k_min:
            new = sp.tanh(sp.Float(math.copysign(k_min, float(c)), 15) * s)
            rep[t] = new
            saturated.add(new)
    out = expr.xreplace(rep) if rep else expr
    for _ in range(4):  # unwrap nesting level by level
        rep = {}
        for t in out.atoms(sp.tanh):
            c, inner = t.args[0].as_coeff_Mul()
            if inner in saturated and c.is_Number:
                rep[t] = sp.Float(math.tanh(float(c)), 15) * inner
        if not rep:
            break
        out = out.xreplace(rep)
    return out


def tidy(expr):
    """Drop exact-zero coefficients and show 1.0*b as b where the coefficient is exactly 1."""
    import sympy as sp

    return sp.Add(*[t for t in sp.Add.make_args(expr) if not (t.is_Number and float(t) == 0.0)])


# ------------------------------------------------------------------ Operon

INFIX_FUNCS = ("tanh", "sin", "cos", "exp", "log", "sqrt", "abs", "square")


def parse_infix(text: str, symbols: Sequence) -> Any:
    """Parse an engine's infix model string (variables ``X1..Xd``) into sympy, safely.

    Only numbers, ``X<k>``, known function names and arithmetic are accepted (token check
    before sympy sees the text); ``^`` is power.

    Examples
    --------
    >>> import sympy as sp
    >>> from charcurves.symbolic import parse_infix
    >>> x, v = sp.symbols("x v")
    >>> parse_infix("(0.3 * X2) + ((X1 * X1) * X1)", [x, v])
    0.3*v + x**3
    """
    import re

    import sympy as sp
    from sympy.parsing.sympy_parser import parse_expr, standard_transformations

    from ..curves import first_disallowed_token

    bad = first_disallowed_token(text, lambda name: name in INFIX_FUNCS or re.fullmatch(r"X\d+", name) is not None,
                                 {"+", "-", "*", "/", "^", "(", ")", "**"})
    if bad == "":
        raise ValueError(f"cannot tokenize model {text!r}")
    if bad is not None:
        raise ValueError(f"unexpected token {bad!r} in model {text!r}")
    # The text is parsed with real symbols of the same names (the variables are real): sympy's
    # evaluation then answers "is this argument real?" at once, where for plain symbols it may expand
    # a long argument of tanh and take a gcd of polynomials (seen: 280 s for the 16 members of one
    # front of a very noisy stick-slip record). The result is rebuilt on the caller's symbols without
    # evaluating again (names sort alike, so the canonical order is kept).
    real = {s: sp.Symbol(s.name, real=True) for s in symbols}
    local = {f"X{i + 1}": real[s] for i, s in enumerate(symbols)}
    local.update({"tanh": sp.tanh, "sin": sp.sin, "cos": sp.cos, "exp": sp.exp, "log": sp.log,
                  "sqrt": sp.sqrt, "abs": sp.Abs, "square": lambda a: a**2})
    expr = parse_expr(text.replace("^", "**"), local_dict=local,
                      global_dict={"Integer": sp.Integer, "Float": sp.Float, "Rational": sp.Rational},
                      transformations=standard_transformations, evaluate=True)
    return xreplace_unevaluated(expr, {r: s for s, r in real.items()})
