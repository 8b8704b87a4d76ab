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
   (see ``desaturate``).

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
import copy
import dataclasses
import threading
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from .._errors import ConfigError
from ._expressions import (desaturate, eval_expression, expression_complexity, parse_infix, polish_constants,
                           reevaluate, tidy)
from ._memo import _MEMO, MEMO_SIZE, _memo_key
from ._stoppable import SearchInterrupted, stoppable_regressor
from ._selection import (AUTO_SELECTION, SELECTION_CRITERIA, Candidate, FrontEntry, SRResult, candidates_from, pareto,
                         select_model)

__all__ = [
    "SymbolicRegressionEngine",
    "OperonEngine",
    "SRResult",
    "FrontEntry",
    "select_model",
    "polish_constants",
    "expression_complexity",
    "OPERATORS",
    "POLY_OPERATORS",
    "TANH_OPERATORS",
    "CLOSED_FORM_OPERATORS",
    "SELECTION_CRITERIA",
    "DEFAULT_SR_OPTIONS",
    "SR_OPTION_KEYS",
]

#: Operator names accepted by ``sr_options["operators"]`` (binary: add sub mul div pow; the rest unary).
OPERATORS = ("add", "sub", "mul", "div", "pow", "square", "tanh", "sin", "cos", "exp", "log", "sqrt", "abs",
             "sqrtabs")
_BINARY = ("add", "sub", "mul", "div", "pow")
#: The paper's operator sets: binary + - * (no division: it can create singularities in forward
#: simulations), plus tanh where a jump (dry friction) must be expressed.
POLY_OPERATORS = ("add", "sub", "mul")
TANH_OPERATORS = ("add", "sub", "mul", "tanh")
#: The second search of post-SR's automatic operator choice (:mod:`charcurves.symbolic._distill`):
#: closed forms beyond polynomials -- drag z|z| (abs), saturation (tanh), periodic (sin, cos),
#: exponential hardening (exp) and square-root laws (``sqrtabs`` = sqrt(|u|), defined everywhere).
CLOSED_FORM_OPERATORS = ("add", "sub", "mul", "abs", "tanh", "sin", "cos", "exp", "sqrtabs")

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
    "max_points": 400,
}
SR_OPTION_KEYS = tuple(DEFAULT_SR_OPTIONS)


