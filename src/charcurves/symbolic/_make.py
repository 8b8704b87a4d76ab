"""Building a search engine from ``sr_options``: the Operon engine (the default) or the optional PySR one."""

from __future__ import annotations

from .._errors import ConfigError
from ._engine import (DEFAULT_SR_OPTIONS, POLY_OPERATORS, SR_OPTION_KEYS, OperonEngine, SymbolicRegressionEngine,
                      check_operators)
from ._pysr import PySREngine

__all__ = ["make_engine"]

_ENGINES = ("operon", "pysr")


def make_engine(sr_options: dict | None = None) -> SymbolicRegressionEngine:
    """Build an engine from ``sr_options``.

    Parameters
    ----------
    sr_options : dict, optional
        Keys (all optional; :data:`DEFAULT_SR_OPTIONS`): ``engine`` ("operon" | "pysr"),
        ``generations``, ``populations``, ``population_size``, ``max_size``, ``operators``
        ("auto" or a list of :data:`OPERATORS`; "auto" lets the caller choose per fit, the
        engine's own default being + - *), ``selection`` (:data:`SELECTION_CRITERIA`),
        ``max_points`` (the search sees at most this many evenly spaced points).

    Raises
    ------
    ConfigError
        For unknown keys or values.

    Examples
    --------
    >>> from charcurves.symbolic import make_engine
    >>> engine = make_engine({"generations": 10, "operators": ["add", "sub", "mul", "tanh"]})
    >>> engine.name, engine.generations, engine.operators
    ('operon', 10, ('add', 'sub', 'mul', 'tanh'))
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
    ops = POLY_OPERATORS if (isinstance(ops, str) and ops.strip().lower() == "auto") else check_operators(ops)
    if engine == "operon":
        return OperonEngine(operators=ops, **merged)
    return PySREngine(operators=ops, **merged)
