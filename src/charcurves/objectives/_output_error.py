"""Output-error training of any fitted model: every representation, every template with a forward model.

The equation-error fit is the start; the curves' parameters (neural weights, polynomial and sparse
coefficients, the constants of closed forms), the unknown scalars, the equations' free constants,
the gain (when free) and the initial state of every shooting segment are refitted to the measured
positions by batched Levenberg-Marquardt (:mod:`._shooting` gives the exact Jacobian). Each
ensemble member of a neural fit trains as its own row, and the members whose loss is within the
preset's tolerance of the best are averaged, as in equation error. A learned jump (dry friction)
trains with its width held at a floor that fixed-step RK4 can integrate, and gets its sharp
width back afterwards. When the free run cannot be simulated or does not improve, the
equation-error model is kept and ``info["output_error"]["status"]`` says why.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from .._errors import ConfigError, DataError
from ..model import finish_model
from ..train import RELEVANCE_LABEL, train
from ._free_run import _free_run_rmse, _uniform_step, free_run_diagnostics
from ._records import common_step, record_segments
from ._revive import network_pruned, revival_needed, revive_pruned_networks

__all__ = ["free_run_diagnostics", "output_error_fit", "choose_substeps",
           "choose_segment_length", "slow_template"]


def choose_substeps(x: np.ndarray) -> int:
    """RK4 steps per sample: enough for 20 steps per period of the highest frequency below which
    99 % of the signal's spectral power lies (RK4 local error about (2 pi / 20)^5 / 120 = 3e-5 of the
    state per step): 1 at the paper's 130 samples per period, 4 at 5."""
    x = np.asarray(x, dtype=float) - float(np.mean(x))
    power = np.abs(np.fft.rfft(x)) ** 2
    if power.size < 3 or power.sum() == 0:
        return 1
    cum = np.cumsum(power) / power.sum()
    k = int(np.searchsorted(cum, 0.99))
    samples_per_period = len(x) / max(k, 1)
    return int(min(8, max(1, math.ceil(20.0 / samples_per_period))))


