"""The PySR backend of symbolic regression (optional: ``pip install 'charcurves[pysr]'``, which
needs Julia): :class:`PySREngine`, a :class:`~charcurves.symbolic._engine.SymbolicRegressionEngine`
whose hall of fame goes through the same selection and constant polishing as Operon's front.
:func:`~charcurves.symbolic.make_engine` builds it for ``{"engine": "pysr"}``; nothing here
imports pysr until a search runs."""

from __future__ import annotations

from .._errors import ConfigError
from ._engine import SymbolicRegressionEngine

__all__ = ["PySREngine"]

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

    Examples
    --------
    >>> from charcurves.symbolic import PySREngine, make_engine
    >>> engine = make_engine({"engine": "pysr", "generations": 40})
    >>> isinstance(engine, PySREngine), engine.name, engine.generations
    (True, 'pysr', 40)
    """

    name = "pysr"

    def _search(self, X, y, symbols, operators, random_state):
        try:
            import pysr  # noqa: F401
            from pysr import PySRRegressor
        except Exception:  # ImportError, or Julia failing to start inside pysr's import
            raise ConfigError(_PYSR_MISSING) from None
        binary = [_PYSR_BINARY[o] for o in operators if o in _PYSR_BINARY]
        # PySR has no sqrt(|u|) node: offer sqrt and abs, whose composition is the same
        unary = list(dict.fromkeys(u for o in operators if o not in _PYSR_BINARY
                                   for u in (("sqrt", "abs") if o == "sqrtabs" else (o,))))
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
