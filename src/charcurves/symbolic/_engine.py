"""Symbolic-regression engines behind one interface, and the model selection they share.

An engine runs a search (Operon by default, PySR optionally) and hands back candidate
expressions. Everything after the search is engine independent and lives here:

1. each candidate is converted to sympy, expanded and split into additive terms
   ``c_j * b_j(vars)``;
2. every candidate is *enriched* with its nested sub-models from a greedy backward elimination
   of terms (the outer coefficients refitted by linear least squares on all points), so that a
   near-correct expression carrying a negligible extra term (Operon always adds an intercept)
   also offers its clean sub-expression to the selection;
3. the Pareto front of (complexity, MSE) is taken over all candidates and a parsimony criterion
   picks one (:data:`SELECTION_CRITERIA`);
4. every numeric constant of the pick (also those inside ``tanh``) is polished by
   ``scipy.optimize.least_squares`` on all points, which makes the coefficients precise (the
   search itself works in single precision on a subsample); constants inside functions are
   also polished for every candidate before the selection (an unpolished ``tanh(k z)`` with a
   slightly wrong k can make a nested variant look better); saturated steps are simplified
   (see ``_desaturate``).

Notes
-----
Measurements behind the defaults (2-core shared machine, one thread, Operon 0.6 via pyoperon,
default settings: 1 population of 300, 40 generations, max size 20, search on 400 points).

*Post-SR* (samples of learned curves). NN-CC+sym fits of Duffing and stick-slip at 40/20/10 dB,
3 noise seeds each, both curves, 2 SR seeds: 72 distillations per criterion, done for networks
of two training presets (tanh MLP; the current default, softplus with Bayesian weight decay).
Recovered = exactly the true terms (Duffing f1 = a z, f2 = b z + c z^3; stick-slip
f1 = c z + muN tanh(k z), f2 = k z), no constant or other term:

=====================================  ======  ==========  ======  =====
criterion                              knee    parsimony   best    bic
=====================================  ======  ==========  ======  =====
recovered of 72, tanh networks         72      72          11      0
recovered of 72, current networks      71      42          24      18
stick-slip f1 by whole-curve SR with
tanh, of 18: tanh / current networks   6 / 17  11 / 14     0 / 13  0 / 13
=====================================  ======  ==========  ======  =====

"best" (PySR's default), "bic" and the fixed-rate "parsimony" keep terms that follow the
network's wiggles (x^5, x^7, 1e-4 x^3...); "knee" stops at the structure (its one miss is a
10 dB network whose curve is itself off, RMSE 0.03). The last row is the friction curve without
the by-parts treatment of :mod:`charcurves.symbolic._distill`: on tanh networks SR imitates the
network's tanh units with nested tanh. Time per curve: mean 1.2-1.8 s, max 3 s.

*SR / SR-CC on records* (20 dB, 5 noise seeds, true structure in f1 and f2 and no mixed term):

==========================  ======  ======
fit                         bic     knee
==========================  ======  ======
Duffing SR                  5/5     5/5
Duffing SR-CC               5/5     5/5
stick-slip SR               5/5     0/5
stick-slip SR-CC            5/5     0/5
==========================  ======  ======

"knee" drops the viscous term of friction (it improves the MSE by a factor 1.7 only, under the
noise) and "parsimony" (a fixed exchange rate) returns a constant on noisy records. Plain BIC
(minimum) admitted a spurious x^5 on one Duffing record (ΔBIC = 1.5), hence the 10-unit margin.
Hence ``selection="auto"``: "knee" for post-SR, "bic" for SR and SR-CC. Times: SR 2-3 s
(max 6 s), SR-CC 4 s (Duffing) and 12 s (stick-slip; max 21 s).
"""

from __future__ import annotations

import abc
import dataclasses
import math
import time
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np

from .._errors import ConfigError

__all__ = [
    "SymbolicRegressionEngine",
    "OperonEngine",
    "PySREngine",
    "SRResult",
    "FrontEntry",
    "make_engine",
    "select_model",
    "polish_constants",
    "expression_complexity",
    "OPERATORS",
    "POLY_OPERATORS",
    "TANH_OPERATORS",
    "SELECTION_CRITERIA",
    "DEFAULT_SR_OPTIONS",
    "SR_OPTION_KEYS",
]

