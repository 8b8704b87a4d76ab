"""Post-SR of a hidden-state fit: each learned curve distilled to a closed form, its constants
refitted by output error.

Every curve of the best start goes through :func:`charcurves.symbolic.distill_curve_front` (symbolic
regression on its samples over the range its argument visits, as post-SR of the separable family);
a knee whose free run leaves the data loss more than ``DATA_LOSS_TOLERANCE`` above the learned
model's gives way to the simplest member of its front that keeps it (:func:`closed_forms`);
a curve the gauge anchors at 0 keeps ``f(0) = 0`` (its form minus its value at 0, exactly, while the
constants move). Then every numeric constant of the closed forms
(:class:`~charcurves.curves.SymbolicParametrisation`), the scalars, the gain and the segments'
initial states are trained together by one more stage of output error at the last segment length
(:func:`~._fit.fit_state_space`). ``info["post_sr"]`` gives each curve's form before and after
the refit and the data loss before distillation, after it and after the refit.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from ..curves import SymbolicFittedCurve, SymbolicParametrisation
from ..symbolic import DATA_LOSS_TOLERANCE, distill_curve_front, operators_option, post_sr_engine
from ._neural import _ParamCurve

__all__: list[str] = []


class _ZeroAtZero:
    """``p(theta, z) - p(theta, 0)``: a closed form held at 0 at 0 while its constants move."""

    symmetry = exact_symmetry = "none"
    symmetry_mode = "exact"
    pinned_at_zero = True

    def __init__(self, param):
        self.inner = param
        self.n_params = param.n_params

    def _zero(self, theta, u):
        import torch

        return torch.zeros(theta.shape[0], 1, dtype=u.dtype)

    def evaluate(self, theta, u, u_both=None):
        return self.inner.evaluate(theta, u) - self.inner.evaluate(theta, self._zero(theta, u))

    def evaluate_jacobian(self, theta, u, u_both=None):
        f, J = self.inner.evaluate_jacobian(theta, u)
        f0, J0 = self.inner.evaluate_jacobian(theta, self._zero(theta, u))
        return f - f0, J - J0

    def evaluate_all(self, theta, u):
        f, J, d = self.inner.evaluate_all(theta, u)
        f0, J0 = self.inner.evaluate_jacobian(theta, self._zero(theta, u))
        return f - f0, J - J0, d

    def decay_groups(self) -> list:
        return []

    def expression(self, values):
        import sympy as sp

        e = self.inner.expression(values)
        return e - e.subs(sp.Symbol("z"), 0)


def _symbolic_fitted(c, b):
    lo, hi = c.domain[b]
    expr = c.rep.expression(c.theta[b])
    return SymbolicFittedCurve(c.name, c.argument, (float(lo), float(hi)), expr, 0.0, dict(c.meta))


def _closed(c, expr, anchored: bool, meta: dict):
    """One row's closed form ``expr`` of curve ``c`` as a trainable curve of the shooting problem."""
    import sympy as sp

    expr = sp.sympify(expr)
    if anchored:
        expr = expr - expr.subs(sp.Symbol("z"), 0)
    closed = SymbolicParametrisation(expr)
    theta0 = closed.theta0[None, :].copy()
    param: Any = _ZeroAtZero(closed) if anchored else closed
    pc = _ParamCurve(c.name, param, c.argument, c.arg_layout, np.zeros(1), np.ones(1), theta0, _symbolic_fitted,
                     pinned=anchored)
    pc.domain = np.asarray(c.domain, dtype=float).reshape(-1, 2)[-1:].copy()
    pc.meta = {**meta, "distilled": str(expr)}
    return pc


def _row(c, b: int):
    """Curve ``c`` of the fit restricted to row ``b`` (one row, as the post-SR stage trains)."""
    import copy

    out = copy.copy(c)
    out.center, out.half, out.theta = c.center[b:b + 1], c.half[b:b + 1], c.theta[b:b + 1]
    out.domain = c.domain[b:b + 1]
    return out


