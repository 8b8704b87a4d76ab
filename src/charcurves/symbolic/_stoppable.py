"""Stopping an Operon search early with what it found so far (Ctrl-C, SIGTERM).

Operon's genetic algorithm ends a run when its generations are done or when the offspring
generator reports its evaluator's budget spent (``generator.Terminate()``, checked before every
offspring and at every generation). pyoperon's ``SymbolicRegressor.fit`` builds that evaluator
internally; :func:`stoppable_regressor` returns a regressor that keeps a handle on it, so that
:meth:`stop` -- called from the main thread while the search runs in C++ in a helper thread -- sets
the budget to 0: the search ends after the offspring being bred (milliseconds) and ``fit`` returns
normally, with the Pareto front of the generations run so far (``stats_["generations"]``).

:class:`SearchInterrupted` is the KeyboardInterrupt an interrupted search raises from
:meth:`~charcurves.symbolic.SymbolicRegressionEngine.fit`; it carries the result selected from the
front reached (``.result``), so a fitter can keep it, while every caller that knows nothing of it
sees a plain KeyboardInterrupt.
"""

from __future__ import annotations

__all__ = ["SearchInterrupted", "stoppable_regressor"]


class SearchInterrupted(KeyboardInterrupt):
    """Ctrl-C or SIGTERM stopped a search; ``result`` is the SRResult of the front reached so far
    (None when nothing was found).

    Examples
    --------
    >>> from charcurves.symbolic import SearchInterrupted
    >>> issubclass(SearchInterrupted, KeyboardInterrupt), SearchInterrupted().result
    (True, None)
    """

    def __init__(self, result=None):
        super().__init__("the search was interrupted; the best expression so far is kept")
        self.result = result


_CLASS: list = []


def stoppable_regressor(**kwargs):
    """A ``pyoperon.sklearn.SymbolicRegressor(**kwargs)`` with a ``stop()`` method (thread safe
    enough for a flag: one integer written while the search reads it)."""
    if not _CLASS:
        from pyoperon.sklearn import SymbolicRegressor

        class StoppableRegressor(SymbolicRegressor):
            """Keeps the evaluator its offspring generator watches, to spend its budget on stop()."""

            def _init_generator(self, generator_name, evaluator, *args, **kw):
                self._watched = evaluator
                if getattr(self, "_stop_asked", False):
                    evaluator.Budget = 0
                return super()._init_generator(generator_name, evaluator, *args, **kw)

            def stop(self) -> None:
                self._stop_asked = True
                watched = getattr(self, "_watched", None)
                if watched is not None:
                    watched.Budget = 0

        _CLASS.append(StoppableRegressor)
    return _CLASS[0](**kwargs)
