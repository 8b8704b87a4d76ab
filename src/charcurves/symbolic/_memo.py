"""The searches remembered per process: a search asked twice (SR-CC and SR-CC+refit share every
univariate search of their loop) is run once (:meth:`SymbolicRegressionEngine.fit`)."""

from __future__ import annotations

import hashlib
import numpy as np

from ._selection import SRResult

__all__ = ["MEMO_SIZE", "forget_searches"]

#: Searches remembered per process (:meth:`SymbolicRegressionEngine.fit`).
MEMO_SIZE = 256
_MEMO: dict[tuple, SRResult] = {}


def forget_searches() -> int:
    """Forget the searches remembered in this process; return how many were remembered.

    The next identical search runs again (a spy on the engine sees it, memory is given back).

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.symbolic import OperonEngine, forget_searches
    >>> z = np.linspace(-2, 2, 50)
    >>> _ = OperonEngine(generations=2).fit(z[:, None], z**2, ["z"], random_state=0)
    >>> forget_searches() >= 1, forget_searches()  # the search above (and any before it), then none
    (True, 0)
    """
    n = len(_MEMO)
    _MEMO.clear()
    return n


def _memo_key(engine, X: np.ndarray, y: np.ndarray, names, random_state: int, ops, context: str) -> tuple:
    """A search's identity: the engine and its settings, the data (by digest), seed, operators, context.

    A search is a deterministic function of these (one thread, seeded), so the same search asked
    twice in a process (SR-CC and SR-CC+refit share every univariate search of their loop) is run
    once; the result is the same, only its timings are those of the first run.
    """
    digest = hashlib.blake2b(np.ascontiguousarray(X).tobytes(), digest_size=16)
    digest.update(np.ascontiguousarray(y).tobytes())
    digest.update(repr(X.shape).encode())
    settings = (type(engine).__name__,) + tuple(sorted((k, repr(v)) for k, v in vars(engine).items() if k != "progress"))
    return (settings, digest.hexdigest(), tuple(names), random_state, tuple(ops), context)
