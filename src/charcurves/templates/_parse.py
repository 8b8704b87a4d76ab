"""Parsing user-written templates: equations linear in unknown univariate curves and scalars.

The text is checked token by token (nothing is evaluated) before sympy parses it; each equation
is split into its known part, its input (terms with a forcing column), the coefficient and
argument of each curve, and the signal of each scalar. See :mod:`._structure` for the model.
"""

from __future__ import annotations

import dataclasses
import re
from typing import Any

import numpy as np

from .._errors import ConfigError, IdentifiabilityError

__all__ = ["check_equation_option", "display", "show", "parse_side", "split_equation", "raw_arguments", "sort_key", "ParsedEquation",
           "FUNCS", "STATE", "DERIV", "FORCE", "CURVE", "SCALAR", "MAX_TEXT", "MAX_EXPONENT"]

FUNCS = ("sin", "cos", "tanh", "exp", "log", "sqrt", "sign", "Abs", "atan", "sinh", "cosh", "tan")
_OPS = {"+", "-", "*", "/", "**", "(", ")", ","}
STATE = re.compile(r"^x\d*$")
DERIV = re.compile(r"^(x\d*)__d([12])$")
FORCE = re.compile(r"^F\d*$")
CURVE = re.compile(r"^f\d+$")
SCALAR = re.compile(r"^a\d+$")
_PRIMES = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)('+)")
MAX_TEXT = 2000


def _name_ok(name: str) -> bool:
    return bool(name in FUNCS or name in ("abs", "pi", "E", "t") or STATE.match(name) or DERIV.match(name)
                or FORCE.match(name) or CURVE.match(name) or SCALAR.match(name))


def display(sym_name: str) -> str:
    """Internal symbol name -> as written (``x1__d1`` -> ``x1'``).

    Examples
    --------
    >>> from charcurves.templates import display
    >>> display("x1__d1"), display("x__d2"), display("F")
    ("x1'", "x''", 'F')
    """
    m = DERIV.match(sym_name)
    return f"{m.group(1)}{chr(39) * int(m.group(2))}" if m else sym_name


def show(expr) -> str:
    """An expression with its internal derivative names as written (``3*x__d2**2`` -> ``3*x''**2``)."""
    text = re.sub(r"\b(\w+?)__d(\d)\b", lambda m: m.group(1) + "'" * int(m.group(2)), str(expr))
    return text if len(text) <= 120 else text[:100] + f"... ({len(text)} characters)"  # messages stay readable


def _short(text: str) -> str:
    """``text`` quoted, cut to 60 characters (a message stays one readable line)."""
    t = text.strip()
    return repr(t) if len(t) <= 60 else f"{t[:57]!r}... ({len(t)} characters)"


def parse_side(text: str, where: str):
    import sympy as sp
    from sympy.core.function import AppliedUndef
    from sympy.parsing.sympy_parser import parse_expr, standard_transformations

    from ..curves import expression_shape_problem, first_disallowed_token

    def primes(m):
        name, marks = m.group(1), m.group(2)
        if not STATE.match(name):
            raise ConfigError(f"{where}: {name}{marks} differentiates {name!r}, which is not a state; "
                              "only states x, x1, x2, ... take primes (x', x'')")
        if len(marks) > 2:
            raise ConfigError(f"{where}: {name}{marks} is a derivative of order {len(marks)}; "
                              "templates use at most x''")
        return f"{name}__d{len(marks)}"

    body = _PRIMES.sub(primes, text.strip()).replace("\n", " ")
    bare = re.search(r"\b(f\d+)\b(?!\s*\()", body)
    if bare:
        raise ConfigError(f"{where}: {bare.group(1)} is a curve and must be applied to an argument, e.g. "
                          f"{bare.group(1)}(x)")
    if "'" in body:
        raise ConfigError(f"{where}: a stray ' in {text.strip()!r}; write derivatives as x' and x''")
    # power towers are refused below by _check_powers, with the template's tighter exponent bound
    bad = first_disallowed_token(body, _name_ok, _OPS, cost_guard=False)
    if bad == "":
        raise ConfigError(f"{where}: cannot read {text.strip()!r}; write e.g. \"x'' + f1(x') + f2(x) = F\"")
    if bad is not None:
        raise ConfigError(
            f"{where}: {display(bad)!r} is not allowed in {text.strip()!r}; use states x, x1, x2 (with ' and ''), "
            "forcings F, F1, F2, time t, curves f1, f2, ..., scalars a1, a2, ..., numbers, + - * / ** and "
            + ", ".join(FUNCS)
        )
    names = set(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", body))
    local: dict[str, Any] = {n: getattr(sp, n) for n in FUNCS}
    local.update({"abs": sp.Abs, "pi": sp.pi, "E": sp.E})
    for n in names:
        if CURVE.match(n):
            local[n] = sp.Function(n)
        elif n not in local:
            local[n] = sp.Symbol(n, real=True)
    gdict = {"Integer": sp.Integer, "Float": sp.Float, "Rational": sp.Rational, "Symbol": sp.Symbol}
    try:
        # unevaluated first: a power tower such as 9**9**9 must be refused before sympy computes it
        _check_powers(parse_expr(body, local_dict=local,
                                 global_dict={**gdict, "Add": sp.Add, "Mul": sp.Mul, "Pow": sp.Pow},
                                 transformations=standard_transformations, evaluate=False), where)
        shape = expression_shape_problem(body)
        if shape:  # before sympy evaluates: products of sums expanded for minutes, nesting recursed (issue 50)
            raise ConfigError(f"{where}: the side {_short(text)} {shape}; write the terms out plainly, e.g. "
                              "\"x'' + a1*x' + f1(x) = F\"")
        expr = parse_expr(body, local_dict=local, global_dict=dict(gdict), transformations=standard_transformations,
                          evaluate=True)
    except ConfigError:
        raise
    except Exception as exc:  # sympy raises many types for bad syntax; none may escape as a traceback
        raise ConfigError(f"{where}: cannot parse {_short(text)} ({type(exc).__name__}); "
                          "write e.g. \"x'' + a1*x' + f1(x) = F\"") from None
    if not isinstance(expr, sp.Expr):
        raise ConfigError(f"{where}: {text.strip()!r} is not an expression")
    if expr.has(sp.zoo, sp.oo, sp.nan, sp.I) or any(
            not (n.is_real and n.is_finite and abs(float(n)) < 1e300) for n in expr.atoms(sp.Number)):
        raise ConfigError(f"{where}: {_short(text)} contains a value that is not a finite real number "
                          "(division by zero, log(0), sqrt of a negative number?); write real, finite terms")
    for n in names:
        if CURVE.match(n) and not any(isinstance(a, AppliedUndef) and a.func.__name__ == n
                                       for a in expr.atoms(AppliedUndef)):
            raise ConfigError(f"{where}: {n} cancels out (or is multiplied by 0); remove it or fix its terms")
    return expr


#: Largest exponent a template may contain (keeps expansion of the equation small)
MAX_EXPONENT = 12


def _check_powers(expr, where: str) -> None:
    """Refuse exponents that are not numbers of modest size (no power towers, no x**x)."""
    import sympy as sp

    if not isinstance(expr, sp.Basic):
        return
    for arg in expr.args:
        _check_powers(arg, where)
    if isinstance(expr, sp.Pow):
        e = expr.exp
        if e.free_symbols:
            raise ConfigError(f"{where}: the exponent {show(e)} depends on the data; exponents must be numbers")
        try:
            val = float(e.evalf(15))
        except (TypeError, ValueError, OverflowError):
            val = float("inf")
        if not np.isfinite(val) or abs(val) > MAX_EXPONENT:
            raise ConfigError(f"{where}: the exponent {show(e)} is too large; exponents are numbers up to "
                              f"{MAX_EXPONENT} in size")


@dataclasses.dataclass(frozen=True)
class ParsedEquation:
    known: Any  # sympy expression of data symbols
    input: Any  # sympy expression containing forcing symbols (enters as -g * input)
    curves: dict  # curve name -> coefficient m (sympy)
    scalars: dict  # scalar name -> signal s (sympy)


def split_equation(lhs, rhs, where: str, arguments: dict) -> ParsedEquation:
    import sympy as sp
    from sympy.core.function import AppliedUndef

    resid = sp.expand(lhs - rhs)
    known, inp = sp.Integer(0), sp.Integer(0)
    curves: dict[str, Any] = {}
    scalars: dict[str, Any] = {}
    for term in sp.Add.make_args(resid):
        apps = [a for a in term.atoms(AppliedUndef)]
        scal = sorted((s for s in term.free_symbols if SCALAR.match(s.name)), key=lambda s: s.name)
        for app in apps:
            for arg in app.args:
                if arg.atoms(AppliedUndef) or any(SCALAR.match(s.name) for s in arg.free_symbols):
                    raise ConfigError(f"{where}: the argument of {app.func.__name__} in {show(term)} contains "
                                      "unknowns; arguments are data signals such as x, x', x1 - x2")
        if apps and scal:
            raise IdentifiabilityError(
                f"{where}: the term {show(term)} multiplies a curve by the scalar {scal[0]}, which the curve can "
                f"absorb (any scale moves between them); drop {scal[0]}"
            )
        if len(apps) > 1:
            raise ConfigError(f"{where}: the term {show(term)} is a product of curves; templates must be linear in "
                              "the unknown curves (each term: coefficient * f(argument))")
        if len(scal) > 1:
            raise ConfigError(f"{where}: the term {show(term)} is a product of scalars; write one scalar per term")
        if apps:
            app = apps[0]
            name = app.func.__name__
            if len(app.args) != 1:
                raise ConfigError(f"{where}: {name} takes {len(app.args)} arguments in {show(term)}; "
                                  "curves are univariate, e.g. f1(x1 - x2)")
            arg = app.args[0]
            if arg.atoms(AppliedUndef) or any(SCALAR.match(s.name) for s in arg.free_symbols):
                raise ConfigError(f"{where}: the argument of {name} in {show(term)} contains unknowns; "
                                  "arguments are data signals such as x, x', x1 - x2")
            if not arg.free_symbols:
                raise ConfigError(f"{where}: {name}({show(arg)}) has a constant argument; give it a data signal")
            coef = sp.simplify(term / app)
            if coef.has(app) or coef.atoms(AppliedUndef):
                raise ConfigError(f"{where}: {show(term)} is not linear in {name}; templates must be linear in "
                                  "the unknown curves (each term: coefficient * f(argument))")
            if name in arguments and sp.simplify(arguments[name] - arg) != 0:
                raise ConfigError(f"{name} is used with two arguments ({show(arguments[name])} and {show(arg)}); "
                                  "a curve has one argument: name the other one differently")
            arguments[name] = arg
            curves[name] = curves.get(name, 0) + coef
        elif scal:
            s = scal[0]
            sig = sp.simplify(term / s)
            if sig.has(s):
                raise ConfigError(f"{where}: {show(term)} is not linear in the scalar {s}")
            scalars[s.name] = scalars.get(s.name, 0) + sig
        elif any(FORCE.match(s.name) for s in term.free_symbols):
            inp = inp - term
        else:
            known = known + term
    curves = {k: v for k, v in curves.items() if sp.simplify(v) != 0}
    scalars = {k: v for k, v in scalars.items() if sp.simplify(v) != 0}
    return ParsedEquation(known, inp, curves, scalars)


def raw_arguments(text: str) -> dict[str, str]:
    """Each curve's argument as first written (``x2 - x1``, not sympy's ``-x1 + x2``)."""
    out: dict[str, str] = {}
    for m in re.finditer(r"\b(f\d+)\s*\(", text):
        depth, start = 1, m.end()
        for k in range(start, len(text)):
            depth += {"(": 1, ")": -1}.get(text[k], 0)
            if depth == 0:
                out.setdefault(m.group(1), " ".join(text[start:k].split()))
                break
    return out


def sort_key(name: str):
    return (name[0], int(name[1:]))


def check_equation_option(equation) -> None:
    """Refuse an empty ``equation`` option: it must not fall back silently to the separable family.

    Examples
    --------
    >>> from charcurves.templates import check_equation_option
    >>> check_equation_option(None)
    >>> try:
    ...     check_equation_option("  ")
    ... except ValueError as exc:
    ...     print(str(exc)[:22])
    the equation is empty;
    """
    if equation is not None and not str(equation).strip():
        raise ConfigError("the equation is empty; write a template such as \"x'' + f1(x') + f2(x) = F\" "
                          "or leave out --equation (equation=None) for the separable family")