#: Operator names accepted by ``sr_options["operators"]`` (binary: add sub mul div pow; the rest unary).
OPERATORS = ("add", "sub", "mul", "div", "pow", "square", "tanh", "sin", "cos", "exp", "log", "sqrt", "abs")
_BINARY = ("add", "sub", "mul", "div", "pow")
#: The paper's operator sets: binary + - * (no division: it can create singularities in forward
#: simulations), plus tanh where a jump (dry friction) must be expressed.
POLY_OPERATORS = ("add", "sub", "mul")
TANH_OPERATORS = ("add", "sub", "mul", "tanh")

#: Model-selection criteria on the Pareto front; see :func:`select_model`.
SELECTION_CRITERIA = ("auto", "knee", "bic", "parsimony", "best")
#: What "auto" means per kind of fit (measured, the Notes of this module): samples of a
#: learned curve carry small *systematic* error, so an information criterion that assumes
#: independent noise keeps adding terms that follow the curve's wiggles, while "knee" stops at
#: the structure; measured records carry independent noise, where BIC is right and "knee" can
#: stop before a small true term (the viscous part of friction under 20 dB noise).
AUTO_SELECTION = {"curve": "knee", "data": "bic"}
#: "bic": the simplest model within this BIC difference of the minimum.
BIC_MARGIN = 10.0
#: "parsimony": a fixed exchange rate, one unit of complexity must lower the MSE by exp(0.5).
PARSIMONY = 0.5

#: Defaults of ``sr_options``. Chosen by measurement (the Notes of this module): with the
#: search on a 400-point subsample, one Operon population of 300 evolved for 40 generations
#: recovers the true forms of the benchmark curves in ~1-2 s per curve on one core.
DEFAULT_SR_OPTIONS: dict[str, Any] = {
    "engine": "operon",
    "generations": 40,
    "populations": 1,
    "population_size": 300,
    "max_size": 20,
    "operators": "auto",
    "selection": "auto",
}
SR_OPTION_KEYS = tuple(DEFAULT_SR_OPTIONS)
_ENGINES = ("operon", "pysr")

#: Relative MSE floor (times var(y)): differences below RMSE = 1e-6 std(y) are round-off, not
#: structure; without the floor, models at the numerical floor of clean data would be ranked
#: by noise in the 15th digit.
_REL_MSE_FLOOR = 1e-12


class FrontEntry(NamedTuple):
    """One Pareto-optimal model: complexity, MSE on all points, the sympy expression."""

    complexity: int
    mse: float
    expression: Any


@dataclasses.dataclass
class SRResult:
    """What an engine returns.

    Attributes
    ----------
    expression : sympy.Expr
        The selected model (constants polished), in the given variable names as sympy Symbols.
    mse : float
        Its mean squared error on all given points.
    complexity : int
        Its complexity (:func:`expression_complexity`).
    front : list of FrontEntry
        The Pareto front (complexity, MSE, expression) the selection chose from, simplest first.
    seconds : float
        Wall time of the whole fit (search + selection + polishing).
    search_seconds : float
        Wall time of the engine's search alone.
    criterion : str
        The selection criterion used.
    engine : str
    operators : tuple of str
    info : dict
        Engine details (generations run, evaluations, candidates considered...).
    """

    expression: Any
    mse: float
    complexity: int
    front: list[FrontEntry]
    seconds: float
    search_seconds: float
    criterion: str
    engine: str
    operators: tuple[str, ...]
    info: dict = dataclasses.field(default_factory=dict)

    def summary(self) -> dict[str, Any]:
        """JSON-able digest (for a FittedModel's ``info``)."""
        return {
            "expression": str(self.expression),
            "mse": float(self.mse),
            "complexity": int(self.complexity),
            "seconds": float(self.seconds),
            "search_seconds": float(self.search_seconds),
            "criterion": self.criterion,
            "engine": self.engine,
            "operators": list(self.operators),
            "front": [[int(c), float(m), str(e)] for c, m, e in self.front],
        }


