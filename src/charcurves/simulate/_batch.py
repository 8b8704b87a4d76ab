"""Many runs of one fitted model at once: one solver over the stacked states of every run.

Forward validation simulates each model from ten initial conditions (the paper's protocol). Run
one by one, each run pays the solver's per-step Python overhead on a 2-state system; stacked,
the runs share the solver's steps and every right-hand-side call evaluates the curves for all
of them at once (numpy): for a model whose curves evaluate in a few numpy operations (tables of
network curves, short closed forms) ten runs cost 1.4-2.7 times less (:data:`MAX_BATCH_OPS`).
The solver's error control then covers all runs together (its weighted norm over the stacked
state): each run is integrated about as accurately as alone, not bit for bit the same way.

Each run keeps the statuses of :func:`charcurves.simulate.simulate_model`: a run whose state
leaves the box or grows beyond ``max_abs`` (also inside a right-hand-side call: "diverged") is
taken out and the others go on from the last accepted step. A model with a dry-friction jump
(stick/slip events), a template other than the separable one, curves whose vectorised evaluation
is long (:data:`MAX_BATCH_OPS`), or a batch that takes longer than ``batch_budget`` (a stiff run
slows every run down) falls back to one run at a time.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

import numpy as np

from .._errors import ConfigError
from ._forward import SimulationResult, prepare_model_curves, simulate_model, solver_class

__all__ = ["simulate_model_batch", "MAX_BATCH_OPS"]

#: Runs are stacked when the two curves' vectorised evaluations take at most this many numpy
#: operations together (:attr:`PreparedCurve.vector_ops`: tables 12 each, closed forms their
#: operation count): on ten runs each operation costs about as much as a scalar evaluation of a
#: run, so long closed forms (degree-10 polynomials) are faster one run at a time (tabulating them
#: does not help: stacked, their runs took 0.55-0.82 s against 0.28-0.55 s). Measured on ten
#: Duffing validation cases of 80 s (2-core machine, one thread): a Parametric model 0.16 s stacked
#: against 0.43 s one by one, NN-CC+sym (tables) 0.33 s against 0.46 s, Poly-CC (degree 10,
#: exact) 0.64-0.80 s stacked against 0.29-0.63 s one by one.
MAX_BATCH_OPS = 24


class _Diverged(Exception):
    def __init__(self, t: float, cases: np.ndarray):
        super().__init__(t)
        self.t, self.cases = float(t), cases


def simulate_model_batch(model, t_eval, x0: Sequence[float], v0: Sequence[float],
                         forcing: Callable[[float], np.ndarray], *, method: str = "LSODA", rtol: float = 1e-8,
                         atol: float = 1e-10, time_budget: float = 60.0, batch_budget: float = 2.0,
                         box: dict | None = None, max_abs: float = 1e6, evaluation: str = "auto",
                         run_forcings: Sequence[Callable[[float], float]] | None = None) -> list[SimulationResult]:
    """Integrate ``x'' = g F_i(t) - f1(x') - f2(x) - b`` from every ``(x0[i], v0[i])`` at once.

    Parameters
    ----------
    model : FittedModel
    t_eval : array_like
        Increasing sample times, shared by the runs.
    x0, v0 : sequence of float
        Initial states, one per run.
    forcing : callable
        ``F(t)`` -> array of the runs' forcings at time t (one value per run).
    method, rtol, atol, box, max_abs, evaluation
        As :func:`charcurves.simulate.simulate_model`.
    time_budget : float
        Wall-clock seconds for one run (runs done one at a time get this each).
    batch_budget : float
        Wall-clock seconds the stacked runs may take before the unfinished ones are run one at a
        time instead (a stiff run slows every run of a batch down).
    run_forcings : sequence of callable, optional
        Each run's own scalar ``F_i(t)`` for runs done one at a time (default: element i of
        ``forcing(t)``).

    Returns
    -------
    list of SimulationResult
        One per run, in order; ``details["batched"]`` says whether it ran in the batch.

    Examples
    --------
    >>> import numpy as np
    >>> import charcurves as cc
    >>> from charcurves.simulate import simulate_model, simulate_model_batch, sinusoidal_forcing
    >>> from charcurves.systems import get_system
    >>> system = get_system("duffing")
    >>> model = cc.fit(system.simulate(), method="parametric", basis="f1=z; f2=z, z**3")
    >>> t = np.linspace(0.0, 20.0, 401)
    >>> A, W = np.array([0.5, 0.3]), np.array([1.2, 1.0])
    >>> runs = simulate_model_batch(model, t, [1.0, 0.0], [0.0, 0.5], lambda s: A * np.cos(W * s), rtol=1e-10,
    ...                             atol=1e-12)
    >>> one = simulate_model(model, t, 0.0, 0.5, sinusoidal_forcing(0.3, 1.0), rtol=1e-10, atol=1e-12)
    >>> [r.status for r in runs], bool(np.max(np.abs(runs[1].x - one.x)) < 1e-6)
    (['ok', 'ok'], True)
    """
    t_eval = np.asarray(t_eval, dtype=float).reshape(-1)
    xs: np.ndarray = np.asarray(x0, dtype=float).reshape(-1)
    vs: np.ndarray = np.asarray(v0, dtype=float).reshape(-1)
    if xs.shape != vs.shape:
        raise ConfigError(f"x0 and v0 need one value per run each, got {xs.size} and {vs.size}")
    if t_eval.size < 2 or not np.all(np.isfinite(t_eval)) or np.any(np.diff(t_eval) <= 0):
        raise ConfigError("t_eval must be finite, strictly increasing sample times; pass e.g. np.linspace(0, 80, 2001)")
    n = xs.size

    def one(i: int) -> SimulationResult:
        own = run_forcings[i] if run_forcings is not None else (lambda s: float(forcing(s)[i]))
        res = simulate_model(model, t_eval, float(xs[i]), float(vs[i]), own,
                             method=method, rtol=rtol, atol=atol, time_budget=time_budget, box=box,
                             max_abs=max_abs, evaluation=evaluation)
        res.details["batched"] = False
        return res

    if getattr(getattr(model, "template", None), "is_general", False) or n < 2:
        return [one(i) for i in range(n)]
    f1, f2 = prepare_model_curves(model, evaluation=evaluation)
    if f1.jump_height != 0.0 or f1.vector is None or f2.vector is None \
            or f1.vector_ops + f2.vector_ops > MAX_BATCH_OPS:  # stick/slip events are per run
        return [one(i) for i in range(n)]
    results: list[SimulationResult | None] = [None] * n
    done = _Batch(f1, f2, float(model.gain), float(model.offset), forcing, t_eval, solver_class(method),
                  float(rtol), float(atol), box, float(max_abs), float(batch_budget)).run(xs, vs, results)
    for i in range(n):
        if i not in done:
            results[i] = one(i)
    return [r for r in results if r is not None]


class _Batch:
    def __init__(self, f1, f2, g, b, forcing, t_eval, solver, rtol, atol, box, max_abs, budget):
        self.f1, self.f2, self.g, self.b, self.forcing = f1, f2, g, b, forcing
        self.t_eval, self.solver, self.rtol, self.atol = t_eval, solver, rtol, atol
        self.xb = box.get("x") if box else None
        self.vb = box.get("v") if box else None
        self.max_abs, self.budget = max_abs, budget

    def rhs(self, active: np.ndarray):
        f1, f2, g, b, forcing, m = self.f1.vector, self.f2.vector, self.g, self.b, self.forcing, self.max_abs
        k = active.size

        def fun(t, y):
            x, v = y[:k], y[k:]
            if not (np.abs(y) <= m).all():  # NaN fails the comparison too
                bad = ~((np.abs(x) <= m) & (np.abs(v) <= m))
                raise _Diverged(t, active[bad])
            return np.concatenate([v, g * forcing(t)[active] - f1(v) - f2(x) - b])

        return fun

    def _outside(self, x: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, list[str]] | None:
        """Which runs end at this accepted step, and why (the checks of one run's accepted steps); None: none."""
        m = self.max_abs
        ok = (np.abs(x) <= m) & (np.abs(v) <= m)
        if self.xb is not None:
            ok &= (x >= self.xb[0]) & (x <= self.xb[1])
        if self.vb is not None:
            ok &= (v >= self.vb[0]) & (v <= self.vb[1])
        if ok.all():
            return None
        bad = ~((np.abs(x) <= m) & (np.abs(v) <= m))
        why = ["diverged" if b else "" for b in bad]
        for lim, z, name in ((self.xb, x, "x"), (self.vb, v, "x'")):
            if lim is None:
                continue
            out = ~((z >= lim[0]) & (z <= lim[1])) & ~bad
            for j in np.flatnonzero(out):
                why[j] = why[j] or f"left_box:{name} = {z[j]:.4g} left [{lim[0]:.4g}, {lim[1]:.4g}]"
            bad = bad | out
        return bad, why

    def run(self, x0: np.ndarray, v0: np.ndarray, results: list) -> set:
        """Integrate every run; fills ``results`` for the runs it finished, returns their indices."""
        t_eval, n = self.t_eval, x0.size
        xs, vs = np.full((n, t_eval.size), np.nan), np.full((n, t_eval.size), np.nan)
        filled = np.zeros(n, dtype=int)
        started = time.perf_counter()
        deadline = time.monotonic() + self.budget
        active = np.arange(n)
        done: set = set()

        def end(i: int, status: str, message: str, t: float) -> None:
            k = int(filled[i])
            results[i] = SimulationResult(t_eval[:k], xs[i, :k], vs[i, :k], status, message, float(t),
                                          (time.perf_counter() - started) / n, 0,
                                          {"batched": True, "batch_size": n})
            done.add(int(i))

        t_cur, y_cur = float(t_eval[0]), np.concatenate([x0, v0])
        first, why = self._outside(x0, v0) or (np.zeros(n, dtype=bool), [""] * n)
        for i in np.flatnonzero(first):
            end(int(i), *self._status(why[i], t_cur, self.max_abs))
        keep = ~first
        active, y_cur = active[keep], np.concatenate([x0[keep], v0[keep]])
        xs[active, 0], vs[active, 0] = y_cur[:active.size], y_cur[active.size:]
        filled[active] = 1
        t_final = float(t_eval[-1])
        while active.size:
            solver = self.solver(self.rhs(active), t_cur, y_cur, t_final, rtol=self.rtol, atol=self.atol)
            restart = False
            while not restart:
                try:
                    solver.step()
                except _Diverged as d:  # a trial state of these runs blew up: they stop, the rest go on
                    for i in d.cases:
                        end(int(i), "diverged", f"the state became non-finite or larger than {self.max_abs:g} "
                                                f"at t = {d.t:.4g}", d.t)
                    keep = ~np.isin(active, d.cases)
                    k = active.size
                    y_cur = np.concatenate([y_cur[:k][keep], y_cur[k:][keep]])
                    active = active[keep]
                    restart = True
                    break
                if solver.status == "failed":
                    return done  # the runs left go one at a time
                k = active.size
                x_new, v_new = solver.y[:k], solver.y[k:]
                checked = self._outside(x_new, v_new)
                if checked is None:
                    bad, good = None, active
                else:
                    bad, why = checked
                    for j in np.flatnonzero(bad):
                        end(int(active[j]), *self._status(why[j], solver.t, self.max_abs))
                    good = active[~bad]
                lo = int(filled[good[0]]) if good.size else 0
                hi = int(np.searchsorted(t_eval, solver.t, side="right"))
                if good.size and hi > lo:
                    y = solver.dense_output()(t_eval[lo:hi])  # (2k, samples)
                    if bad is None:
                        xs[good, lo:hi], vs[good, lo:hi] = y[:k], y[k:]
                    else:
                        xs[good, lo:hi], vs[good, lo:hi] = y[:k][~bad], y[k:][~bad]
                    filled[good] = hi
                t_cur = float(solver.t)
                if bad is not None:
                    good = ~bad
                    active = active[good]
                    y_cur = np.concatenate([x_new[good], v_new[good]])
                    restart = True
                    break
                y_cur = np.array(solver.y)
                if solver.status == "finished":
                    for i in active:
                        if filled[i] < t_eval.size:  # cannot happen unless the solver stopped short silently
                            end(int(i), "solver_failed", "the solver stopped before the last sample", t_cur)
                        else:
                            end(int(i), "ok", "", t_final)
                    return done
                if time.monotonic() > deadline:
                    return done
        return done

    @staticmethod
    def _status(why: str, t: float, max_abs: float) -> tuple[str, str, float]:
        if why.startswith("left_box:"):
            return "left_box", f"{why[len('left_box:'):]} at t = {t:.4g}", t
        return "diverged", f"the state became non-finite or larger than {max_abs:g} at t = {t:.4g}", t