def choose_segment_length(n: int) -> int:
    """Samples per shooting segment: 64 (long enough to see the dynamics, short enough that a
    start from the equation-error fit stays close; docs/measured-records.md), fewer on short records."""
    return int(max(16, min(64, (n - 1) // 4 + 1)))


def _segments(n: int, L: int, max_segments: int):
    """Segment length, starts (consecutive segments share their end sample, the record is cut into
    ``round((n - 1) / (L - 1))`` equal segments) and which consecutive pairs abut."""
    if n < 16:
        raise ConfigError(f"the record has {n} samples, too few for output error; give at least 16")
    count = max(1, int(round((n - 1) / (L - 1))))
    L = (n - 1) // count + 1
    starts = np.arange(count) * (L - 1)
    if count > max_segments:
        pick = np.unique(np.round(np.linspace(0, count - 1, max_segments)).astype(int))
        starts = starts[pick]
    contiguous = np.diff(starts) == L - 1
    return L, starts, contiguous


def _stage_arrays(signal, starts, L, substeps, hold, dtype):
    import torch

    from ..data import stage_inputs

    ua, um, ub = stage_inputs(np.asarray(signal, dtype=float), substeps, hold)
    idx = starts[None, :] * substeps + np.arange((L - 1) * substeps)[:, None]
    return tuple(torch.as_tensor(a[idx], dtype=dtype) for a in (ua, um, ub))


def _positions(record, positions) -> dict:
    """The measured position columns (x, or x1, x2, ...) of a record."""
    from ..data import Trajectory

    if isinstance(record, Trajectory):
        return {"x": np.asarray(record.x, dtype=float)}
    return {p: np.asarray(record.states[p], dtype=float) for p in positions}


def output_error_fit(model, prepared, measured, settings: Any, *, preset, progress=None, strict: bool = False,
                     revive: bool | None = None):
    """Output error of one fitted model on its record (module docstring).

    Parameters
    ----------
    model : FittedModel
        The equation-error fit (or post-SR model) to start from.
    prepared : Trajectory or MultiTrajectory
        The record with the derivatives the fit used (their smoothed states start the segments).
    measured : Trajectory or MultiTrajectory
        The record as measured (its positions are the output that is fitted).
    settings : OutputError
    strict : bool
        Raise (ConfigError/DataError) when output error cannot run on this model or record, instead of
        keeping the equation-error model with the reason in ``info`` (the fallback of ``objective="auto"``).
    preset : TrainingPreset
        Its ``combine`` and ``combine_tol`` decide which ensemble members are averaged.
    revive : bool, optional
        Whether networks that equation error pruned restart small (``objectives/_revive.py``). Unset:
        output error runs without reviving them, and again with them revived where that first run
        ends above the noise of the measured positions (``info["output_error"]["revival"]`` says
        which, with the ratio).

    Returns
    -------
    FittedModel
        The refitted model, or the input model when output error is not possible or does not
        improve; ``info["output_error"]`` says what happened either way.

    Examples
    --------
    >>> from charcurves.data import corrupt
    >>> from charcurves.fitting import CharacteristicCurves, OutputError, get_preset, output_error_fit, raw_fit
    >>> from charcurves.systems import get_system
    >>> measured = corrupt(get_system("duffing").simulate(t_end=20.0, n_points=500), 30, on="state", seed=0)
    >>> [start], [prepared] = raw_fit(CharacteristicCurves.from_method(method="parametric", basis="f1=z; f2=z, z**3"), [measured])
    >>> settings = OutputError(segment_length=16, substeps=1, max_iter=2)  # a short run
    >>> model = output_error_fit(start, prepared, measured, settings, preset=get_preset("default"))
    >>> model.info["output_error"]["status"], model.curves["f2"].coefficients.round(2).tolist()
    ('ok', [-1.0, 1.0])
    """
    if revive is None:  # first without reviving pruned networks; again with them where that ends above the noise
        info, warnings = dict(model.info), list(model.info.get("warnings", []))
        first = output_error_fit(model, prepared, measured, settings, preset=preset, progress=progress, strict=strict,
                                 revive=False)
        again, why = revival_needed(first.info.get("output_error") or {}, measured)
        if again and not first.info.get("interrupted"):  # after Ctrl-C, nothing more runs
            if first is model:  # a kept start carries the first run's status: the second starts clean
                model.info.clear()
                model.info.update(info)
                if warnings or "warnings" in info:
                    model.info["warnings"] = list(warnings)
            second = output_error_fit(model, prepared, measured, settings, preset=preset, progress=progress,
                                      strict=strict, revive=True)
            if (second.info.get("output_error") or {}).get("status", "").startswith("ok"):
                second.info["output_error"]["revival"] = why
                return second
        if why:
            first.info["output_error"]["revival"] = why
        return first
    import torch

    from ..curves import jump_log_eps, trainable
    from ..templates import ForwardModel, record_columns
    from ._shooting import CurveBlock, ShootingProblem

    started = time.perf_counter()
    template = model.template
    report: dict[str, Any] = {"objective": "output-error", "hold": settings.hold}
    bounds = getattr(measured, "bounds", None)  # a RecordSet: several records, segments within each
    try:
        fm = ForwardModel(template)
        dt = _uniform_step(measured) if bounds is None else common_step(measured.records, _uniform_step)
        measured = measured if bounds is None else measured.joined
        refits = {name: trainable(model.curves[name]) for name in template.curve_names}
    except (ConfigError, DataError) as exc:
        if strict:
            raise
        return _kept(model, report, f"not run: {exc}")
    dtype = torch.float64
    n = measured.n_samples
    L = int(settings.segment_length or choose_segment_length(n))
    L = min(L, n)
    positions = [s for s in fm.layout if "__d" not in s]
    meas_cols = _positions(measured, positions) if _has_columns(measured, positions) else None
    prep_cols = record_columns(prepared, template)
    substeps = int(settings.substeps or choose_substeps(np.asarray(prep_cols[positions[0]])))
    L, starts, contiguous = _segments(n, L, int(settings.max_segments)) if bounds is None else \
        record_segments(bounds, L, int(settings.max_segments), _segments)
    S = starts.size
    M = max(r.theta.shape[0] for r in refits.values())
    pinned = {nm: bool(model.curves[nm].pinned_at_zero) for nm in template.curve_names}
    offsets = template.anchored_offsets(pinned) if template.n_equations == 1 or template.is_general else []
    offsets = sorted(set(offsets) | ({0} if model.offset != 0.0 else set()))
    scalars = list(template.scalar_names)
    T = lambda a: torch.as_tensor(np.asarray(a, dtype=float), dtype=dtype)  # noqa: E731
    col = lambda v: torch.full((M, 1), float(v), dtype=dtype)  # noqa: E731
    blocks, parts = [], []
    restore, revived, free_width, pruned = {}, {}, {}, []
    for name in template.curve_names:
        rf = refits[name]
        theta_c = np.repeat(rf.theta, M // rf.theta.shape[0] + 1, axis=0)[:M] if rf.theta.shape[0] != M else rf.theta
        theta_c = np.array(theta_c, dtype=float)
        if revive:  # a network equation error pruned restarts small (._revive): output error cannot reopen it alone
            theta_c, back = revive_pruned_networks(rf.param, theta_c,
                                                   _seed(model) * 7919 + template.curve_names.index(name))
            if back.any():
                revived[name] = int(back.sum())
        elif network_pruned(rf.param, theta_c):
            pruned.append(name)
        frozen = []
        sl = rf.param.slices() if hasattr(rf.param, "slices") else {}
        if "jump_log_eps" in sl:  # train with a width RK4 integrates; the learned one comes back afterwards
            j = sl["jump_log_eps"].start
            floor = _smooth_jump_raw(rf, substeps, dt)
            if np.any(np.asarray(jump_log_eps(theta_c[:, j])) > floor + SMOOTH_JUMP_MARGIN):
                # equation error profiled a width above RK4's floor: a smooth saturation (tanh friction) or a
                # step that the differentiator smoothed. The free run decides: the width is trained from there
                # (never below the floor: a step that would need it is refused as it diverges), and a width that
                # ends within the margin of the floor is Coulomb's sign afterwards
                theta_c[:, j] = np.maximum(theta_c[:, j], floor)
                free_width[name] = (j, floor)
            else:  # Coulomb's sign: trained at the floor, the sharp step afterwards
                restore[name] = np.full(theta_c.shape[0], -60.0)
                theta_c[:, j] = floor
                frozen.append(j)
        param = rf.param if rf.param.decay_groups() or not settings.bayesian else _Ridge(rf.param)
        blocks.append(CurveBlock(name, param, col(rf.center), col(rf.half_width), col(rf.out_scale), col(rf.shift),
                                 frozen))
        parts.append(T(theta_c))
    sc = model.scalars
    for s in scalars:
        parts.append(col(sc.get(s, 0.0)))
    for e in offsets:
        parts.append(col(model.offset if e == 0 else sc.get(f"b{e + 1}", 0.0)))
    if template.free_gain:
        parts.append(col(model.gain))
    y0 = np.stack([np.asarray(prep_cols[name], dtype=float)[starts] for name in fm.layout], axis=1)  # (S, D)
    parts.append(T(y0.reshape(1, -1)).expand(M, -1))
    theta0 = torch.cat(parts, dim=1)
    source = meas_cols if meas_cols is not None else prep_cols
    meas = np.stack([np.asarray(source[p], dtype=float)[starts[:, None] + np.arange(L)[None, :]] for p in positions],
                    axis=-1)  # (S, L, O)
    inputs = {f: _stage_arrays(prep_cols[f], starts, L, substeps, settings.hold, dtype) for f in template.forces}
    t = np.asarray(prep_cols["t"], dtype=float)
    frac = np.arange((L - 1) * substeps) / substeps
    t_idx = starts[None, :] + np.floor(frac).astype(int)[:, None]
    tt = t[t_idx] + (frac - np.floor(frac))[:, None] * dt
    h = dt / substeps
    times = tuple(T(tt + c * h) for c in (0.0, 0.5, 1.0))
    scales = T([max(float(np.std(np.asarray(prep_cols[name], dtype=float))), 1e-12) for name in fm.layout])
    problem = ShootingProblem(fm, blocks, scalars, offsets, template.free_gain, template.gain, inputs, times, T(meas),
                              [fm.layout.index(p) for p in positions], scales, dt, substeps, settings.continuity,
                              torch.as_tensor(contiguous, dtype=torch.bool), weight_decay=1e-10,
                              bayesian=bool(settings.bayesian), decay_groups=preset.decay_groups)
    with torch.no_grad():
        loss0 = problem.residuals(theta0)[:, :problem.n_data].pow(2).sum(dim=1)  # the data part only
        X0, _, _ = problem.simulate(theta0, need_jac=False)  # the free run just done (remembered)
    if not bool(torch.isfinite(loss0).any()):
        return _kept(model, report, "failed: the free run of the equation-error model diverges on every segment")
    slow = slow_template(fm)
    max_iter = int(settings.max_iter) if settings.max_iter is not None else (120 if slow else 40)
    theta, log = train(problem, theta0, adam_steps=0, adam_lr=0.0, lm_max_iter=max_iter,
                       lm_tol=float(settings.tol), stop_loss=0.0, progress=progress, lm_window=STOP_WINDOW,
                       lm_deadline=time.monotonic() + float(settings.time_budget) - (time.perf_counter() - started),
                       lm_nielsen=slow, evidence_sweeps=EVIDENCE_SWEEPS)
    for i, name in enumerate(template.curve_names):
        if name in free_width:  # a trained width near RK4's floor is Coulomb's sign; a wider one is kept
            j, floor = free_width[name]
            trained = theta[:, problem.block_offsets[i] + j].double().numpy()
            restore[name] = np.where(np.asarray(jump_log_eps(trained)) <= floor + SMOOTH_JUMP_MARGIN, -60.0, trained)
    with torch.no_grad():
        # members are compared by their fit to the record (the data rows), not by their decay rows
        loss = problem.residuals(theta)[:, :problem.n_data].pow(2).sum(dim=1).double().numpy()
        X1, _, _ = problem.simulate(theta, need_jac=False)
    finite = np.isfinite(loss)
    if not finite.any():
        return _kept(model, report, "failed: the free run diverged during training")
    loss = np.where(finite, loss, np.inf)
    members, best, crit = _members(loss, log.effective_parameters, problem.n_data, preset)
    rows = theta.double().numpy()[members]
    curves = {}
    for i, name in enumerate(template.curve_names):
        o = problem.block_offsets[i]
        th = rows[:, o:o + blocks[i].n_params].copy()
        if name in restore:
            th[:, refits[name].param.slices()["jump_log_eps"].start] = restore[name][members]
        curves[name] = refits[name].rebuild(th)
    new_scalars = {s: float(rows[:, problem.scalar_index[s]].mean()) for s in scalars}
    offs = {e: float(rows[:, problem.offset_index[e]].mean()) for e in offsets}
    gain = float(rows[:, problem.gain_index].mean()) if template.free_gain else float(model.gain)
    if not np.isfinite(gain) or gain == 0.0:
        return _kept(model, report, "failed: the gain became zero or not finite")
    labels = [lab for name in template.curve_names for lab in refits[name].labels] + list(scalars)
    labels += [("b" if e == 0 else f"b{e + 1}") for e in offsets] + (["g"] if template.free_gain else [])
    order = list(range(problem.n_shared))
    if template.free_gain and offsets:  # the older report's order: ..., g, b
        order = order[:-1 - len(offsets)] + [int(problem.gain_index or 0)] + order[-1 - len(offsets):-1]
        labels = labels[:-1 - len(offsets)] + ["g"] + labels[-1 - len(offsets):-1]
    raw = np.ones(problem.n_shared)  # the curves' own coefficients from the trained ones (monomials of z / h)
    for i, name in enumerate(template.curve_names):
        if refits[name].unscale is not None:
            o = problem.block_offsets[i]
            raw[o:o + blocks[i].n_params] = refits[name].unscale
    seg_before = float(np.sqrt(np.mean((X0.double().numpy() - meas[None]) ** 2)))
    seg_after = float(np.sqrt(np.mean((X1.double().numpy()[members] - meas[None]) ** 2)))
    info = dict(model.info)
    info["loss_equation_error_before"] = float(model.loss)
    report.update({
        "segment_length": L, "segments": int(S), "contiguous_pairs": int(contiguous.sum()),
        "substeps": substeps, "continuity": float(settings.continuity), "members": int(members.size),
        "iterations": log.lm_iterations, "max_iter": max_iter, "stopped_by": log.stopped_by,
        "evidence_sweeps_undone": log.sweeps_undone,
        "networks_revived": revived,
        "pruned_networks": pruned,
        "damping": "nielsen" if slow else "fixed factors",
        "segmented_rmse_before": seg_before, "segmented_rmse_after": seg_after,
        "loss_before": float(loss0.double().min()), "loss_after": float(loss[best]),
        "member_selection": "AIC within 2 (Bayesian effective parameters)" if crit is not None else
        f"data loss within {preset.combine_tol:g} of the best",
        "output": "measured positions" if meas_cols is not None else "smoothed positions (no raw columns)",
        "parameters": labels,
        "coefficients_before": (theta0.double().numpy()[:, :problem.n_shared] * raw)[:, order].mean(axis=0).tolist(),
        "coefficients_after": (rows[:, :problem.n_shared] * raw)[:, order].mean(axis=0).tolist(),
    })
    if log.interrupted:
        info["interrupted"] = True
    new = finish_model(template, model.method, curves, gain, offs, new_scalars, prepared, info, None)
    if not seg_after <= seg_before * (1 + 1e-9):
        return _kept(model, report, "failed: the free run did not improve; kept the equation-error model")
    # the Laplace posterior (._posterior_oe); the equation-error fit's own warnings about its posterior go
    if "warnings" in new.info:
        new.info["warnings"] = [w for w in new.info["warnings"] if not w.startswith("uncertainty:")]
        if not new.info["warnings"]:
            del new.info["warnings"]
    if not log.interrupted:
        from ._posterior_oe import output_error_posterior

        output_error_posterior(new, problem, theta, members, {
            problem.block_offsets[i] + refits[nm].param.slices()["jump_log_eps"].start: restore[nm]
            for i, nm in enumerate(template.curve_names) if nm in restore})
    y_first = rows[:, problem.n_shared:problem.n_shared + fm.n_state].mean(axis=0)
    if bounds is not None:  # each record's own first state; one free run per record (no run across a join)
        firsts = [int(np.searchsorted(starts, a)) for a, _ in bounds]
        y_all = rows[:, problem.n_shared:].reshape(rows.shape[0], S, fm.n_state).mean(axis=0)
        report["record_initial_states"] = [y_all[i].tolist() for i in firsts]
        report["initial_state"] = report["record_initial_states"][0]
        report["records"] = len(bounds)
        report["status"] = "interrupted" if log.interrupted else "ok"
        report["seconds"] = time.perf_counter() - started
        new.info["output_error"] = report
        new.info["objective"] = "output-error"
        return new
    report["free_run_rmse_before"] = _free_run_rmse(model, measured, meas_cols, y_first, settings.hold, substeps)
    report["free_run_rmse_after"] = _free_run_rmse(new, measured, meas_cols, y_first, settings.hold, substeps)
    report["initial_state"] = y_first.tolist()
    report["status"] = "interrupted" if log.interrupted else "ok"
    report["seconds"] = time.perf_counter() - started
    new.info["output_error"] = report
    new.info["objective"] = "output-error"
    return new


def slow_template(fm) -> bool:
    """True when a curve of the template is multiplied by a state (van der Pol's ``f1(x) x'``, the
    first-order family's ``f2(x) x'``) or the template couples several equations (two-DOF): there
    the output-error fit converges slowly, and gets more iterations and Nielsen's damping (see
    :class:`OutputError`; docs/measured-records.md has the measurements)."""
    if fm.divides or len(fm.equations) > 1:  # divides: a curve is a factor of the highest derivative
        return True
    return any(m.constant is None for eq in fm.equations for m in eq["mult"].values())


#: Levenberg-Marquardt stops a member once its loss fell by less than ``OutputError.tol`` (relative)
#: over this many iterations (see :func:`._train.train`).
STOP_WINDOW = 4

#: Evidence sweeps on the linearised problem after each step of a member that has fitted its data
#: (:func:`._train.train`): pruning the spare terms of a polynomial or library curve then takes a
#: few steps instead of some twenty (docs/measured-records.md).
EVIDENCE_SWEEPS = 50

#: Members whose Akaike criterion is within this of the best are averaged (Burnham & Anderson:
#: "substantial support" below 2).
AIC_SUPPORT = 2.0


def _members(loss: np.ndarray, gammas, n_data: int, preset):
    """Which ensemble members to average after output error, and the best one.

    The member of least data loss is not the best: a member can lower the loss by fitting noise
    with more effective parameters (a wiggle where the gauge anchors a curve, a spurious constant),
    by about 1 % on the paper's records. With Bayesian regularisation every member has its number of
    effective parameters gamma, and members are ranked by AIC = n ln(loss) + 2 gamma; those within
    ``AIC_SUPPORT`` of the best are averaged. Without it, the preset's loss tolerance applies.
    """
    if preset.combine != "mean":
        best = int(np.argmin(loss))
        return np.array([best]), best, None
    if gammas and all(g is not None for g in gammas) and len(gammas) == loss.size:
        crit = n_data * np.log(np.maximum(loss, 1e-300)) + 2.0 * np.asarray(gammas, dtype=float)
        crit = np.where(np.isfinite(loss), crit, np.inf)
        best = int(np.argmin(crit))
        return np.flatnonzero(crit <= crit[best] + AIC_SUPPORT), best, crit
    best = int(np.argmin(loss))
    return np.flatnonzero(loss <= loss[best] * (1.0 + preset.combine_tol)), best, None


class _Ridge:
    """A parametrisation whose coefficients form one weight-decay group (the evidence then decides how
    much a polynomial or closed form may bend: Bayesian ridge regression)."""

    def __init__(self, param):
        self._param = param

    def __getattr__(self, name):
        return getattr(self._param, name)

    def decay_groups(self) -> list:
        return [(slice(k, k + 1), f"{RELEVANCE_LABEL}{k + 1}") for k in range(int(self._param.n_params))]


def _has_columns(record, positions) -> bool:
    from ..data import Trajectory

    if isinstance(record, Trajectory):
        return positions == ["x"]
    return all(p in record.states for p in positions)


#: A jump width (log, scaled units) within this of RK4's floor counts as the floor: log(2), a factor 2.
SMOOTH_JUMP_MARGIN = math.log(2.0)


def _smooth_jump_raw(rf, substeps, dt) -> float:
    """Raw width parameter of the narrowest jump fixed-step RK4 integrates stably: the jump acts as a
    damping mu / eps, and RK4 needs (dt / substeps) * mu / eps below ~2, so eps >= mu * h / 2 (in
    units of the curve's scaled argument), and at least 0.2 % of the argument's range."""
    sl = rf.param.slices()
    mu = float(np.max(np.abs(rf.theta[:, sl["jump_height"]]))) * abs(rf.out_scale)
    h = dt / substeps
    eps_data = max(mu * h / 2.0, 2e-3 * rf.half_width)
    return math.log(max(eps_data / rf.half_width, 1e-7))


def _seed(model) -> int:
    """The fit's seed (the revived networks' initialisation draws from it)."""
    seed = model.info.get("seed", 0)
    return int(seed) if isinstance(seed, (int, np.integer)) else 0


def _kept(model, report: dict, status: str):
    report = dict(report)
    report["status"] = status
    model.info["output_error"] = report
    model.info["objective"] = "equation-error (output error " + ("not possible" if status.startswith("not") else
                                                                 "failed") + ")"
    model.info.setdefault("warnings", []).append(f"output error: {status}")
    return model

