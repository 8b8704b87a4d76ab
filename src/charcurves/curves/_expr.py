"""Safe parsing of closed-form expressions read from users, files and SR engines.

sympy's parser evaluates Python code, so no text reaches it before :func:`first_disallowed_token`
has checked every token against an allow-list, and :func:`expression_cost_problem` has refused
texts whose exact evaluation could hang (``9**9**9``). Both checks only tokenize/parse the text
with the standard library; nothing is executed.
"""

from __future__ import annotations

import re

__all__ = ["ALLOWED_FUNCS", "first_disallowed_token", "expression_cost_problem", "expression_shape_problem",
           "parse_basis_function", "monomial_power"]

ALLOWED_FUNCS = ("sin", "cos", "tanh", "exp", "log", "sqrt", "sign", "Abs", "atan", "sinh", "cosh", "tan")


_ALLOWED_NAMES = set(ALLOWED_FUNCS) | {"z", "abs", "pi", "E"}
_ALLOWED_OPS = {"+", "-", "*", "/", "**", "(", ")", ","}


def first_disallowed_token(text: str, name_ok, ops, *, cost_guard: bool = True) -> str | None:
    """The first token of ``text`` that is not a number, an allowed name (``name_ok(name)``) or an
    operator in ``ops``; "" when the text cannot be tokenized; None when every token is allowed.

    This is the safety check run before sympy parses text from users, files or engines (sympy's
    parser evaluates Python code, so nothing else may reach it). With ``cost_guard`` (the default)
    a text made only of allowed tokens is also refused with a ConfigError when sympy's exact
    arithmetic on it could hang (``9**9**9``; see ``expression_cost_problem``).

    Examples
    --------
    >>> from charcurves.curves import first_disallowed_token
    >>> ok = {"z", "tanh"}.__contains__
    >>> first_disallowed_token("tanh(50*z)", ok, {"*", "(", ")"}), first_disallowed_token("z.real", ok, {"*"})
    (None, '.')
    """
    import io
    import tokenize

    try:
        tokens = list(tokenize.generate_tokens(io.StringIO(text).readline))
    except (tokenize.TokenError, IndentationError, SyntaxError):
        return ""
    for tok in tokens:
        if tok.type in (tokenize.NEWLINE, tokenize.NL, tokenize.ENDMARKER, tokenize.NUMBER):
            continue
        if tok.type == tokenize.NAME and name_ok(tok.string):
            continue
        if tok.type == tokenize.OP and tok.string in ops:
            continue
        return tok.string
    if cost_guard:
        from .._errors import ConfigError

        problem = expression_cost_problem(text)
        if problem:
            raise ConfigError(f"{text.strip()[:60]!r} {problem}; write a plain closed form with small exponents "
                              "such as 'z**3' or 'tanh(50*z)'")
    return None


def _check_tokens(text: str) -> None:
    """Allow only numbers, the symbol z, known function names and arithmetic: nothing is executed."""
    from .._errors import ConfigError

    bad = first_disallowed_token(text, _ALLOWED_NAMES.__contains__, _ALLOWED_OPS)
    if bad == "":
        raise ConfigError(f"cannot parse {text!r}; write an expression of z such as 'z**3'")
    if bad is not None:
        raise ConfigError(
            f"{text!r} is not a plain expression of z ({bad!r} is not allowed); use z, numbers, "
            f"+ - * / ** and {', '.join(ALLOWED_FUNCS)}"
        )


