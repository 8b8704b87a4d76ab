"""Model selection on the Pareto front of (complexity, MSE), shared by every engine."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any, NamedTuple, cast

import numpy as np

from .._errors import ConfigError
from ._expressions import canonical, eval_expression, expression_complexity, n_constants, polish_constants, split_terms

__all__ = ["FrontEntry", "SRResult", "Candidate", "candidates_from", "has_inner_constants", "pareto", "select_model",
           "SELECTION_CRITERIA", "AUTO_SELECTION", "BIC_MARGIN", "KNEE_RIVAL", "KNEE_UNFINISHED", "PARSIMONY", "REL_MSE_FLOOR"]

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

#: "knee": a knee whose MSE is more than this times the least on the front is not the structure yet
#: (the front goes on to fit the curve far better); the selection moves on to the knee after it.
KNEE_UNFINISHED = 100.0
#: ... and a later step gains at least this share of the knee's -Δlog(MSE) per unit of complexity.
KNEE_RIVAL = 0.5

#: Relative MSE floor (times var(y)): differences below RMSE = 1e-6 std(y) are round-off, not
#: structure; without the floor, models at the numerical floor of clean data would be ranked
#: by noise in the 15th digit.
REL_MSE_FLOOR = 1e-12


class FrontEntry(NamedTuple):
    """One Pareto-optimal model: complexity, MSE on all points, the sympy expression.

    Examples
    --------
    >>> import sympy as sp
    >>> from charcurves.symbolic import FrontEntry, select_model
    >>> z = sp.Symbol("z")
    >>> front = [FrontEntry(1, 1.0, z), FrontEntry(3, 1e-3, z**3 - z), FrontEntry(7, 9.9e-4, z**3 - z + z**5 / 100)]
    >>> front[1].expression, select_model(front, "bic", n=1000, var_y=1.0)
    (z**3 - z, 2)
    """

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

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.symbolic import SRResult, make_engine
    >>> z = np.linspace(-2, 2, 200)
    >>> result = make_engine({"generations": 5}).fit(z[:, None], z**3 - z, ["z"], random_state=0)
    >>> isinstance(result, SRResult), result.complexity, result.mse < 1e-12, [e.complexity for e in result.front][:3]
    (True, 11, True, [1, 3, 7])
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

@dataclasses.dataclass
class Candidate:
    expression: Any
    mse: float
    complexity: int
    n_constants: int
    key: Any
    #: the expression was built without sympy's evaluation (a polished candidate): see ``reevaluate``
    raw: bool = False


def candidates_from(exprs, symbols, X, y) -> list[Candidate]:
    """Canonical forms of the searched expressions plus their backward-elimination sub-models."""
    import sympy as sp

    pool: dict[Any, Candidate] = {}
    basis_cache: dict[Any, np.ndarray | None] = {}

    def add(expr, mse, key):
        if not math.isfinite(mse):
            return
        old = pool.get(key)
        if old is None or mse < old.mse:
            pool[key] = Candidate(expr, mse, expression_complexity(expr), n_constants(expr), key)

    for raw in exprs:
        expr = canonical(raw)
        terms = split_terms(expr)
        bases: Any = []  # the basis expressions; None when one of them is not finite on X
        for c, b in terms:
            if b not in basis_cache:
                basis_cache[b] = eval_expression(b, symbols, X)
            if basis_cache[b] is None:
                bases = None
                break
            bases.append(b)
        if not bases:
            continue
        B = np.column_stack([cast(np.ndarray, basis_cache[b]) for b in bases])  # no None: checked above
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
            assert best_j is not None  # y and the columns are finite, so are the sub-models' errors
            active.remove(best_j)
    out = list(pool.values())
    # constants inside functions (tanh(k z)) come from the single-precision search on a subsample;
    # unpolished, a slightly wrong k can make a nested variant look better than the plain form
    for cand in out:
        if has_inner_constants(cand.expression):
            expr, mse = polish_constants(cand.expression, symbols, X, y, max_nfev=60, canonical=False)
            if mse < cand.mse:
                cand.expression, cand.mse, cand.raw = expr, mse, True
    return out


def has_inner_constants(expr) -> bool:
    import sympy as sp

    return any(isinstance(a, sp.Float) for f in expr.atoms(sp.Function) for a in sp.preorder_traversal(f))


def pareto(cands: list[Candidate]) -> list[Candidate]:
    """Simplest first, each strictly more accurate than every simpler one."""
    out: list[Candidate] = []
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
        step after which adding terms buys little. A knee whose MSE is still more than 100 times
        (``KNEE_UNFINISHED``) the least on the front, when a later step gains at least half as
        much per unit (``KNEE_RIVAL``), is only a first step (the linear part of a drag law
        ``0.2 z + 0.15 z|z|``, which explains 97 % of its variance): then that later step is
        taken, and so on.
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

    Examples
    --------
    >>> import sympy as sp
    >>> from charcurves.symbolic import FrontEntry, SELECTION_CRITERIA, select_model
    >>> z = sp.Symbol("z")
    >>> front = [FrontEntry(1, 1.0, z), FrontEntry(3, 1e-3, z**3 - z), FrontEntry(7, 9.9e-4, z**3 - z + z**5 / 100)]
    >>> SELECTION_CRITERIA
    ('auto', 'knee', 'bic', 'parsimony', 'best')
    >>> select_model(front, "bic", n=1000, var_y=1.0), select_model(front, "best", n=1000, var_y=1.0)
    (2, 1)
    """
    if criterion not in SELECTION_CRITERIA:
        raise ConfigError(f"unknown selection criterion {criterion!r}; choose one of {', '.join(SELECTION_CRITERIA)}")
    if criterion == "auto":
        if context not in AUTO_SELECTION:
            raise ConfigError(f"context must be one of {', '.join(AUTO_SELECTION)}, got {context!r}")
        criterion = AUTO_SELECTION[context]
    if len(front) == 1:
        return 0
    floor = max(REL_MSE_FLOOR * float(var_y), 1e-300)
    mse = np.maximum(np.array([f.mse for f in front], dtype=float), floor)
    cx = np.array([f.complexity for f in front], dtype=float)
    if criterion == "parsimony":
        return int(np.argmin(np.log(mse) + PARSIMONY * cx))
    if criterion == "bic":
        k = np.array([f.n_constants if hasattr(f, "n_constants") else n_constants(f.expression)
                      for f in front], dtype=float)
        bic = n * np.log(mse) + k * np.log(n)
        return int(np.flatnonzero(bic <= bic.min() + BIC_MARGIN)[0])
    score = np.zeros(len(front))
    score[1:] = -np.diff(np.log(mse)) / np.maximum(np.diff(cx), 1.0)
    if criterion == "best":
        score = np.where(mse <= 1.5 * mse.min(), score, -np.inf)
    pick = int(np.argmax(score))
    # "knee": a knee whose MSE is still KNEE_UNFINISHED times the front's least, followed by a step
    # nearly as steep (KNEE_RIVAL), is the first of two structural steps (the linear part of a drag law
    # 0.2 z + 0.15 z|z|); terms that follow a learned curve's wiggles gain far less per unit
    while criterion == "knee" and mse[pick] > KNEE_UNFINISHED * mse.min() and pick < len(front) - 1:
        later = pick + 1 + int(np.argmax(score[pick + 1:]))
        if score[later] < KNEE_RIVAL * score[pick]:
            break
        pick = later
    return pick


# ---------------------------------------------------------------------------------------------
# engines
# ---------------------------------------------------------------------------------------------