def closed_forms(curves: list, best: int, anchored, sr_options: dict | None, seed: int, loss_of, bound: float,
                 n: int = 1000) -> tuple[list, dict]:
    """The closed form of each curve of row ``best`` (``_ParamCurve``s of one row over
    :class:`~charcurves.curves.SymbolicParametrisation`, the argument as is; ``meta`` the SR digest)
    and, per curve kept as learned, the reason.

    A hidden state's free run is sensitive to its curves, and the knee of a front (chosen on the
    curve's samples alone) may let it drift away: each curve's knee is kept when the data loss
    (``loss_of(curves)``, the other curves as learned) stays within ``bound``, else the simplest
    member of its front that keeps it; when none does, the learned curve stays (one row of it,
    trained by the refit with the closed forms). ``meta["data_guard"]`` says which."""
    engine = post_sr_engine(sr_options)
    ops = operators_option(sr_options)
    rows = [_row(c, best) for c in curves]
    out: list = []
    kept: dict = {}
    for i, c in enumerate(rows):
        source = c.fitted(0)
        t0 = time.perf_counter()
        closed, front = distill_curve_front(source, engine, n=int(n), random_state=int(seed) + 1000 * i, operators=ops)
        meta = {**closed.meta, "source_kind": source.kind}
        pick = _closed(c, closed.expression(), c.name in anchored, meta)
        others = lambda k: rows[:i] + [k] + rows[i + 1:]  # noqa: E731
        knee = loss_of(others(pick))
        if not knee <= bound:
            best_loss, best_expr = np.inf, None
            for expr in front:  # simplest first
                value = loss_of(others(_closed(c, expr, c.name in anchored, meta)))
                if value <= bound:
                    best_loss, best_expr = value, expr
                    break
                best_loss, best_expr = (value, expr) if value < best_loss else (best_loss, best_expr)
            if best_loss <= bound:
                pick = _closed(c, best_expr, c.name in anchored, meta)
                pick.meta["data_guard"] = f"front member kept the data loss in bound (knee {closed.expression()} did not)"
            else:  # no closed form keeps the free run: the learned curve stays (trained with the rest)
                kept[c.name] = {**meta, "distilled": None, "data_guard": (
                    f"learned curve kept: no front member kept the data loss within {DATA_LOSS_TOLERANCE:.0%} (knee "
                    f"{closed.expression()}: {knee:.4g}, best member {best_expr}: {best_loss:.4g}, bound {bound:.4g})")}
                out.append(c)
                continue
        pick.meta["distill_seconds"] = time.perf_counter() - t0
        out.append(pick)
    return out, kept


def post_sr_report(closed: list, kept: dict, loss_before: float, loss_distilled: float, loss_refit: float,
                   seconds: float) -> dict:
    """``info["post_sr"]``: per curve the distilled form, the refitted one (None for a curve kept as
    learned) and the SR digest; the data losses (sum of squares over the segments) before,
    distilled and refitted."""
    curves = {}
    for c in closed:
        meta = dict(kept[c.name]) if c.name in kept else dict(c.meta)
        meta["expression"] = None if c.name in kept else str(c.rep.expression(c.theta[0]))
        curves[c.name] = meta
    return {"curves": curves, "loss_before": float(loss_before), "loss_distilled": float(loss_distilled),
            "loss_refit": float(loss_refit), "seconds": float(seconds)}


def post_sr_stage(run, shared, best, anchored, traj, gain, scalars, loss, sr_options, seed, log, started, progress):
    """Post-SR of start ``best`` (module docstring): its closed forms, their data loss as distilled
    (``run`` without iterations) and after the output-error refit. Returns the refitted fit (one
    row), whether Ctrl-C stopped it and ``info["post_sr"]``; Ctrl-C before the refit keeps the fit."""
    t0 = time.perf_counter()
    row = slice(best, best + 1)
    g1, sc1, tr1 = gain[row], {k: v[row] for k, v in scalars.items()}, traj[row]
    try:
        def loss_of(curves):  # the data loss of one row's curves, not trained
            return float(run(curves, g1, sc1, tr1, iters=0)[3][0])

        closed, kept = closed_forms(shared, best, anchored, sr_options, seed, loss_of,
                              float(loss[best]) * (1.0 + DATA_LOSS_TOLERANCE))
        distilled = run(closed, g1, sc1, tr1, iters=0)[3]
        tr_new, g_new, sc_new, loss_new, iterations, interrupted = run(closed, g1, sc1, tr1)
    except KeyboardInterrupt:
        log[-1]["stopped"] = "interrupted"
        return shared, traj, gain, scalars, loss, True, None
    log.append({"segment_length": int(log[-1]["segment_length"]), "linear_curves": False, "curves": "closed form",
                "start": int(best), "loss": [float(v) for v in loss_new], "lm_iterations": iterations,
                "seconds": time.perf_counter() - started})
    if interrupted:
        log[-1]["stopped"] = "interrupted"
    report = post_sr_report(closed, kept, float(loss[best]), float(distilled[0]), float(loss_new[0]),
                            time.perf_counter() - t0)
    if progress is not None:
        progress(f"post-SR: data loss {report['loss_before']:.4g} before, {report['loss_distilled']:.4g} distilled, "
                 f"{report['loss_refit']:.4g} refitted")
    return closed, tr_new, g_new, sc_new, loss_new, interrupted, report