def parse_basis_function(text: str):
    """Parse a closed form in ``z`` safely: the text is checked token by token before sympy sees it.

    Examples
    --------
    >>> from charcurves.curves import parse_basis_function
    >>> parse_basis_function("0.8*tanh(50*z) + z**3")
    z**3 + 0.8*tanh(50*z)
    >>> try:
    ...     parse_basis_function("__import__('os')")
    ... except ValueError as exc:
    ...     print(str(exc)[:40])
    "__import__('os')" is not a plain expres
    """
    import sympy as sp
    from sympy.parsing.sympy_parser import parse_expr, standard_transformations

    from .._errors import ConfigError

    if not isinstance(text, str) or not text.strip():
        raise ConfigError(f"empty basis function {text!r}; write e.g. 'z**3' or 'tanh(50*z)'")
    _check_tokens(text)
    z = sp.Symbol("z")
    local = {"z": z, **{name: getattr(sp, name) for name in ALLOWED_FUNCS}, "abs": sp.Abs, "pi": sp.pi, "E": sp.E}
    try:
        expr = parse_expr(text, local_dict=local, global_dict={"Integer": sp.Integer, "Float": sp.Float,
                                                                "Rational": sp.Rational, "Symbol": sp.Symbol},
                          transformations=standard_transformations, evaluate=True)
    except Exception as exc:  # sympy raises many types for bad syntax
        shown = repr(text) if len(text) <= 60 else f"{text[:57]!r}... ({len(text)} characters)"
        raise ConfigError(f"cannot parse basis function {shown} ({type(exc).__name__}); "
                          "write an expression of z such as 'z**3'") from None
    if not isinstance(expr, sp.Expr):
        raise ConfigError(f"basis function {text!r} is not an expression of z")
    if expr.has(sp.I, sp.zoo, sp.oo, sp.nan):  # sqrt(-1), 1/0: no real, finite column
        raise ConfigError(f"basis function {text[:60]!r} has a value that is not a finite real number (division by "
                          "zero, sqrt or log of a negative number?); write a real closed form such as 'z**3'")
    extra = expr.free_symbols - {z}
    if extra:
        raise ConfigError(
            f"basis function {text!r} uses {sorted(map(str, extra))}; write it in the curve's argument z only"
        )
    return expr



#: bounds that keep sympy's exact arithmetic cheap on expressions read from files
_MAX_EXPONENT_LITERAL = 100
_MAX_EXPONENT_LITERALS = 2
_MAX_POWER_GROWTH = 1e5  # product of the exponents of powers nested in one another's bases
_MAX_LITERAL_DIGITS = 30
_MAX_EXPRESSION_CHARS = 2000


def expression_cost_problem(text: str) -> str | None:
    """Why parsing ``text`` could hang (e.g. ``9**9**9``, which sympy evaluates exactly), or None.

    The text is only parsed by Python's ``ast`` (nothing is evaluated): powers may not nest
    in their exponent, which may hold at most two numbers of magnitude <= 100; powers nested in
    bases may multiply their exponents up to 1e5; numbers have at most 30 digits. Fitted curves
    stay far inside these bounds.

    Examples
    --------
    >>> from charcurves.curves import expression_cost_problem
    >>> expression_cost_problem("z**3 - z") is None
    True
    >>> expression_cost_problem("9**9**9")
    'nests a power in an exponent (exact evaluation could take forever)'
    """
    import ast

    if len(text) > _MAX_EXPRESSION_CHARS:
        return f"is longer than {_MAX_EXPRESSION_CHARS} characters"
    try:
        tree = ast.parse(text.replace("^", "**"), mode="eval")
    except (SyntaxError, ValueError, RecursionError, MemoryError):
        return None  # not Python syntax: the token check of the curve parser refuses it with its own message
    shape = _shape_problem(tree)
    if shape:
        return shape
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float, complex)):
            digits = sum(ch.isdigit() for ch in repr(node.value))
            if digits > _MAX_LITERAL_DIGITS:
                return f"holds a number with more than {_MAX_LITERAL_DIGITS} digits"
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Pow):
            inner = list(ast.walk(node.right))
            if any(isinstance(n, ast.BinOp) and isinstance(n.op, ast.Pow) for n in inner):
                return "nests a power in an exponent (exact evaluation could take forever)"
            numbers = [n.value for n in inner if isinstance(n, ast.Constant) and isinstance(n.value, (int, float))]
            if len(numbers) > _MAX_EXPONENT_LITERALS or any(abs(v) > _MAX_EXPONENT_LITERAL for v in numbers):
                return "raises to an exponent too large to evaluate exactly"
    if _power_growth(tree.body) > _MAX_POWER_GROWTH:
        return "nests powers whose exponents multiply beyond what can be evaluated exactly"
    return None


#: bounds on the shape of an expression (issue 50: deep nesting ended in RecursionError, a product of
#: sums in an equation expanded for minutes): nesting of different operations and calls, AST nodes,
#: and the number of terms the fully expanded expression can have before like terms are collected
MAX_NESTING = 30
MAX_NODES = 1500
MAX_EXPANDED_TERMS = 10_000


def _post_order(tree):
    """The nodes of ``tree`` children first, without recursion (deep trees stay safe)."""
    import ast

    out, stack = [], [(tree, False)]
    while stack:
        node, done = stack.pop()
        if done:
            out.append(node)
            continue
        stack.append((node, True))
        stack.extend((child, False) for child in ast.iter_child_nodes(node))
    return out


