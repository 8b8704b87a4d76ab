"""Post-SR: distil a fitted model's curves into closed forms (paper methods ii, iv and ix).

Each curve goes through :func:`charcurves.symbolic.distill_curve_front` (symbolic regression on its
samples over the training range); the template's gauge is re-applied and, given the training
record, the data loss is recomputed and guarded (:func:`_guard_data_loss`).
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..curves import SymbolicFittedCurve
from ..symbolic import DATA_LOSS_TOLERANCE, distill_curve_front, expression_complexity, operators_option, post_sr_engine
from ..templates import sticking_mask
from ..model import FittedModel

__all__ = ["distill_model", "DATA_LOSS_TOLERANCE"]




def _guard_data_loss(model, curves: dict, fronts: dict, traj) -> None:
    """Never let post-SR make the model clearly worse on its training record.

    The knee of a curve's front is chosen on the curve's samples alone; when a smooth stand-in of
    a jump (a SINDy polynomial of Coulomb friction) has no simple closed form, the knee is a
    straight line that doubles the data loss. Here the data loss (sticking samples left out, as
    in training) of the model with the distilled curves is compared with the model's own; while
    it exceeds ``1 + DATA_LOSS_TOLERANCE`` times that, each curve that alone breaks the bound is
    moved up its front to the simplest member that keeps it, else to the source's own closed form
    (basis/symbolic curves), else to the front member of least data loss. ``curves`` is updated
    in place; the choice is recorded in the curve's ``meta["data_guard"]``.
    """
    import sympy as sp

    mask = ~sticking_mask(traj)
    zs = sp.Symbol("z")

    def loss(cs: dict) -> float:
        # constants are not re-gauged here: the gauge only moves them between curves and b
        m = FittedModel(model.template, model.method, cs, model.gain, model.offset, model.loss, model.info)
        r = np.asarray(m.force_residual(traj))[mask]
        return float(np.mean(r**2))

    def closed(name: str, expr, how: str) -> SymbolicFittedCurve:
        c = curves[name]
        z = model.curves[name].grid(int(c.meta.get("n_grid", 1000)))
        rmse = float(np.sqrt(np.mean((SymbolicFittedCurve(c.name, c.argument, c.domain, expr)(z)
                                      - model.curves[name](z)) ** 2)))
        meta = dict(c.meta)
        meta.update({"expression": str(expr), "data_guard": how, "complexity": expression_complexity(expr),
                     "distillation_rmse": rmse})
        return SymbolicFittedCurve(c.name, c.argument, c.domain, expr, 0.0, meta)

    base = loss(dict(model.curves))
    bound = base * (1.0 + DATA_LOSS_TOLERANCE)
    if not np.isfinite(base) or loss(curves) <= bound:
        return
    for name, source in model.curves.items():
        trial = dict(model.curves)
        trial[name] = curves[name]
        if loss(trial) <= bound:
            continue
        chosen = str(curves[name].expression())
        best, best_loss = None, math.inf
        for expr in fronts.get(name, []):
            trial[name] = closed(name, expr, "")
            value = loss(trial)
            if value <= bound:
                best, best_loss = expr, value
                break
            if value < best_loss:
                best, best_loss = expr, value
        if best_loss <= bound:
            curves[name] = closed(name, best, f"front member kept the data loss within "
                                              f"{DATA_LOSS_TOLERANCE:.0%} (knee {chosen} did not)")
            continue
        own = source.expression()
        if own is not None and not (own.free_symbols - {zs}):
            curves[name] = closed(name, own, f"source curve kept: no front member kept the data loss within "
                                             f"{DATA_LOSS_TOLERANCE:.0%} (knee {chosen})")
        elif best is not None:
            curves[name] = closed(name, best, f"front member of least data loss (knee {chosen})")


def distill_model(model, *, sr_options: dict | None = None, random_state: int = 0, n: int = 1000, traj=None,
                  progress=None):
    """Post-SR of every curve of a fitted model.

    Parameters
    ----------
    model : FittedModel
    sr_options : dict, optional
        See :func:`charcurves.symbolic.make_engine` ("operators": "auto" picks per curve); the
        post-SR defaults (:data:`charcurves.symbolic.POST_SR_OPTIONS`) fill what is not given.
    random_state : int
        Seed; curve i uses ``random_state + 1000 i``.
    n : int
        Grid points per curve.
    traj : Trajectory, optional
        The training record: when given, the loss is recomputed with the closed forms (sticking
        samples left out, as in training); otherwise ``loss`` keeps the pre-distillation value
        and ``info["loss_recomputed"]`` is False.

    Returns
    -------
    FittedModel
        Same template, method, gain; all curves :class:`SymbolicFittedCurve` with the template's
        gauge re-applied (the anchor curve is 0 at 0; a constant that no unpinned curve can carry
        becomes the offset b). ``info`` keeps the old entries and adds ``post_sr`` (per curve:
        expression, front, timing, criterion), ``loss_before_distillation`` and
        ``post_sr_seconds``.

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.fitting import distill_model
    >>> from charcurves.systems import get_system
    >>> model = cc.fit(get_system("duffing").simulate(), method="poly-cc", options={"degree": 3})
    >>> closed = distill_model(model, sr_options={"generations": 5}, n=100)
    >>> closed.to_sympy(curves=True, digits=3)
    {'f1': 0.3*z, 'f2': z**3 - z}
    """
    t0 = time.perf_counter()
    engine = post_sr_engine(sr_options)
    engine.progress = progress  # a long search reports that it runs (the CLI prints every 2 s)
    ops = operators_option(sr_options)
    curves, fronts = {}, {}
    for i, (name, c) in enumerate(model.curves.items()):
        curves[name], fronts[name] = distill_curve_front(c, engine, n=n, random_state=int(random_state) + 1000 * i,
                                              operators=ops)
    if traj is not None and traj.has_derivatives:
        _guard_data_loss(model, curves, fronts, traj)
    raw0 = {k: float(c.raw(np.array([0.0]))[0]) for k, c in curves.items()}
    pinned = {k: c.pinned_at_zero for k, c in curves.items()}
    scalars = model.scalars
    before = {0: float(model.offset), **{e: scalars.get(f"b{e + 1}", 0.0)
                                         for e in range(1, model.template.n_equations)}}
    shifts, new_off = model.template.normalise(raw0, pinned, before)
    for k, c in curves.items():
        c.shift = shifts[k]
    offset = float(new_off.get(0, 0.0))
    info = dict(model.info)
    if model.template.is_general:
        info["scalars"] = {**scalars, **{f"b{e + 1}": float(v) for e, v in new_off.items() if e > 0}}
    info["gauge_conditions"] = model.template.gauge_conditions(pinned)
    info["loss_before_distillation"] = float(model.loss)
    info["post_sr"] = {k: c.meta for k, c in curves.items()}
    info["post_sr_seconds"] = time.perf_counter() - t0
    loss = float(model.loss)
    if traj is not None and traj.has_derivatives:
        new = FittedModel(model.template, model.method, curves, model.gain, offset, loss, info)
        mask = ~sticking_mask(traj)
        r = np.asarray(new.force_residual(traj))[mask]
        loss = float(np.mean(r**2))
        info["loss_recomputed"] = True
    else:
        info["loss_recomputed"] = False
    out = FittedModel(model.template, model.method, curves, model.gain, offset, loss, info)
    if traj is not None and traj.has_derivatives:  # the constants' posterior (._post_sr_posterior)
        from ._post_sr_posterior import closed_form_posterior

        out.posterior = closed_form_posterior(out, traj)
    return out