# ---------------------------------------------------------------------------------------------
# expression utilities
# ---------------------------------------------------------------------------------------------
def expression_complexity(expr) -> int:
    """Size of an expression tree, counted as a search without ``pow`` would build it.

    Every symbol, constant and operator counts 1; ``b**n`` for an integer n >= 2 counts as the
    n-fold product (``z**3`` = z*z*z = 5), so a cubic is not mistaken for something as simple as
    a linear term.
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


def _numeric_atoms(expr) -> list:
    """The Floats of ``expr`` (the fitted constants; integer exponents are structure)."""
    import sympy as sp

    return sorted(expr.atoms(sp.Float), key=lambda f: sp.default_sort_key(f))


def _n_constants(expr) -> int:
    import sympy as sp

    return len([a for a in sp.preorder_traversal(expr) if isinstance(a, sp.Float)])


def _canonical(expr):
    """Expand products and merge constants (``(a z)(b z) + c`` -> ``ab z**2 + c``).

    ``exp``/``log`` rules are off: they would only trade one form for another.
    """
    import sympy as sp

    try:
        out = sp.expand(expr, power_exp=False, power_base=False, log=False)
    except Exception:  # pragma: no cover - sympy failures on exotic trees
        out = expr
    # sympy keeps exact 1.0 factors as Floats: fold Float(1)*b into b only via the term split
    return out


def _split_terms(expr):
    """``sum c_j b_j`` -> [(c_j, b_j)] with numeric c_j (b_j = 1 for the constant)."""
    import sympy as sp

    terms = sp.Add.make_args(expr)
    merged: dict[Any, float] = {}
    for t in terms:
        c, rest = t.as_coeff_Mul()
        if not c.is_Number:
            c, rest = sp.Integer(1), t
        merged[rest] = merged.get(rest, 0.0) + float(c)
    return [(c, b) for b, c in merged.items()]


def _lambdify(expr, symbols):
    import sympy as sp

    return sp.lambdify(symbols, expr, modules="numpy")


def _eval(expr, symbols, X) -> np.ndarray | None:
    """Values of ``expr`` on the columns of X; None when not finite."""
    n = X.shape[0]
    if not (expr.free_symbols & set(symbols)):
        try:
            val = float(expr)
        except (TypeError, ValueError):
            return None
        return np.full(n, val) if math.isfinite(val) else None
    f = _lambdify(expr, symbols)
    with np.errstate(all="ignore"):
        try:
            out = np.asarray(f(*[X[:, i] for i in range(X.shape[1])]), dtype=float)
        except (TypeError, ValueError, ZeroDivisionError, OverflowError, AttributeError):
            return None
    out = np.broadcast_to(out, (n,)).astype(float)
    if not np.all(np.isfinite(out)):
        return None
    return out


def polish_constants(expr, symbols, X, y, *, max_nfev: int = 200):
    """Least-squares refinement of every numeric constant of ``expr`` on (X, y).

    Parameters
    ----------
    expr : sympy.Expr
    symbols : sequence of sympy.Symbol
        The variables, in the column order of X.
    X : (N, d) array
    y : (N,) array

    Returns
    -------
    (sympy.Expr, float)
        The polished expression and its MSE; the input unchanged when polishing does not lower
        the MSE (or fails).
    """
    import sympy as sp
    from scipy.optimize import least_squares

    y = np.asarray(y, dtype=float)
    base = _eval(expr, symbols, X)
    mse0 = float(np.mean((base - y) ** 2)) if base is not None else math.inf
    consts = _numeric_atoms(expr)
    if not consts:
        return expr, mse0
    params = sp.symbols(f"__c0:{len(consts)}")
    template = expr.xreplace(dict(zip(consts, params)))
    f = sp.lambdify(list(symbols) + list(params), template, modules="numpy")
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
    new = template.xreplace({p: sp.Float(v, 15) for p, v in zip(params, sol.x)})
    vals = _eval(new, symbols, X)
    if vals is None:
        return expr, mse0
    mse = float(np.mean((vals - y) ** 2))
    return (new, mse) if mse <= mse0 else (expr, mse0)


@dataclasses.dataclass
class _Candidate:
    expression: Any
    mse: float
    complexity: int
    n_constants: int
    key: Any


def _candidates_from(exprs, symbols, X, y) -> list[_Candidate]:
    """Canonical forms of the searched expressions plus their backward-elimination sub-models."""
    import sympy as sp

    pool: dict[Any, _Candidate] = {}
    basis_cache: dict[Any, np.ndarray | None] = {}

    def add(expr, mse, key):
        if not math.isfinite(mse):
            return
        old = pool.get(key)
        if old is None or mse < old.mse:
            pool[key] = _Candidate(expr, mse, expression_complexity(expr), _n_constants(expr), key)

    for raw in exprs:
        expr = _canonical(raw)
        terms = _split_terms(expr)
        bases = []
        for c, b in terms:
            if b not in basis_cache:
                basis_cache[b] = _eval(b, symbols, X)
            if basis_cache[b] is None:
                bases = None
                break
            bases.append(b)
        if not bases:
            continue
        B = np.column_stack([basis_cache[b] for b in bases])
        active = list(range(len(bases)))
        # greedy backward elimination: the outer coefficients are linear, so each sub-model is a
        # least-squares solve on fixed columns (microseconds), not a new search
        while active:
            A = B[:, active]
            coef, *_ = np.linalg.lstsq(A, y, rcond=None)
            mse = float(np.mean((A @ coef - y) ** 2))
            sub = sp.Add(*[sp.Float(float(c), 15) * bases[j] if bases[j] != 1 else sp.Float(float(c), 15)
                           for c, j in zip(coef, active)])
            add(sub, mse, frozenset(bases[j] for j in active))
            if len(active) == 1:
                break
            best_j, best_mse = None, math.inf
            for j in active:
                rest = [k for k in active if k != j]
                A2 = B[:, rest]
                c2, *_ = np.linalg.lstsq(A2, y, rcond=None)
                m2 = float(np.mean((A2 @ c2 - y) ** 2))
                if m2 < best_mse:
                    best_j, best_mse = j, m2
            active.remove(best_j)
    out = list(pool.values())
    # constants inside functions (tanh(k z)) come from the single-precision search on a subsample;
    # unpolished, a slightly wrong k can make a nested variant look better than the plain form
    for c in out:
        if _has_inner_constants(c.expression):
            expr, mse = polish_constants(c.expression, symbols, X, y, max_nfev=60)
            if mse < c.mse:
                c.expression, c.mse = expr, mse
    return out


def _has_inner_constants(expr) -> bool:
    import sympy as sp

    return any(isinstance(a, sp.Float) for f in expr.atoms(sp.Function) for a in sp.preorder_traversal(f))


def _pareto(cands: list[_Candidate]) -> list[_Candidate]:
    """Simplest first, each strictly more accurate than every simpler one."""
    out: list[_Candidate] = []
    for c in sorted(cands, key=lambda c: (c.complexity, c.mse)):
        if not out or c.mse < out[-1].mse:
            if out and c.complexity == out[-1].complexity:
                continue
            out.append(c)
    return out


def select_model(front: Sequence, criterion: str, n: int, var_y: float, context: str = "data") -> int:
    """Index of the chosen model on a Pareto front (simplest first, MSE strictly decreasing).

    Parameters
    ----------
    front : sequence
        Entries with ``complexity``, ``mse`` and ``expression`` (or ``n_constants``).
    criterion : str
        One of :data:`SELECTION_CRITERIA`.
    n : int
        Number of points the MSEs were computed on.
    var_y : float
        Variance of the target (sets the round-off floor).
    context : {"data", "curve"}
        What was fitted, for ``criterion="auto"`` (:data:`AUTO_SELECTION`).

    Notes
    -----
    MSE below ``1e-12 var(y)`` counts as that floor: round-off is not structure.

    ``"auto"`` (default)
        "knee" for samples of a learned curve (post-SR), "bic" for measured records (SR, SR-CC).
    ``"knee"``
        The largest relative MSE drop per added complexity,
        ``-Δlog(MSE) / Δcomplexity`` between neighbours on the front (PySR's "score"): the
        step after which adding terms buys little.
    ``"parsimony"``
        Minimise ``log(MSE) + 0.5 complexity`` (a fixed exchange rate): fine on samples of a
        learned curve, but on noisy data the total gain of the true model can be smaller than
        its price and a constant wins.
    ``"best"``
        PySR's default: the highest score among models whose MSE is within 1.5x of the most
        accurate one.
    ``"bic"``
        ``N log(MSE) + k log(N)`` with k the number of numeric constants; the pick is the
        simplest model whose BIC is within 10 of the minimum (a difference above 10 is "very
        strong" evidence, Kass & Raftery 1995): the search tries many extra terms, and the best
        of them fits the noise by chance more often than one pre-chosen term would.
        Appropriate for independent noise; on samples of a smooth learned curve (systematic,
        correlated error) it keeps adding terms.
    """
    if criterion not in SELECTION_CRITERIA:
        raise ConfigError(f"unknown selection criterion {criterion!r}; choose one of {', '.join(SELECTION_CRITERIA)}")
    if criterion == "auto":
        if context not in AUTO_SELECTION:
            raise ConfigError(f"context must be one of {', '.join(AUTO_SELECTION)}, got {context!r}")
        criterion = AUTO_SELECTION[context]
    if len(front) == 1:
        return 0
    floor = max(_REL_MSE_FLOOR * float(var_y), 1e-300)
    mse = np.maximum(np.array([f.mse for f in front], dtype=float), floor)
    cx = np.array([f.complexity for f in front], dtype=float)
    if criterion == "parsimony":
        return int(np.argmin(np.log(mse) + PARSIMONY * cx))
    if criterion == "bic":
        k = np.array([f.n_constants if hasattr(f, "n_constants") else _n_constants(f.expression)
                      for f in front], dtype=float)
        bic = n * np.log(mse) + k * np.log(n)
        return int(np.flatnonzero(bic <= bic.min() + BIC_MARGIN)[0])
    score = np.zeros(len(front))
    score[1:] = -np.diff(np.log(mse)) / np.maximum(np.diff(cx), 1.0)
    if criterion == "best":
        score = np.where(mse <= 1.5 * mse.min(), score, -np.inf)
    return int(np.argmax(score))


# ---------------------------------------------------------------------------------------------
# engines
# ---------------------------------------------------------------------------------------------
def _check_operators(ops) -> tuple[str, ...]:
    if isinstance(ops, str):
        ops = [o.strip() for o in ops.replace(";", ",").split(",") if o.strip()]
    try:
        ops = tuple(str(o).strip().lower() for o in ops)
    except TypeError:
        raise ConfigError(f"operators must be 'auto' or a list of names like ('add', 'sub', 'mul', 'tanh'), got {ops!r}") from None
    bad = [o for o in ops if o not in OPERATORS]
    if bad:
        raise ConfigError(f"unknown operator(s) {bad}; choose from {', '.join(OPERATORS)}")
    if not any(o in _BINARY for o in ops):
        raise ConfigError(f"operators {ops} have no binary operator; include at least 'add'")
    return ops


class SymbolicRegressionEngine(abc.ABC):
    """A symbolic-regression search plus the shared parsimony selection and constant polishing.

    Parameters
    ----------
    generations : int
        Search iterations (Operon generations; PySR ``niterations``).
    populations : int
        Independent populations (PySR islands; Operon: independent restarts with derived seeds
        whose fronts are merged).
    population_size : int
        Individuals per population.
    max_size : int
        Largest expression size (Operon ``max_length``; PySR ``maxsize``).
    operators : sequence of str
        Default operator set (:data:`OPERATORS`); ``fit`` can override it per call.
    selection : str
        Criterion on the Pareto front (:func:`select_model`); "auto" depends on the fit's
        ``context``.
    max_points : int
        The search sees at most this many evenly spaced points (selection and polishing use all).
    """

    name = "abstract"

    def __init__(self, *, generations: int = DEFAULT_SR_OPTIONS["generations"],
                 populations: int = DEFAULT_SR_OPTIONS["populations"],
                 population_size: int = DEFAULT_SR_OPTIONS["population_size"],
                 max_size: int = DEFAULT_SR_OPTIONS["max_size"], operators: Sequence[str] = POLY_OPERATORS,
                 selection: str = DEFAULT_SR_OPTIONS["selection"], max_points: int = 400):
        for key, val, lo in (("generations", generations, 1), ("populations", populations, 1),
                             ("population_size", population_size, 2), ("max_size", max_size, 3),
                             ("max_points", max_points, 10)):
            if isinstance(val, bool) or not isinstance(val, (int, np.integer)) or int(val) < lo:
                raise ConfigError(f"sr option {key} must be an integer >= {lo}, got {val!r}")
        if selection not in SELECTION_CRITERIA:
            raise ConfigError(f"unknown selection criterion {selection!r}; choose one of {', '.join(SELECTION_CRITERIA)}")
        self.generations = int(generations)
        self.populations = int(populations)
        self.population_size = int(population_size)
        self.max_size = int(max_size)
        self.operators = _check_operators(operators)
        self.selection = selection
        self.max_points = int(max_points)

    def __repr__(self) -> str:
        return (f"{type(self).__name__}(generations={self.generations}, populations={self.populations}, "
                f"population_size={self.population_size}, max_size={self.max_size}, "
                f"operators={self.operators}, selection={self.selection!r})")

    @abc.abstractmethod
    def _search(self, X: np.ndarray, y: np.ndarray, symbols: list, operators: tuple[str, ...],
                random_state: int) -> tuple[list, dict]:
        """Run the search; return candidate sympy expressions (in ``symbols``) and details."""

    def fit(self, X, y, names: Sequence[str], *, random_state: int = 0,
            operators: Sequence[str] | None = None, context: str = "data") -> SRResult:
        """Search y ≈ f(X) and pick one expression.

        Parameters
        ----------
        X : (N, d) array
        y : (N,) array
        names : list of str
            Variable names; the result's expressions use ``sympy.Symbol(name)``.
        random_state : int
        operators : sequence of str, optional
            Override of the engine's operator set for this call.
        context : {"data", "curve"}
            "curve" when y are samples of a learned curve (post-SR), "data" for measured
            records; decides what ``selection="auto"`` means (:data:`AUTO_SELECTION`).

        Returns
        -------
        SRResult
        """
        import sympy as sp

        t0 = time.perf_counter()
        X = np.asarray(X, dtype=float)
        if X.ndim == 1:
            X = X[:, None]
        y = np.asarray(y, dtype=float).reshape(-1)
        if X.shape[0] != y.shape[0] or X.shape[1] != len(names):
            raise ConfigError(f"SR needs X of shape (N, {len(names)}) and y of shape (N,), got {X.shape} and {y.shape}")
        if X.shape[0] < 5 or not (np.all(np.isfinite(X)) and np.all(np.isfinite(y))):
            raise ConfigError("SR needs at least 5 finite samples")
        ops = self.operators if operators is None else _check_operators(operators)
        symbols = [sp.Symbol(n) for n in names]
        idx = np.unique(np.linspace(0, X.shape[0] - 1, min(self.max_points, X.shape[0])).round().astype(int))
        ts = time.perf_counter()
        exprs, info = self._search(X[idx], y[idx], symbols, ops, int(random_state))
        search_seconds = time.perf_counter() - ts
        var_y = float(np.var(y))
        cands = _candidates_from(exprs, symbols, X, y)
        # the plain mean is always a candidate: the front never is empty
        mean_expr = sp.Float(float(np.mean(y)), 15)
        cands.append(_Candidate(mean_expr, var_y, 1, 1, frozenset([sp.Integer(1)])))
        front = _pareto(cands)
        pick = select_model(front, self.selection, X.shape[0], var_y, context)
        criterion = AUTO_SELECTION.get(context, "knee") if self.selection == "auto" else self.selection
        chosen = front[pick]
        expr, mse = polish_constants(chosen.expression, symbols, X, y)
        expr = _tidy(_desaturate(expr, symbols, X))
        vals = _eval(expr, symbols, X)
        if vals is not None:
            mse = float(np.mean((vals - y) ** 2))
        info.update({"n_candidates": len(cands), "n_search_models": len(exprs), "front_index": pick,
                     "n_points_search": int(idx.size)})
        return SRResult(
            expression=expr, mse=mse, complexity=expression_complexity(expr),
            front=[FrontEntry(c.complexity, c.mse, c.expression) for c in front],
            seconds=time.perf_counter() - t0, search_seconds=search_seconds, criterion=criterion,
            engine=self.name, operators=tuple(ops), info=info,
        )


def _desaturate(expr, symbols, X):
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


def _tidy(expr):
    """Drop exact-zero coefficients and show 1.0*b as b where the coefficient is exactly 1."""
    import sympy as sp

    return sp.Add(*[t for t in sp.Add.make_args(expr) if not (t.is_Number and float(t) == 0.0)])


# ------------------------------------------------------------------ Operon
_OPERON_SYMBOLS = {"add": "add", "sub": "sub", "mul": "mul", "div": "div", "pow": "pow", "square": "square",
                   "tanh": "tanh", "sin": "sin", "cos": "cos", "exp": "exp", "log": "log", "sqrt": "sqrt",
                   "abs": "abs"}
_INFIX_FUNCS = ("tanh", "sin", "cos", "exp", "log", "sqrt", "abs", "square")


def parse_infix(text: str, symbols: Sequence) -> Any:
    """Parse an engine's infix model string (variables ``X1..Xd``) into sympy, safely.

    Only numbers, ``X<k>``, known function names and arithmetic are accepted (token check
    before sympy sees the text); ``^`` is power.
    """
    import re

    import sympy as sp
    from sympy.parsing.sympy_parser import parse_expr, standard_transformations

    from ..curves._fitted import first_disallowed_token

    bad = first_disallowed_token(text, lambda name: name in _INFIX_FUNCS or re.fullmatch(r"X\d+", name) is not None,
                                 {"+", "-", "*", "/", "^", "(", ")", "**"})
    if bad == "":
        raise ValueError(f"cannot tokenize model {text!r}")
    if bad is not None:
        raise ValueError(f"unexpected token {bad!r} in model {text!r}")
    local = {f"X{i + 1}": s for i, s in enumerate(symbols)}
    local.update({"tanh": sp.tanh, "sin": sp.sin, "cos": sp.cos, "exp": sp.exp, "log": sp.log,
                  "sqrt": sp.sqrt, "abs": sp.Abs, "square": lambda a: a**2})
    return parse_expr(text.replace("^", "**"), local_dict=local,
                      global_dict={"Integer": sp.Integer, "Float": sp.Float, "Rational": sp.Rational},
                      transformations=standard_transformations, evaluate=True)


class OperonEngine(SymbolicRegressionEngine):
    """Operon (``pyoperon.sklearn.SymbolicRegressor``), multi-objective (MSE, length) search.

    Settings mirror the paper's PySR runs where Operon has a counterpart:

    ============================  ==============================================================
    charcurves option             Operon
    ============================  ==============================================================
    ``generations``               ``generations`` (evolutionary steps)
    ``population_size``           ``population_size`` and ``pool_size`` (offspring per step)
    ``populations``               independent runs with seeds ``seed, seed+1, ...`` whose Pareto
                                  fronts are merged (Operon has one population, no islands)
    ``max_size``                  ``max_length`` (tree nodes; Operon variables carry their own
                                  weight, so ``c*x`` is one node where PySR counts 3)
    ``operators``                 ``allowed_symbols`` (+ constant, variable)
    (fixed)                       ``objectives=["mse", "length"]`` (NSGA-II, L2 loss), Levenberg-
                                  Marquardt on constants (``optimizer_iterations``, 10),
                                  no evaluation budget (the generations bound the search),
                                  ``n_threads=1``, ``random_state``
    ============================  ==============================================================

    Operon's own linear scaling adds a scale and an intercept to every model; the intercept is
    removed again by the selection when it does not pay for itself.
    """

    name = "operon"

    def __init__(self, *, optimizer_iterations: int = 10, n_threads: int = 1, **kwargs):
        super().__init__(**kwargs)
        self.optimizer_iterations = int(optimizer_iterations)
        self.n_threads = int(n_threads)

    def _search(self, X, y, symbols, operators, random_state):
        try:
            from pyoperon.sklearn import SymbolicRegressor
            import pyoperon as op
        except ImportError:  # pragma: no cover - pyoperon is a dependency
            raise ConfigError("the Operon engine needs the 'pyoperon' package: pip install pyoperon") from None
        import warnings

        allowed = ",".join([_OPERON_SYMBOLS[o] for o in operators] + ["constant", "variable"])
        exprs, gens, evals = [], 0, 0
        for k in range(self.populations):
            reg = SymbolicRegressor(
                allowed_symbols=allowed, objectives=["mse", "length"], max_length=self.max_size,
                max_depth=max(6, self.max_size), population_size=self.population_size,
                pool_size=self.population_size, generations=self.generations,
                max_evaluations=10**12,  # the generations bound the search, not a budget
                optimizer_iterations=self.optimizer_iterations, n_threads=self.n_threads,
                random_state=(int(random_state) * 7919 + k) % (2**63), reinserter="keep-best",
                offspring_generator="basic", initialization_max_length=min(10, self.max_size),
            )
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                reg.fit(X, y)
            gens += int(reg.stats_.get("generations", 0))
            evals += int(reg.stats_.get("evaluation_count", 0))
            names = {h: f"X{i + 1}" for i, h in enumerate(reg.variables_)}
            # reg.variables_ maps hash -> "X1".. in column order already; keep our own names anyway
            for entry in reg.pareto_front_:
                text = op.InfixFormatter.Format(entry["tree"], names, 17)
                try:
                    exprs.append(parse_infix(text, symbols))
                except (ValueError, SyntaxError, TypeError):
                    continue
        return exprs, {"generations_run": gens, "evaluations": evals}


# ------------------------------------------------------------------ PySR
_PYSR_BINARY = {"add": "+", "sub": "-", "mul": "*", "div": "/", "pow": "^"}
_PYSR_MISSING = ("the PySR backend needs the optional 'pysr' package and a Julia installation: "
                 "pip install 'charcurves[pysr]' (PySR installs Julia on first import); "
                 "use engine='operon' (the default) otherwise")


class PySREngine(SymbolicRegressionEngine):
    """PySR (``pysr.PySRRegressor``), as the paper's authors ran it; imported only when used.

    Mapping: ``generations`` -> ``niterations``, ``populations`` -> ``populations``,
    ``population_size`` -> ``population_size``, ``max_size`` -> ``maxsize``, ``operators`` ->
    ``binary_operators`` (+ - * / ^) and ``unary_operators`` (the rest); L2 loss,
    ``deterministic=True`` with serial parallelism and ``random_state`` (reproducible). PySR's
    whole hall of fame goes through the same selection and polishing as Operon's front.
    """

    name = "pysr"

    def _search(self, X, y, symbols, operators, random_state):
        try:
            import pysr  # noqa: F401
            from pysr import PySRRegressor
        except Exception:  # ImportError, or Julia failing to start inside pysr's import
            raise ConfigError(_PYSR_MISSING) from None
        binary = [_PYSR_BINARY[o] for o in operators if o in _PYSR_BINARY]
        unary = [o for o in operators if o not in _PYSR_BINARY]
        safe = [f"x{i}" for i in range(X.shape[1])]
        import inspect

        accepted = set(inspect.signature(PySRRegressor.__init__).parameters)
        kwargs = dict(niterations=self.generations, populations=self.populations,
                      population_size=self.population_size, maxsize=self.max_size,
                      binary_operators=binary, unary_operators=unary, model_selection="best",
                      random_state=int(random_state), deterministic=True, progress=False, verbosity=0)
        # L2 loss and serial (deterministic) evaluation are spelled differently across versions
        kwargs["elementwise_loss" if "elementwise_loss" in accepted else "loss"] = "L2DistLoss()"
        if "parallelism" in accepted:
            kwargs["parallelism"] = "serial"
        else:
            kwargs.update(procs=0, multithreading=False)
        try:
            reg = PySRRegressor(**{k: v for k, v in kwargs.items() if k in accepted})
            reg.fit(X, y, variable_names=safe)
        except ConfigError:
            raise
        except Exception as exc:  # Julia missing/broken surfaces here on first use
            if "julia" in str(exc).lower():
                raise ConfigError(_PYSR_MISSING) from None
            raise
        import sympy as sp

        sub = {sp.Symbol(s): sym for s, sym in zip(safe, symbols)}
        exprs = []
        for e in reg.equations_["sympy_format"]:
            try:
                exprs.append(sp.sympify(e).xreplace(sub))
            except (sp.SympifyError, TypeError):
                continue
        return exprs, {"n_hall_of_fame": len(exprs)}


# ---------------------------------------------------------------------------------------------
def make_engine(sr_options: dict | None = None) -> SymbolicRegressionEngine:
    """Build an engine from ``sr_options``.

    Parameters
    ----------
    sr_options : dict, optional
        Keys (all optional; :data:`DEFAULT_SR_OPTIONS`): ``engine`` ("operon" | "pysr"),
        ``generations``, ``populations``, ``population_size``, ``max_size``, ``operators``
        ("auto" or a list of :data:`OPERATORS`; "auto" lets the caller choose per fit, the
        engine's own default being + - *), ``selection`` (:data:`SELECTION_CRITERIA`).

    Raises
    ------
    ConfigError
        For unknown keys or values.
    """
    opts = dict(sr_options or {})
    unknown = sorted(set(opts) - set(SR_OPTION_KEYS))
    if unknown:
        raise ConfigError(f"unknown sr option(s) {unknown}; valid: {', '.join(SR_OPTION_KEYS)}")
    merged = {**DEFAULT_SR_OPTIONS, **{k: v for k, v in opts.items() if v is not None}}
    engine = str(merged.pop("engine")).lower()
    if engine not in _ENGINES:
        raise ConfigError(f"unknown SR engine {engine!r}; choose one of {', '.join(_ENGINES)}")
    ops = merged.pop("operators")
    ops = POLY_OPERATORS if (isinstance(ops, str) and ops.strip().lower() == "auto") else _check_operators(ops)
    cls = OperonEngine if engine == "operon" else PySREngine
    return cls(operators=ops, **merged)


def operators_option(sr_options: dict | None):
    """``None`` when ``sr_options["operators"]`` is "auto" (caller decides), else the tuple."""
    ops = (sr_options or {}).get("operators", "auto")
    if ops is None or (isinstance(ops, str) and ops.strip().lower() == "auto"):
        return None
    return _check_operators(ops)