def _op_kind(node) -> str | None:
    import ast

    if isinstance(node, ast.BinOp):
        return "add" if isinstance(node.op, (ast.Add, ast.Sub)) else "mul" if isinstance(node.op, (ast.Mult, ast.Div)) \
            else "pow"
    if isinstance(node, ast.UnaryOp):
        return "unary"
    return None


def _shape_problem(tree) -> str | None:
    import ast

    _MARKERS = (ast.expr_context, ast.operator, ast.unaryop, ast.cmpop, ast.boolop)  # not parts of their own

    nodes = [n for n in _post_order(tree) if not isinstance(n, _MARKERS)]
    if len(nodes) > MAX_NODES:
        return f"has {len(nodes)} parts, more than {MAX_NODES}"
    depth: dict[int, int] = {}
    terms: dict[int, float] = {}
    worst = 1.0
    for node in nodes:
        kids = [k for k in ast.iter_child_nodes(node) if not isinstance(k, _MARKERS)]
        kind = _op_kind(node)
        # a chain of the same operation (a + b + c, a*b*c) is one level, as sympy flattens it
        depth[id(node)] = max([depth[id(k)] + (0 if kind is not None and _op_kind(k) == kind and kind != "pow"
                                                else 1) for k in kids], default=0)
        if isinstance(node, ast.BinOp):
            a, b = terms[id(node.left)], terms[id(node.right)]
            if isinstance(node.op, (ast.Add, ast.Sub)):
                n = a + b
            elif isinstance(node.op, ast.Mult):
                n = a * b
            elif isinstance(node.op, ast.Pow) and isinstance(node.right, ast.Constant) \
                    and isinstance(node.right.value, int) and 0 <= node.right.value <= 1000:
                n = a ** node.right.value if a < 1e6 else float("inf")
            else:
                n = a
        elif isinstance(node, (ast.UnaryOp, ast.Expression)):
            n = terms[id(kids[0])] if kids else 1.0
        else:
            n = 1.0  # a number, a name, a call (its arguments are counted on their own)
        n = min(n, 1e300)
        terms[id(node)] = n
        worst = max(worst, n)
    top = depth[id(tree.body)] if isinstance(tree, ast.Expression) else depth[id(tree)]
    if top > MAX_NESTING:
        return f"nests operations {top} deep, more than {MAX_NESTING}"
    if worst > MAX_EXPANDED_TERMS:
        return f"expands to more than {MAX_EXPANDED_TERMS} terms (about {worst:.3g})"
    return None


def expression_shape_problem(text: str) -> str | None:
    """Why ``text`` is too large to expand and evaluate safely, or None: more than
    :data:`MAX_NESTING` levels of nested operations, :data:`MAX_NODES` parts, or a product of sums
    whose expansion has more than :data:`MAX_EXPANDED_TERMS` terms. Only parsed by ``ast``.

    Examples
    --------
    >>> from charcurves.curves import expression_shape_problem
    >>> expression_shape_problem("(z + 1)**3 * tanh(50*z)") is None
    True
    >>> expression_shape_problem("*".join(["(z + 1)"] * 20))
    'expands to more than 10000 terms (about 1.05e+06)'
    """
    import ast

    try:
        tree = ast.parse(text.replace("^", "**"), mode="eval")
    except (SyntaxError, ValueError, RecursionError, MemoryError):
        return None  # not Python syntax: the caller's parser refuses it with its own message
    return _shape_problem(tree)


def _power_growth(tree) -> float:
    """Largest product of exponent sizes along a chain of powers nested in bases, e.g. ((a**3)**4) -> 12."""
    import ast

    growth: dict[int, float] = {}
    for node in _post_order(tree):
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Pow):
            size = 1.0
            for n in ast.walk(node.right):
                if isinstance(n, ast.Constant) and isinstance(n.value, (int, float)):
                    size = min(size * max(1.0, abs(float(n.value))), 1e300)
            growth[id(node)] = min(size * growth[id(node.left)], 1e300)
        else:
            growth[id(node)] = max([growth[id(c)] for c in ast.iter_child_nodes(node)], default=1.0)
    return growth[id(tree)]


def monomial_power(text: str) -> int | None:
    """``k`` for ``"1"``, ``"z"`` or ``"z**k"`` (spaces allowed), else None."""
    t = text.replace(" ", "")
    if t == "1":
        return 0
    if t == "z":
        return 1
    m = re.fullmatch(r"z\*\*(\d+)", t)
    return int(m.group(1)) if m else None