def check_operators(ops) -> tuple[str, ...]:
    if isinstance(ops, str):
        ops = [o.strip() for o in ops.replace(";", ",").split(",") if o.strip()]
    try:
        ops = tuple(str(o).strip().lower() for o in ops)
    except TypeError:
        raise ConfigError(f"operators must be 'auto' or a list of names like ('add', 'sub', 'mul', 'tanh'), got {ops!r}") from None
    if not ops:
        raise ConfigError(f"no operators given; give auto or names from {', '.join(OPERATORS)} (e.g. add,sub,mul,tanh)")
    bad = [o for o in ops if o not in OPERATORS]
    if bad:
        raise ConfigError(f"unknown operator(s) {bad}; give auto or names from {', '.join(OPERATORS)} "
                          "(e.g. add,sub,mul,abs,tanh)")
    repeated = sorted({o for o in ops if ops.count(o) > 1})
    if repeated:
        raise ConfigError(f"operator(s) {', '.join(repeated)} given more than once; name each operator once")
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

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.symbolic import SymbolicRegressionEngine, make_engine
    >>> engine = make_engine({"generations": 5})
    >>> isinstance(engine, SymbolicRegressionEngine)
    True
    >>> z = np.linspace(-2, 2, 200)
    >>> result = engine.fit(z[:, None], 2 * z**3 - z, ["z"], random_state=0)
    >>> result.expression.evalf(3), result.criterion, result.engine
    (2.0*z**3 - 1.0*z, 'bic', 'operon')
    """

    name = "abstract"
    #: ``progress(phase, step, total, loss)`` called while a search runs (every 0.1 s; loss nan), or None
    progress = None

    def __init__(self, *, generations: int = DEFAULT_SR_OPTIONS["generations"],
                 populations: int = DEFAULT_SR_OPTIONS["populations"],
                 population_size: int = DEFAULT_SR_OPTIONS["population_size"],
                 max_size: int = DEFAULT_SR_OPTIONS["max_size"], operators: Sequence[str] = POLY_OPERATORS,
                 selection: str = DEFAULT_SR_OPTIONS["selection"], max_points: int = DEFAULT_SR_OPTIONS["max_points"]):
        from .._bounds import check_number

        for key, val in (("generations", generations), ("populations", populations), ("max_size", max_size)):
            check_number(f"sr_{key}", val, label=f"sr option {key} (--sr-{key.replace('_', '-')})")
        for key, val, lo in (("population_size", population_size, 2), ("max_points", max_points, 10)):
            if isinstance(val, bool) or not isinstance(val, (int, np.integer)) or int(val) < lo:
                raise ConfigError(f"sr option {key} must be an integer >= {lo}, got {val!r}")
        if selection not in SELECTION_CRITERIA:
            raise ConfigError(f"unknown selection criterion {selection!r}; choose one of {', '.join(SELECTION_CRITERIA)}")
        self.generations = int(generations)
        self.populations = int(populations)
        self.population_size = int(population_size)
        self.max_size = int(max_size)
        self.operators = check_operators(operators)
        self.selection = selection
        self.max_points = int(max_points)

    def __repr__(self) -> str:
        return (f"{type(self).__name__}(generations={self.generations}, populations={self.populations}, "
                f"population_size={self.population_size}, max_size={self.max_size}, "
                f"operators={self.operators}, selection={self.selection!r}, max_points={self.max_points})")

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

        Raises
        ------
        SearchInterrupted
            (a KeyboardInterrupt) when Ctrl-C or SIGTERM stopped the search; its ``result`` is
            the pick of the front reached so far.
        """
        X = np.asarray(X, dtype=float)
        if X.ndim == 1:
            X = X[:, None]
        y = np.asarray(y, dtype=float).reshape(-1)
        if X.shape[0] != y.shape[0] or X.shape[1] != len(names):
            raise ConfigError(f"SR needs X of shape (N, {len(names)}) and y of shape (N,), got {X.shape} and {y.shape}")
        if X.shape[0] < 5 or not (np.all(np.isfinite(X)) and np.all(np.isfinite(y))):
            raise ConfigError("SR needs at least 5 finite samples")
        ops = self.operators if operators is None else check_operators(operators)
        key = _memo_key(self, X, y, names, int(random_state), ops, context)
        hit = _MEMO.get(key)
        if hit is None:
            hit = self._fit(X, y, names, int(random_state), ops, context)
            if hit.info.get("interrupted"):  # the pick of the front so far, never remembered
                raise SearchInterrupted(hit)
            _MEMO[key] = hit
            while len(_MEMO) > MEMO_SIZE:
                _MEMO.pop(next(iter(_MEMO)))
        return dataclasses.replace(hit, info=copy.deepcopy(hit.info))

    def _fit(self, X, y, names, random_state, ops, context) -> SRResult:
        import sympy as sp

        t0 = time.perf_counter()
        symbols = [sp.Symbol(n) for n in names]
        idx = np.unique(np.linspace(0, X.shape[0] - 1, min(self.max_points, X.shape[0])).round().astype(int))
        ts = time.perf_counter()
        exprs, info = self._search(X[idx], y[idx], symbols, ops, int(random_state))
        search_seconds = time.perf_counter() - ts
        var_y = float(np.var(y))
        cands = candidates_from(exprs, symbols, X, y)
        # the plain mean is always a candidate: the front never is empty
        mean_expr = sp.Float(float(np.mean(y)), 15)
        cands.append(Candidate(mean_expr, var_y, 1, 1, frozenset([sp.Integer(1)])))
        front = pareto(cands)
        for c in front:  # candidates were polished without sympy's evaluation (see polish_constants)
            if c.raw:
                c.expression, c.raw = reevaluate(c.expression), False
        pick = select_model(front, self.selection, X.shape[0], var_y, context)
        criterion = AUTO_SELECTION.get(context, "knee") if self.selection == "auto" else self.selection
        chosen = front[pick]
        expr, mse = polish_constants(chosen.expression, symbols, X, y)
        expr = tidy(desaturate(expr, symbols, X))
        vals = eval_expression(expr, symbols, X)
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


