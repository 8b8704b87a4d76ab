"""Output error with hidden states: a state-space template fitted to the measured states only.

Equation error cannot run on a hidden state (it has no data), so the fit starts without it. The
template's ODE (:class:`~charcurves.templates.ForwardModel`) is integrated by the multiple-shooting
problem of output error (:class:`~._shooting.ShootingProblem`); the measured states are its output,
every segment's initial state (hidden entries included) is a parameter tied to the previous
segment's end by continuity residuals, and the gauges of the hidden states
(:class:`~charcurves.templates.StateSpace`) are fixed: a hidden offset by an initial value held
fixed or by curves anchored at 0, a hidden scale by the gain held fixed.

The start (``start``):

* ``"growing"``: ``n_starts`` seeded starts (rows of one batched Levenberg-Marquardt), each with
  linear curves of random slopes (the sign of a curve of its own equation's state chosen
  restoring); the segments grow from 16 samples to the whole record (``schedule``), each stage
  starting from the previous one's curves and its simulated states at the new segment starts.
* ``"linear"``: the same stages, the first two with every curve linear (a linear state-space model),
  then the full curves.

After each stage the curves are re-expressed on the range their (hidden) arguments now visit (exact
for polynomial bases). The best row by data loss is the model.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from .._errors import ConfigError, DataError
from ..objectives import choose_substeps
from ._curves import _Curve, _pinned, _representations
from ._model import StateSpaceModel, build_problem, record_table, simulate_states

__all__ = ["fit_state_space", "START_NAMES"]

#: The starts :func:`fit_state_space` offers (module docstring).
START_NAMES = ("growing", "linear")


def fit_state_space(template, record, *, start: str = "growing", n_starts: int = 4, seed: int = 0, degree: int = 10,
                    schedule=None, substeps: int | None = None, hold: str = "linear", max_iter: int = 40,
                    continuity: float = 10.0, time_budget: float = 600.0, progress=None,
                    extrapolation: str = "polynomial", post_sr: bool = False,
                    sr_options: dict | None = None) -> StateSpaceModel:
    """Fit a :class:`~charcurves.templates.StateSpace` template with hidden states by output error.

    Parameters
    ----------
    template : StateSpace
        The template, its measured map and curve representations (unset: polynomials of ``degree``,
        default 10 as :class:`~charcurves.curves.Polynomial`; curves anchored at 0 get a basis
        without a constant; :class:`~charcurves.curves.Neural` curves run the stages as such
        polynomials and then a stage of their own, :mod:`._neural`).
    record : Trajectory or MultiTrajectory
        Uniformly sampled; the measured map names its columns (``x`` of a Trajectory, ``x1``... of
        a MultiTrajectory) and the template's forcings must be among its columns.
    start : {"growing", "linear"}
        How the fit starts without equation error (module docstring); ``info["start"]`` reports it.
    n_starts, seed : int
        Seeded starts, trained together; the best one is kept.
    schedule : sequence of int, optional
        Segment lengths of the stages (default 16, 64, 256, capped by the record's length).
    substeps : int, optional
        RK4 steps per sample (default: output error's choice from the measured signal's spectrum).
    max_iter : int
        Levenberg-Marquardt iterations per stage.
    time_budget : float
        Seconds; a stage past it is the last. The stage of the networks and post-SR's refit each
        get at least a quarter of it.
    progress : callable, optional
        Called with one line after each stage.
    extrapolation : {"polynomial", "linear"}
        ``"linear"``: polynomial curves continue as their tangent line outside the range they were
        fitted on (:class:`~charcurves.curves.ContinuedPolynomial`), so a free run past that range
        does not grow like ``s**degree``; about 3x the CPU time (measured on a 300-sample two-tank fit).
    post_sr : bool
        Distil each curve of the best start into a closed form and refit the constants by output
        error (:mod:`._post_sr`; ``info["post_sr"]``). ``sr_options``: as
        :func:`~charcurves.fitting.distill_model`'s.

    Returns
    -------
    StateSpaceModel

    Notes
    -----
    Ctrl-C (KeyboardInterrupt) stops the fit and keeps the best model so far: the trainer's best
    weights of the stage it interrupts, or the last finished stage (``info["interrupted"]``); an
    interrupt before the first stage finished is raised.

    Examples
    --------
    >>> from charcurves.systems import TwoTank
    >>> from charcurves.templates import StateSpace
    >>> from charcurves.fitting import fit_state_space
    >>> record = TwoTank().simulate(n_points=81, t_end=160.0, seed=0)
    >>> template = StateSpace("x1' = g*F - f1(x1); x2' = f1(x1) - f2(x2)", measured={"x2": "x"})
    >>> model = fit_state_space(template, record, n_starts=1, degree=2, schedule=(16,), max_iter=5, substeps=1)
    >>> model.info["start"], model.info["hidden"], model.info["gauge_conditions"]
    ('growing', ['x1'], ['x1(t0) = 0'])
    """
    started, cpu_started = time.perf_counter(), time.process_time()
    if start not in START_NAMES:
        raise ConfigError(f"unknown start {start!r}; choose one of {', '.join(START_NAMES)}")
    if not hasattr(template, "analysis"):
        raise ConfigError("fit_state_space needs a StateSpace template, e.g. StateSpace(\"x1' = g*F - f1(x1); "
                          "x2' = f1(x1) - f2(x2)\", measured={'x2': 'x'})")
    structure = template.structure()
    from ..templates import ForwardModel

    fm = ForwardModel(structure)
    if extrapolation not in ("polynomial", "linear"):
        raise ConfigError(f"unknown extrapolation {extrapolation!r}; choose 'polynomial' or 'linear'")
    continued = extrapolation == "linear"
    from ._neural import check_anchors, curve_kind, split_representations, with_domain

    # networks (targets) run the stages as polynomials, then one stage of their own (._neural)
    reps, targets = split_representations(template, structure, degree, continued, lambda given: _representations(
        template, structure, degree, continued, given))
    pinned_of = {n: bool(targets[n].pinned_at_zero if n in targets else r.pinned_at_zero) for n, r in reps.items()}
    analysis = template.analysis({n: p or n in structure.anchors for n, p in pinned_of.items()}, structure)
    anchored = set(analysis.anchored) | set(structure.anchors)
    check_anchors(targets, anchored)
    for n in anchored | {n for n, p in pinned_of.items() if p}:
        if not reps[n].pinned_at_zero:
            reps[n] = _pinned(degree, continued)
    cols, dt = record_table(record, analysis.measured, structure.forces)
    n = len(cols["t"])
    if n < 16:
        raise DataError(f"the record has {n} samples, too few for output error; give at least 16")
    sub = int(substeps or choose_substeps(cols[next(iter(analysis.measured.values()))]))
    sched = [min(int(L), n) for L in (schedule or (16, 64, 256))]
    rng = np.random.default_rng(seed)
    B = int(n_starts)
    data_state = _measured_layout(fm, cols, analysis.measured, dt)  # (n, D) with NaN for hidden entries
    scale = np.array([np.nanstd(data_state[:, d]) if np.isfinite(data_state[:, d]).any() else np.nan
                      for d in range(fm.n_state)])
    scale = _hidden_scales(fm, cols, scale, float(structure.gain))
    typical = float(np.nanmean(scale[np.isfinite(scale)])) if np.isfinite(scale).any() else 1.0
    scale = np.where(np.isfinite(scale) & (scale > 0), scale, typical)
    tau = _time_scale(cols, analysis.measured)
    shared = _start_shared(fm, structure, reps, analysis, scale, tau, rng, B, start, data_state)
    scalars = _start_scalars(fm, structure, scale, tau, rng, B)  # name -> (B,)
    gain = np.full(B, float(structure.gain))
    # the start's free run gives the hidden states' first guess
    traj = simulate_states(fm, shared, gain, _initial(fm, data_state, analysis, B), cols, dt, sub, hold,
                           scalars=scalars)
    log: list[dict[str, Any]] = []
    stages = [(L, start == "linear" and k < 2) for k, L in enumerate(sched)]
    kept, interrupted = None, False  # the last finished stage: what Ctrl-C keeps
    for k, (L, linear) in enumerate(stages):
        try:
            shared = [_renormalise(c, traj[..., c.arg_layout] if c.arg_layout is not None else
                                   c.argument_values(fm, traj, cols), linear) for c in shared]
            traj, gain, scalars, loss, iterations, interrupted = _stage(
                fm, structure, shared, gain, scalars, traj, data_state, analysis, cols, dt, sub, hold, L, max_iter,
                continuity, scale, started + time_budget)
        except KeyboardInterrupt:  # outside the trainer (which keeps its best weights itself)
            if kept is None:
                raise
            shared, traj, gain, scalars, loss = kept
            log[-1]["stopped"], interrupted = "interrupted", True
            break
        kept = (shared, traj, gain, scalars, loss)
        log.append({"segment_length": int(L), "linear_curves": bool(linear),
                    "loss": [float(v) for v in loss], "lm_iterations": iterations,
                    "seconds": time.perf_counter() - started})
        try:  # a signal sent when this line is read can land before the print returns: the stage is kept
            if progress is not None:
                progress(f"stage {k + 1}/{len(stages)}: segments of {int(L)} samples, best loss "
                         f"{float(np.min(loss)):.4g}")
        except KeyboardInterrupt:
            interrupted = True
        if interrupted:
            log[-1]["stopped"] = "interrupted"
            break
        if time.perf_counter() - started > time_budget and k < len(stages) - 1:
            log[-1]["stopped"] = "time budget"
            break
    def arg(c, tr):  # a curve's argument along the states tr (B, n, D)
        return tr[..., c.arg_layout] if c.arg_layout is not None else c.argument_values(fm, tr, cols)

    def run(curves, g, sc, tr, iters=max_iter):  # one more stage at the last segment length
        curves = [with_domain(c, arg(c, tr)) for c in curves]
        return _stage(fm, structure, curves, g, sc, tr, data_state, analysis, cols, dt, sub, hold, sched[-1], iters,
                      continuity, scale, max(started + time_budget, time.perf_counter() + 0.25 * time_budget))

    if targets and not interrupted:
        from ._neural import network_stage

        shared, traj, gain, scalars, loss, interrupted = network_stage(run, arg, shared, targets, traj, gain, scalars,
                                                                       loss, seed, log, started, progress)
    best_start, post = None, None
    if post_sr and not interrupted:
        from ._post_sr import post_sr_stage

        best_start = int(np.argmin(np.where(np.isfinite(loss), loss, np.inf)))
        shared = [with_domain(c, arg(c, traj)) for c in shared]  # distilled over the range the states visit
        shared, traj, gain, scalars, loss, interrupted, post = post_sr_stage(
            run, shared, best_start, anchored, traj, gain, scalars, loss, sr_options, seed, log, started, progress)
    finite = np.isfinite(loss)
    if not finite.any():
        raise DataError("the free run of every start diverges; give a shorter record, more starts (n_starts) or "
                        "a template whose states stay bounded")
    best = int(np.argmin(np.where(finite, loss, np.inf)))
    curves = {c.name: c.fitted(best) for c in shared}
    x0 = traj[best, 0].copy()
    info = {"objective": "output-error (hidden states)", "start": start, "n_starts": B, "seed": int(seed), "extrapolation": extrapolation,
            "best_start": best if best_start is None else best_start, "stages": log,
            "representations": {c.name: curve_kind(c) for c in shared}, "hidden": list(analysis.hidden), "measured": dict(analysis.measured),
            "gauge_freedoms": list(analysis.freedoms),
            "gauge_conditions": [f"{a}(0) = 0" for a in sorted(anchored)]
            + [f"{h}(t0) = {v:g}" for h, v in analysis.fixed_initial.items()]
            + (["g fixed"] if analysis.gain_fixed else []),
            "scalars": {k: float(v[best]) for k, v in scalars.items()},
            "substeps": sub, "hold": hold, "seconds": time.perf_counter() - started,
            "cpu_seconds": time.process_time() - cpu_started}
    if interrupted:
        info.update(interrupted=True, stopped_by="interrupted")
    if post is not None:
        info["post_sr"] = post
    model = StateSpaceModel(template, structure, curves, float(gain[best]), dict(zip(fm.layout, x0.tolist())), info)
    try:
        rmse = _measure_free_runs(model, record)
    except KeyboardInterrupt:  # the training had ended: an interrupt while its free runs are measured keeps it
        model.info.update(interrupted=True, stopped_by="interrupted")
        if log:
            log[-1].setdefault("stopped", "interrupted")
        rmse = _measure_free_runs(model, record)
    model.info["warnings"] = [] if all(np.isfinite(v) for v in rmse.values()) else [
        "the free run of the whole record diverges from the fitted initial state (the segments fit, the "
        "model is not stable over the record); give more starts (n_starts), a longer last segment (schedule) "
        "or lower-degree curves"]
    model.info["status"] = "ok" if not model.info["warnings"] else "free run diverges"
    return model


# ---------------------------------------------------------------------------------------------- pieces
def _measure_free_runs(model, record) -> dict:
    """The free-run RMSE of the whole record from the default start (the state fitted to its first
    samples) and from the fitted initial state (measured entries as fitted), stored in ``model.info``
    (``free_run_start`` says which start the first ran from); returns the first."""
    model.info["free_run_start"] = model.start_description("window", len(record.t))
    model.info["free_run_rmse"] = rmse = model.free_run_rmse(record)
    model.info["free_run_rmse_fitted_start"] = model.free_run_rmse(record, initial=model.initial_state)
    return rmse


def _measured_layout(fm, cols, measured, dt):
    """The ODE state from the data: measured positions and their finite-difference derivatives
    (NaN for hidden entries)."""
    n = len(cols["t"])
    out = np.full((n, fm.n_state), np.nan)
    for d, name in enumerate(fm.layout):
        base, _, k = name.partition("__d")
        if base in measured:
            x = np.asarray(cols[measured[base]], dtype=float)
            for _ in range(int(k or 0)):
                x = np.gradient(x, dt)
            out[:, d] = x
    return out


def _hidden_scales(fm, cols, scale, gain: float):
    """A hidden state that enters an equation as a known linear term beside a forcing (Bouc-Wen's
    ``+ x2 = g*F``) has that forcing's size: its scale is ``|gain| std(F) / |coefficient|``."""
    import sympy as sp

    scale = scale.copy()
    for d, name in enumerate(fm.layout):
        if np.isfinite(scale[d]):
            continue
        for eq in fm.equations:
            force = str(eq["input"].expr)
            sym = [v for v in eq["known0"].expr.free_symbols if str(v) == name] if force in cols else []
            a = sp.diff(eq["known0"].expr, sym[0]) if sym else sp.Integer(0)
            if sym and a.is_number and float(a) != 0 and np.std(cols[force]) > 0:
                scale[d] = abs(gain) * float(np.std(cols[force])) / abs(float(a))
                break
    return scale


def _time_scale(cols, measured) -> float:
    x = np.asarray(cols[next(iter(measured.values()))], dtype=float)
    dt = float(np.median(np.diff(cols["t"])))
    v = np.gradient(x, dt)
    return float(np.std(x) / max(np.std(v), 1e-300)) if np.std(v) > 0 else dt * len(x) / 10


def _initial(fm, data_state, analysis, B):
    y0 = np.where(np.isfinite(data_state[0]), data_state[0], 0.0)
    for h, v in analysis.fixed_initial.items():
        y0[fm.layout.index(h)] = v
    return np.repeat(y0[None], B, axis=0)


def _multiplier_size(m, fm, data_state):
    """The std of a curve's multiplier on the data when it is a signal of measured entries about zero
    mean (None for a number, a one-signed signal or one that needs a hidden state)."""
    import sympy as sp

    expr = sp.sympify(m)
    names = [str(v) for v in expr.free_symbols]
    if not names or not all(n in fm.layout for n in names):
        return None
    cols = [data_state[:, fm.layout.index(n)] for n in names]
    if not all(np.isfinite(c).all() for c in cols):
        return None
    values = np.broadcast_to(sp.lambdify(list(expr.free_symbols), expr, "numpy")(*cols), cols[0].shape)
    size = float(np.std(values))
    # only a signal about zero mean: a constant times it integrates to a bounded state
    return size if size > 0 and abs(float(np.mean(values))) < 0.5 * size else None


def _restoring_sign(m, state, fm, signs):
    """The sign of a constant curve ``c`` in ``state' + m*c = 0`` with ``m = a*v`` (``v`` the velocity
    ``b__d1`` of a measured ``b``) that makes ``state`` (about ``-a*c*b``) restoring where it enters
    ``b``'s equation as a known term of coefficient ``k``: ``-a*c*k > 0``. Else ``signs`` as given."""
    import sympy as sp

    expr = sp.sympify(m)
    for v in expr.free_symbols:
        base, _, order = str(v).partition("__d")
        if order != "1" or not (sp.diff(expr, v)).is_number:
            continue
        for eq in fm.equations:
            h = [w for w in eq["known0"].expr.free_symbols if str(w) == state]
            k = sp.diff(eq["known0"].expr, h[0]) if h else sp.Integer(0)
            if h and k.is_number and float(k) != 0:
                return np.full(signs.shape, -float(np.sign(float(sp.diff(expr, v)) * float(k))))
    return signs


def _start_shared(fm, structure, reps, analysis, scale, tau, rng, B, start, data_state=None):
    """Linear curves of random slopes per start: magnitude from the signals' sizes and time scale,
    the sign restoring where the curve's argument is its own equation's state."""
    import sympy as sp

    out = []
    A_inv = np.asarray(fm.A_inv) if fm.A_inv is not None else np.ones((1, 1))
    for name in structure.curve_names:
        u = structure.argument_exprs[name]
        arg_layout = fm.layout.index(str(u)) if str(u) in fm.layout else None
        size_u = scale[arg_layout] if arg_layout is not None else float(np.mean(scale))
        eqs = [e for e, eq in enumerate(structure.equations) if name in eq.curves]
        e = eqs[0]
        own = [j for j in range(len(fm.top)) if A_inv[j, e] != 0]
        top = fm.top[own[0]] if own else fm.top[0]
        base, _, k = top.partition("__d")
        size_s = scale[fm.layout.index(base)]
        slope = size_s / (size_u * tau ** int(k)) * 10.0 ** rng.uniform(-0.5, 0.5, B)
        m = structure.equations[e].curves[name]
        du = sp.diff(u, sp.Symbol(base, real=True)) if base in str(u) else 0
        try:
            sign = float(np.sign(float(sp.sympify(m)) * float(du))) if du != 0 else 0.0
        except TypeError:
            sign = 0.0
        sign *= float(np.sign(A_inv[own[0], e])) if own else 1.0
        signs = np.full(B, sign) if sign != 0 else rng.choice([-1.0, 1.0], B)
        rep = reps[name]
        pinned = bool(rep.pinned_at_zero)
        center = np.zeros(B)
        half = np.full(B, 2.0 * size_u)
        c = _Curve(name, rep, structure.arguments[name], arg_layout, center, half, None)
        size_m = _multiplier_size(m, fm, data_state) if data_state is not None and not pinned else None
        if size_m is not None and arg_layout is not None and arg_layout == fm.layout.index(base):
            # a curve of its own state times a signal (Bouc-Wen's f4(x2)*x1'): a line through 0 would
            # leave a state that starts at 0 there; start it constant, the state then follows the signal
            level = size_s / (size_m * tau ** int(k)) * 10.0 ** rng.uniform(-0.5, 0.5, B)
            signs = _restoring_sign(m, base, fm, signs)
            c.theta = _project(c, np.zeros((B, 64)), half, lambda z, b: np.full_like(z, signs[b] * level[b]), pinned)
            c.domain = np.stack([-half, half], axis=1)
            out.append(c)
            continue
        c.theta = _project(c, np.zeros((B, 64)), half, lambda z, b: signs[b] * slope[b] * z, pinned)
        c.domain = np.stack([-half, half], axis=1)
        out.append(c)
    return out


def _start_scalars(fm, structure, scale, tau, rng, B) -> dict:
    """Each scalar ``a`` of a term ``a*s`` per start: the size a curve's slope gets (the equation's
    state over the signal's, per time-scale power), the sign restoring where ``s`` is that state."""
    import sympy as sp

    out = {}
    A_inv = np.asarray(fm.A_inv) if fm.A_inv is not None else np.ones((1, 1))
    sizes = dict(zip(fm.layout, scale))
    for name in structure.scalar_names:
        e = next(k for k, eq in enumerate(structure.equations) if name in eq.scalars)
        signal = sp.sympify(structure.equations[e].scalars[name])
        own = [j for j in range(len(fm.top)) if A_inv[j, e] != 0]
        base, _, k = (fm.top[own[0]] if own else fm.top[0]).partition("__d")
        used = [str(v) for v in signal.free_symbols if str(v) in sizes]
        size_sig = float(np.mean([sizes[u] for u in used])) if used else 1.0
        magnitude = sizes[base] / (size_sig * tau ** int(k or 0)) * 10.0 ** rng.uniform(-0.5, 0.5, B)
        slope = sp.diff(signal, sp.Symbol(base, real=True))
        sign = float(np.sign(float(slope))) if slope.is_number and float(slope) != 0 else 0.0
        sign *= float(np.sign(A_inv[own[0], e])) if own else 1.0
        out[name] = (np.full(B, sign) if sign != 0 else rng.choice([-1.0, 1.0], B)) * magnitude
    return out


def _project(curve, _unused, half, fn, pinned):
    """Coefficients (per row) of ``fn(u, row)`` on the curve's basis over ``center +- half``."""
    import torch

    B = half.shape[0]
    zs = np.linspace(-1.0, 1.0, 64)
    phi = curve.param()._features(torch.as_tensor(zs)).numpy()
    theta = np.zeros((B, phi.shape[1]))
    for b in range(B):
        u = curve.center[b] + half[b] * zs
        theta[b] = np.linalg.lstsq(phi, fn(u, b), rcond=None)[0]
    return theta


def _renormalise(c, u, linear):
    """The curve re-expressed on the range its argument visits now (``u``: ``(B, N)``); with
    ``linear`` only its best straight line on that range is kept."""
    import torch

    u = np.where(np.isfinite(u), u, np.nan)
    lo, hi = np.nanmin(u, axis=1), np.nanmax(u, axis=1)
    bad = ~(np.isfinite(lo) & np.isfinite(hi) & (hi > lo))
    lo, hi = np.where(bad, c.center - c.half, lo), np.where(bad, c.center + c.half, hi)
    pinned = bool(c.rep.pinned_at_zero)
    center = np.zeros_like(lo) if pinned else 0.5 * (lo + hi)
    half = np.maximum(np.abs(lo), np.abs(hi)) if pinned else 0.5 * (hi - lo) * 1.05
    zs = np.linspace(-1.0, 1.0, 64)
    phi = c.param()._features(torch.as_tensor(zs)).numpy()
    theta = np.zeros_like(c.theta)
    for b in range(c.theta.shape[0]):
        grid = np.linspace(lo[b], hi[b], 64)
        f = c.values(np.broadcast_to(grid, (c.theta.shape[0], 64)))[b]
        if linear:
            f = np.polyval(np.polyfit(grid, f, 1), grid) if not pinned else grid * (grid @ f) / (grid @ grid)
        z = (grid - center[b]) / half[b]
        theta[b] = np.linalg.lstsq(phi if np.allclose(z, zs) else c.param()._features(torch.as_tensor(z)).numpy(),
                                   f, rcond=None)[0]
    out = _Curve(c.name, c.rep, c.argument, c.arg_layout, center, half, theta)
    out.domain = np.stack([lo, hi], axis=1)
    return out


def _stage(fm, structure, shared, gain, scalars, traj, data_state, analysis, cols, dt, sub, hold, L, max_iter,
           continuity, scale, deadline):
    """One stage of multiple shooting with segments of ``L`` samples; returns the simulated states
    ``(B, n, D)``, the gains, the data losses, the Levenberg-Marquardt iterations and whether Ctrl-C
    stopped the trainer."""
    import torch

    from ..train import train

    B, n, D = traj.shape
    count = max(1, int(round((n - 1) / (L - 1))))
    L = (n - 1) // count + 1
    starts = np.arange(count) * (L - 1)
    S = starts.size
    T = lambda a: torch.as_tensor(np.asarray(a, dtype=float), dtype=torch.float64)  # noqa: E731
    out_states = list(analysis.measured)
    out_index = [fm.layout.index(s) for s in out_states]
    meas = np.stack([data_state[starts[:, None] + np.arange(L)[None, :], d] for d in out_index], axis=-1)
    free_gain = structure.free_gain and not analysis.gain_fixed
    specs = [(c.name, c.param(), c.center, c.half, np.zeros(B)) for c in shared]
    problem = build_problem(fm, structure, specs, free_gain, float(structure.gain), cols, dt, sub, hold, starts, L,
                            out_index, meas, scale, continuity, scalars=list(scalars))
    parts = [T(c.theta) for c in shared] + [T(v[:, None]) for v in scalars.values()]
    if free_gain:
        parts.append(T(gain[:, None]))
    y0 = traj[:, starts, :].copy()  # (B, S, D)
    y0[:, 0, [fm.layout.index(s) for s in out_states]] = data_state[0, out_index]
    for h, v in analysis.fixed_initial.items():
        y0[:, 0, fm.layout.index(h)] = v
    parts.append(T(y0.reshape(B, -1)))
    theta0 = torch.nan_to_num(torch.cat(parts, dim=1), nan=0.0)
    frozen = torch.zeros(problem.n_params, dtype=torch.bool)
    for h in analysis.fixed_initial:
        frozen[problem.n_shared + fm.layout.index(h)] = True
    problem.frozen = frozen if bool(frozen.any()) else None
    theta, tlog = train(problem, theta0, adam_steps=0, adam_lr=0.0, lm_max_iter=int(max_iter), lm_tol=1e-6,
                        stop_loss=0.0, lm_window=4, lm_deadline=deadline, lm_nielsen=True)
    with torch.no_grad():
        loss = problem.residuals(theta)[:, :problem.n_data].pow(2).sum(dim=1).numpy()
    th = theta.double().numpy()
    for i, c in enumerate(shared):
        o = problem.block_offsets[i]
        c.theta = th[:, o:o + c.theta.shape[1]].copy()
    if free_gain:
        gain = th[:, problem.gain_index].copy()
    scalars = {k: th[:, problem.scalar_index[k]].copy() for k in scalars}
    new_traj = simulate_states(fm, shared, gain, th[:, problem.n_shared:problem.n_shared + D], cols, dt, sub, hold,
                               segments=(th[:, problem.n_shared:].reshape(B, S, D), starts, L), scalars=scalars)
    return (new_traj, gain, scalars, np.where(np.isfinite(loss), loss, np.inf), int(tlog.lm_iterations),
            bool(tlog.interrupted))