_OPERON_SYMBOLS = {"add": "add", "sub": "sub", "mul": "mul", "div": "div", "pow": "pow", "square": "square",
                   "tanh": "tanh", "sin": "sin", "cos": "cos", "exp": "exp", "log": "log", "sqrt": "sqrt",
                   "abs": "abs", "sqrtabs": "sqrtabs"}


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

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.symbolic import OperonEngine
    >>> z = np.linspace(-2, 2, 200)
    >>> result = OperonEngine(generations=5).fit(z[:, None], z**3 - z, ["z"], random_state=0)
    >>> result.engine, sorted(str(t.as_coeff_Mul()[1]) for t in result.expression.as_ordered_terms())
    ('operon', ['z', 'z**3'])
    """

    name = "operon"

    def __init__(self, *, optimizer_iterations: int = 10, n_threads: int = 1, **kwargs):
        super().__init__(**kwargs)
        self.optimizer_iterations = int(optimizer_iterations)
        self.n_threads = int(n_threads)

    def _ticker(self, k: int):
        progress = self.progress
        if progress is None:
            return None
        return lambda: progress("sr search", k + 1, self.populations, float("nan"))

    def _search(self, X, y, symbols, operators, random_state):
        try:
            import pyoperon as op
        except ImportError:  # pragma: no cover - pyoperon is a dependency
            raise ConfigError("the Operon engine needs the 'pyoperon' package: pip install pyoperon") from None
        import warnings

        allowed = ",".join([_OPERON_SYMBOLS[o] for o in operators] + ["constant", "variable"])
        exprs, gens, evals = [], 0, 0
        for k in range(self.populations):
            reg = stoppable_regressor(
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
                stopped = _interruptible(reg.fit, X, y, stop=reg.stop, tick=self._ticker(k))
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
            if stopped:  # Ctrl-C or SIGTERM: the front so far, no further population
                return exprs, {"generations_run": gens, "evaluations": evals, "interrupted": True}
        return exprs, {"generations_run": gens, "evaluations": evals}


_RUNNING = [0]  # searches running in helper threads, abandoned ones included
_RUNNING_LOCK = threading.Lock()


def searches_running() -> int:
    """How many SR searches run in helper threads now: after Ctrl-C stopped a search, it ends on its own
    in the background (there is no way to cancel Operon's C++ search); a program that exits before it
    ends leaves it to be torn down with the process.

    Examples
    --------
    >>> from charcurves.symbolic import searches_running
    >>> searches_running()
    0
    """
    with _RUNNING_LOCK:
        return _RUNNING[0]


def _interruptible(fn, *args, stop=None, tick=None) -> bool:
    """``fn(*args)`` in a helper thread while the main thread waits in short steps, so that Ctrl-C and
    SIGTERM reach a search that runs in C++ (Operon releases the GIL, but Python only runs signal
    handlers between bytecodes of the main thread) within 0.1 s. With ``stop`` the first interrupt
    calls it (the search ends after the offspring being bred, with its front so far) and the wait
    goes on: True is returned once ``fn`` returned. Without ``stop``, or on a further interrupt while
    the search stops, KeyboardInterrupt is raised here and the abandoned search ends on its own in
    the background (its result is dropped). Elsewhere than in the main thread (sweep workers) ``fn``
    runs directly. ``tick()`` is called after every 0.1 s of waiting."""
    if threading.current_thread() is not threading.main_thread():
        fn(*args)
        return False
    box: dict = {}
    done = threading.Event()  # not Thread.is_alive: a join that Ctrl-C interrupts can leave it False too early

    def run():
        try:
            box["value"] = fn(*args)
        except BaseException as exc:  # handed to the caller below
            box["error"] = exc
        finally:
            with _RUNNING_LOCK:
                _RUNNING[0] -= 1
            done.set()

    with _RUNNING_LOCK:
        _RUNNING[0] += 1

    worker = threading.Thread(target=run, name="charcurves-sr-search", daemon=True)
    worker.start()
    stopped = False
    while not done.is_set():
        try:
            if not done.wait(0.1) and tick is not None:
                tick()
        except KeyboardInterrupt:
            if stop is None or stopped:
                raise
            stop()
            stopped = True
    if "error" in box:
        raise box["error"]
    return stopped


def operators_option(sr_options: dict | None):
    """``None`` when ``sr_options["operators"]`` is "auto" (caller decides), else the tuple.

    Examples
    --------
    >>> from charcurves.symbolic import operators_option
    >>> operators_option({"operators": "auto"}), operators_option({"operators": ["add", "mul", "tanh"]})
    (None, ('add', 'mul', 'tanh'))
    """
    ops = (sr_options or {}).get("operators", "auto")
    if ops is None or (isinstance(ops, str) and ops.strip().lower() == "auto"):
        return None
    return check_operators(ops)
