"""Output-error refinement of closed-form models: fit the coefficients to the free-run simulation.

Every method of charcurves fits *equation error*: the residual of ``x'' + f1(x') + f2(x) + b = g F``
with estimated derivatives. When the derivatives are biased (few samples per period, smoothing)
or the structure is only approximately right, equation error and simulation disagree, and the
free-run simulation is what a user of the model sees. This module takes a fitted model whose
curves are closed forms (post-SR, parametric, poly-cc, SINDy) and re-estimates all its numeric
coefficients, the gain (when free) and the constant ``b`` by minimising the simulation error
on the estimation record (``scipy.optimize.least_squares``).

Robustness: multiple shooting without continuity constraints ("segmented output error"). The
record is cut into segments of ``segment_length`` samples, each with its own free initial state,
so a poor starting model (or a chaotic system) cannot make the long free run drift away and
trap the optimiser in a local minimum; for a stable system the transient of a wrong initial
state dies out within a few time constants, so segments much longer than that give the same
coefficients as one free run of the whole record. All segments (and the finite-difference
perturbations of the Jacobian) are simulated in one vectorised RK4 run
(:func:`charcurves.simulate.rk4_sampled`).
"""

from __future__ import annotations

import time
import warnings

import numpy as np

from .._errors import ConfigError, DataError

__all__ = ["refine_output_error", "free_run_error", "estimate_initial_state", "check_refine_options", "REFINE_MODES",
           "DEFAULT_OPTIONS"]

#: Values of ``CharacteristicCurves(refine=...)`` / ``--refine``.
REFINE_MODES = ("none", "output-error", "auto")

#: Defaults of ``refine_options`` (see :func:`refine_output_error`).
DEFAULT_OPTIONS = {
    "hold": "linear",
    "substeps": 4,
    "segment_length": 256,
    "max_nfev": 60,
    "time_budget": 600.0,
}

def check_refine_options(options) -> None:
    """Raise :class:`ConfigError` for unknown keys or unusable values of ``refine_options``."""
    from ..simulate._sampled import _check_hold

    if options is None:
        return
    if not isinstance(options, dict):
        raise ConfigError(f"refine_options must be a dict such as {{'hold': 'linear'}}, got {type(options).__name__}")
    unknown = sorted(set(options) - set(DEFAULT_OPTIONS))
    if unknown:
        raise ConfigError(f"unknown refine option {unknown[0]!r}; valid: {', '.join(DEFAULT_OPTIONS)}")
    merged = {**DEFAULT_OPTIONS, **options}
    _check_hold(merged["hold"], merged["substeps"])
    seg = merged["segment_length"]
    if not isinstance(seg, (int, np.integer)) or isinstance(seg, bool) or seg < 16:
        raise ConfigError(f"segment_length must be an integer >= 16 samples, got {seg!r}")
    nfev = merged["max_nfev"]
    if not isinstance(nfev, (int, np.integer)) or isinstance(nfev, bool) or nfev < 1:
        raise ConfigError(f"max_nfev must be a positive integer, got {nfev!r}")
    budget = merged["time_budget"]
    if not isinstance(budget, (int, float)) or isinstance(budget, bool) or not budget > 0:
        raise ConfigError(f"time_budget must be a positive number of seconds, got {budget!r}")


#: Forward-difference step in the scaled parameters (all of order 1).
_FD_STEP = 1e-7


class _BudgetSpent(Exception):
    pass


class _Parametrised:
    """The model with its numeric coefficients turned into a parameter vector.

    Layout of ``theta``: the free coefficients of f1, then of f2, then g (when free), then b.
    Additive constants of the curves stay fixed: they are collinear with b (gauge).
    """

    def __init__(self, model):
        import sympy as sp

        self.model = model
        self.z = sp.Symbol("z")
        self.curve_names = ("f1", "f2")
        self.blocks: dict[str, tuple[int, int]] = {}
        self.labels: list[str] = []
        values: list[float] = []
        self.funcs = {}
        self.rebuild = {}
        for name in self.curve_names:
            curve = model.curves[name]
            start = len(values)
            expr, vals, builder, terms = self._curve_parameters(name, curve)
            syms = [sp.Symbol(f"p{start + i}") for i in range(len(vals))]
            self.funcs[name] = sp.lambdify((self.z, *syms), expr(syms), modules="numpy")
            values += vals
            self.labels += [f"{name}:{term}" for term in terms]
            self.blocks[name] = (start, len(values))
            self.rebuild[name] = builder
        self.free_gain = bool(model.template.free_gain)
        if self.free_gain:
            self.labels.append("g")
            values.append(float(model.gain))
        self.labels.append("b")
        values.append(float(model.offset))
        self.theta0 = np.asarray(values, dtype=float)

    # -------------------------------------------------------------- per curve
    def _curve_parameters(self, name, curve):
        """(expression builder from parameter symbols, start values, curve builder from values, labels).

        A symbolic curve gets one coefficient per additive term (also where it is an implicit 1 or an
        integer, as in ``z**3 - z``) plus every Float inside the terms (``tanh(50.0*z)``); exponents
        and the additive constant stay fixed.
        """
        import sympy as sp

        from ..curves._fitted import BasisFittedCurve, SymbolicFittedCurve

        z = self.z
        if isinstance(curve, BasisFittedCurve):
            exprs = list(curve._exprs)
            shift = sp.Float(curve.shift)

            def expr(syms):
                return sum((s * e for s, e in zip(syms, exprs)), sp.Integer(0)) + shift

            def build(vals):
                return BasisFittedCurve(curve.name, curve.argument, curve.domain, curve.basis, vals, curve.shift)

            return expr, [float(c) for c in curve.coefficients], build, list(curve.basis)
        full = curve.expression()
        if full is None:
            raise ConfigError(
                f"output-error refinement needs closed-form curves, but {name} is a {curve.kind} curve; "
                "use a method with +post-sr, parametric, poly-cc or sindy, or refine='none'"
            )
        if isinstance(curve, SymbolicFittedCurve):
            raw, shift = curve._expr, float(curve.shift)
        else:
            raw, shift = full, 0.0
        const, rest = raw.as_coeff_Add()  # the additive constant stays fixed (collinear with b)
        floats: list[float] = []
        labels: list[str] = []
        terms = []
        for term in sp.Add.make_args(rest) if rest != 0 else ():
            coeff, body = term.as_coeff_Mul()
            holder = sp.Symbol(f"__c{len(floats)}")
            floats.append(float(coeff))
            labels.append(str(body))
            inner = len(floats)
            body = _replace_floats(body, floats)
            labels += [f"{labels[-1]}#{k}" for k in range(len(floats) - inner)]
            terms.append(holder * body)
        template = sp.Add(*terms)

        def expr(syms):
            return template.xreplace(dict(zip(_placeholders(len(floats)), syms))) + const + sp.Float(shift)

        def build(vals):
            new = template.xreplace({p: sp.Float(float(v)) for p, v in zip(_placeholders(len(floats)), vals)})
            return SymbolicFittedCurve(curve.name, curve.argument, curve.domain, new + const, shift,
                                       dict(getattr(curve, "meta", {}) or {}))

        return expr, floats, build, labels

    # -------------------------------------------------------------- evaluation
    def accel(self, theta):
        """``accel(x, v, u)`` for parameters ``theta`` of shape (P,) or (P, K) (K candidates)."""
        a1, b1 = self.blocks["f1"]
        a2, b2 = self.blocks["f2"]
        f1, f2 = self.funcs["f1"], self.funcs["f2"]
        p1 = tuple(theta[a1:b1])
        p2 = tuple(theta[a2:b2])
        g = theta[-2] if self.free_gain else float(self.model.gain)
        b = theta[-1]

        def accel(x, v, u):
            return g * u - f1(v, *p1) - f2(x, *p2) - b

        return accel

    def build(self, theta):
        from ._model import FittedModel

        curves = {}
        for name in self.curve_names:
            a, b = self.blocks[name]
            curves[name] = self.rebuild[name](np.asarray(theta[a:b], dtype=float))
        g = float(theta[-2]) if self.free_gain else float(self.model.gain)
        m = self.model
        return FittedModel(m.template, m.method, curves, g, float(theta[-1]), m.loss, dict(m.info))


def _placeholders(n):
    import sympy as sp

    return [sp.Symbol(f"__c{i}") for i in range(n)]


def _replace_floats(expr, out: list):
    """``expr`` with every Float occurrence (not exponents) replaced by a placeholder ``__c<i>``."""
    import sympy as sp

    if isinstance(expr, sp.Float):
        sym = sp.Symbol(f"__c{len(out)}")
        out.append(float(expr))
        return sym
    if not expr.args:
        return expr
    if isinstance(expr, sp.Pow):
        base, exp = expr.args
        return sp.Pow(_replace_floats(base, out), exp)  # exponents are structure, not coefficients
    return expr.func(*[_replace_floats(a, out) for a in expr.args])


# ------------------------------------------------------------------------------ helpers
def _inputs_for(traj, hold, substeps):
    from ..simulate._sampled import stage_inputs

    traj.require_uniform("output-error refinement (a sampled-input free run)")
    return stage_inputs(np.asarray(traj.F), substeps, hold)


def _velocity(traj) -> np.ndarray:
    if traj.v is not None:
        return np.asarray(traj.v)
    return np.gradient(np.asarray(traj.x), np.asarray(traj.t))


def free_run_error(model, traj, *, hold: str = "linear", substeps: int = 4, x0: float | None = None,
                   v0: float | None = None, time_budget: float = 120.0):
    """Free-run simulation of ``model`` driven by the record's input, and its RMSE against x.

    Parameters
    ----------
    model : FittedModel
    traj : Trajectory
        Uniformly sampled record (x and F).
    hold, substeps : see :func:`charcurves.simulate.simulate_sampled`.
    x0, v0 : float, optional
        Initial state; by default estimated from the first samples (:func:`estimate_initial_state`).

    Returns
    -------
    rmse : float
        Root-mean-square of simulated minus measured x over all samples (inf when the run fails).
    result : SimulationResult
    """
    from ..simulate._sampled import simulate_sampled

    traj.require_uniform("a free-run simulation of a sampled record")
    if x0 is None or v0 is None:
        ex0, ev0 = estimate_initial_state(model, traj, hold=hold, substeps=substeps)
        x0 = ex0 if x0 is None else x0
        v0 = ev0 if v0 is None else v0
    res = simulate_sampled(model, traj, float(x0), float(v0), hold=hold, substeps=substeps, time_budget=time_budget)
    if not res.ok:
        return float("inf"), res
    return float(np.sqrt(np.mean((res.x - np.asarray(traj.x)) ** 2))), res


def estimate_initial_state(model, traj, *, hold: str = "linear", substeps: int = 4, n_fit: int = 128):
    """The initial state (x0, x0') that best explains the first ``n_fit`` samples by a free run.

    A record's first velocity is not measured, and a derivative estimate at the very edge of a
    record is poor (spectral methods assume periodic continuation); two parameters fitted by
    output error on a short span are robust and cost a few milliseconds.
    """
    from scipy.optimize import least_squares

    from ..simulate._sampled import rk4_sampled, stage_inputs

    n = int(min(max(n_fit, 8), traj.n_samples))
    x = np.asarray(traj.x[:n], dtype=float)
    ua, um, ub = stage_inputs(np.asarray(traj.F[:n]), substeps, hold)
    if _closed(model):
        par = _Parametrised(model)
        accel = par.accel(par.theta0)
    else:
        accel = _model_accel(model)
    dt = float(traj.dt)
    v_guess = float(np.gradient(x[:5], dt)[0]) if n >= 5 else 0.0
    sx = max(float(np.std(x)), 1e-12)
    sv = max(float(np.std(np.gradient(x, dt))), 1e-12)

    def resid(q):
        xs, _, _ = rk4_sampled(accel, ua[:, None], um[:, None], ub[:, None], np.array([q[0] * sx]),
                               np.array([q[1] * sv]), dt, substeps)
        return np.nan_to_num((xs[:, 0] - x) / sx, nan=1e3)

    sol = least_squares(resid, [x[0] / sx, v_guess / sv], method="lm", xtol=1e-12, ftol=1e-12, max_nfev=200)
    return float(sol.x[0] * sx), float(sol.x[1] * sv)


def _closed(model) -> bool:
    return all(c.expression() is not None for c in model.curves.values())


def _model_accel(model):
    f1, f2, g, b = model.curves["f1"], model.curves["f2"], float(model.gain), float(model.offset)
    return lambda x, v, u: g * u - f1(v) - f2(x) - b


# ------------------------------------------------------------------------------ the refinement
def refine_output_error(model, traj, *, hold: str = "linear", substeps: int = 4, segment_length: int = 256,
                        max_nfev: int = 60, time_budget: float = 600.0):
    """Refine a closed-form model's coefficients, gain and constant by output error.

    Parameters
    ----------
    model : FittedModel
        Curves must be closed forms. Basis curves: their coefficients are refined. Symbolic curves:
        one coefficient per additive term (also an implicit 1, as in ``z**3 - z``) and every Float
        inside a term (``tanh(50.0*z)``); additive constants (they trade with ``b``) and exponents
        stay fixed.
    traj : Trajectory
        The estimation record, uniformly sampled; ``v`` (when present) gives the segments'
        starting velocities.
    hold : {"linear", "zoh", "bandlimited"}
        The input between samples (:mod:`charcurves.simulate._sampled`); the refined model is an
        ODE for that input reconstruction.
    substeps : int
        RK4 steps per sample interval (1: the discrete-time RK4 model of the literature).
    segment_length : int
        Samples per shooting segment (module docstring); the record is cut into
        ``round(n / segment_length)`` equal segments (at most ``n_segments - 1`` samples at the end
        are left out).
    max_nfev : int
        Largest number of least-squares iterations (each: one batched simulation for the
        Jacobian and one for the step).
    time_budget : float
        Seconds; the optimiser stops at the next iteration after it is spent.

    Returns
    -------
    FittedModel
        A new model with the refined curves, gain and constant; ``info["output_error"]`` holds the
        coefficients before and after, the segmented and whole-record free-run RMSE before and
        after, the initial state, the iterations and the time. When the refinement fails (the
        free run diverges from every start), the input model is returned with a warning and the
        reason in ``info["output_error"]["status"]``. The coefficients are labelled by what they
        multiply (``info["output_error"]["parameters"]``, e.g. "f2:z**3", "g", "b").
    """
    from scipy.optimize import least_squares
    from scipy.sparse import csr_matrix

    from ..simulate._sampled import rk4_sampled

    check_refine_options({"hold": hold, "substeps": substeps, "segment_length": segment_length,
                          "max_nfev": max_nfev, "time_budget": time_budget})
    if getattr(model.template, "is_general", False):
        raise ConfigError(f"output-error refinement simulates the separable family; the {model.template.family} "
                          "template is not supported (use refine='none')")
    started = time.perf_counter()
    par = _Parametrised(model)
    ua, um, ub = _inputs_for(traj, hold, substeps)
    y = np.asarray(traj.x, dtype=float)
    n = y.shape[0]
    if n < 32:
        raise DataError(f"output-error refinement needs at least 32 samples, the record has {n}")
    dt = float(traj.dt)
    vel = _velocity(traj)
    n_seg = max(1, int(round(n / min(segment_length, n))))
    L = n // n_seg
    starts = np.arange(n_seg) * L
    # stage inputs per segment: ((L - 1) * substeps, n_seg, 1), broadcasting over candidates
    idx = starts[None, :] * substeps + np.arange((L - 1) * substeps)[:, None]
    Ua, Um, Ub = (arr[idx][:, :, None] for arr in (ua, um, ub))
    Y = y[starts[None, :] + np.arange(L)[:, None]]  # (L, n_seg)

    P = par.theta0.size
    theta0 = par.theta0.copy()
    scale = np.abs(theta0)
    sy = max(float(np.std(y)), 1e-300)
    sv = max(float(np.std(vel)), 1e-300)
    ib = P - 1
    force_scale = float(np.std(np.asarray(traj.F))) * abs(float(model.gain))
    scale[ib] = max(scale[ib], 0.05 * force_scale, 1e-12)  # b may start at 0
    scale[scale == 0] = 1.0
    s0 = np.r_[y[starts], vel[starts]].reshape(2, n_seg)
    q0 = np.r_[theta0 / scale, (s0[0] / sy), (s0[1] / sv)]
    # layout of q: [shared parameters (P) | x0 of the segments | v0 of the segments], all scaled to ~1
    n_q = P + 2 * n_seg
    bad_value = 10.0  # residual (in units of std(y)) given to samples of diverged runs

    def unpack(q):
        return q[:P] * scale, q[P:P + n_seg] * sy, q[P + n_seg:] * sv

    def simulate(theta_batch, x0, v0):
        xs, _, _ = rk4_sampled(par.accel(theta_batch), Ua, Um, Ub, x0, v0, dt, substeps)
        return xs  # (L, n_seg, K)

    cache: dict = {"best": (np.inf, q0)}

    def residuals(q):
        if time.perf_counter() - started > time_budget:
            raise _BudgetSpent
        theta, x0, v0 = unpack(q)
        xs = simulate(theta[:, None], x0[:, None], v0[:, None])[:, :, 0]
        r = np.nan_to_num(((xs - Y) / sy).T.ravel(), nan=bad_value, posinf=bad_value, neginf=-bad_value)
        cost = float(r @ r)
        if cost < cache["best"][0]:
            cache["best"] = (cost, np.array(q, copy=True))
        return r

    seg_of_row = np.repeat(np.arange(n_seg), L)
    cols = np.column_stack([np.tile(np.arange(P), (n_seg * L, 1)), P + seg_of_row, P + n_seg + seg_of_row]).ravel()
    indptr = np.arange(n_seg * L + 1) * (P + 2)

    def jacobian(q):
        theta, x0, v0 = unpack(q)
        K = P + 3
        thb = np.repeat(theta[:, None], K, axis=1)
        thb[np.arange(P), 1 + np.arange(P)] += _FD_STEP * scale
        X0 = np.repeat(x0[:, None], K, axis=1)
        V0 = np.repeat(v0[:, None], K, axis=1)
        X0[:, P + 1] += _FD_STEP * sy
        V0[:, P + 2] += _FD_STEP * sv
        xs = simulate(thb, X0, V0)  # (L, n_seg, K)
        d = (xs[:, :, 1:] - xs[:, :, :1]) / (_FD_STEP * sy)  # derivative of r = (x - y)/sy per unit q
        d = np.nan_to_num(d, nan=0.0, posinf=0.0, neginf=0.0)
        data = d.transpose(1, 0, 2).reshape(n_seg * L, P + 2).ravel()
        cache["jac_evals"] = cache.get("jac_evals", 0) + 1
        return csr_matrix((data, cols, indptr), shape=(n_seg * L, n_q))

    def residuals_unbudgeted(q):
        theta, x0, v0 = unpack(q)
        xs = simulate(theta[:, None], x0[:, None], v0[:, None])[:, :, 0]
        return np.nan_to_num(((xs - Y) / sy).T.ravel(), nan=bad_value, posinf=bad_value, neginf=-bad_value)

    r0 = residuals_unbudgeted(q0)
    seg_rmse_before = float(np.sqrt(np.mean(r0**2)) * sy)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            sol = least_squares(residuals, q0, jac=jacobian, method="trf", tr_solver="lsmr", x_scale=1.0,
                                ftol=1e-9, xtol=1e-9, gtol=1e-10, max_nfev=int(max_nfev))
        q_best, message, nfev = sol.x, str(sol.message), int(sol.nfev)
    except _BudgetSpent:  # keep the best point evaluated so far
        q_best, message, nfev = cache["best"][1], f"time budget of {time_budget:g} s spent", -1
        cache["timed_out"] = True
    theta, x0s, v0s = unpack(q_best)
    seg_rmse_after = float(np.sqrt(np.mean(residuals_unbudgeted(q_best) ** 2)) * sy)
    diverged = not np.all(np.isfinite(simulate(theta[:, None], x0s[:, None], v0s[:, None])))
    refined = par.build(theta)
    info = {
        "hold": hold,
        "substeps": int(substeps),
        "segment_length": int(L),
        "segments": int(n_seg),
        "parameters": par.labels,
        "coefficients_before": theta0.tolist(),
        "coefficients_after": theta.tolist(),
        "segmented_rmse_before": seg_rmse_before,
        "segmented_rmse_after": seg_rmse_after,
        "iterations": nfev,
        "jacobians": int(cache.get("jac_evals", 0)),
        "optimizer": message,
        "seconds": None,
    }
    if diverged or not np.isfinite(seg_rmse_after) or seg_rmse_after > seg_rmse_before:
        info["status"] = "failed: the free run diverges or does not improve; kept the equation-error model"
        info["seconds"] = time.perf_counter() - started
        warnings.warn(f"output-error refinement failed ({info['status']})", RuntimeWarning, stacklevel=2)
        out = par.build(theta0)
        out.info["output_error"] = info
        return out
    before, _ = free_run_error(model, traj, hold=hold, substeps=substeps, x0=float(s0[0, 0]), v0=float(s0[1, 0]))
    after, _ = free_run_error(refined, traj, hold=hold, substeps=substeps, x0=float(x0s[0]), v0=float(v0s[0]))
    info.update({
        "status": "ok" if not cache.get("timed_out") else "time budget spent",
        "free_run_rmse_before": before,
        "free_run_rmse_after": after,
        "initial_state": [float(x0s[0]), float(v0s[0])],
        "seconds": time.perf_counter() - started,
    })
    info["loss_before"] = float(model.loss)
    refined.loss = float(np.mean(refined.force_residual(traj) ** 2)) if traj.has_derivatives else float("nan")
    refined.info["output_error"] = info
    refined.method = model.method
    return refined


# ------------------------------------------------------------------------------ reporting (CLI)
def closed_form_text(model, digits: int = 6) -> str:
    """``x'' + f1(x') + f2(x) + b = g F`` with the closed forms written out."""
    import sympy as sp

    parts = []
    for name, arg in (("f1", "x'"), ("f2", "x")):
        expr = model.curves[name].expression()
        text = "?" if expr is None else str(sp.N(expr, digits)).replace("z", arg)
        parts.append(f"({text})" if expr is not None and len(sp.Add.make_args(sp.expand(expr))) > 1 else text)
    sign = "-" if model.offset < 0 else "+"
    return f"x'' + {parts[0]} + {parts[1]} {sign} {abs(model.offset):.{digits}g} = {model.gain:.{digits}g}*F"


def summary_lines(model) -> list[str]:
    """Lines for the CLI summary describing ``model.info["output_error"]``."""
    oe = model.info.get("output_error", {})
    if not oe:
        return []
    how = (f"hold {oe['hold']}, {oe['substeps']} RK4 step{'s' if oe['substeps'] > 1 else ''} per sample, "
           f"{oe['segments']} segment{'s' if oe['segments'] > 1 else ''} of {oe['segment_length']} samples")
    if oe.get("status", "").startswith("failed"):
        return [f"output-error refinement ({how}): {oe['status']}"]
    return [
        f"output-error refinement ({how}; {oe['iterations']} evaluations, status {oe['status']}):",
        f"  free-run RMSE of x on the estimation record {oe['free_run_rmse_before']:.4g} -> "
        f"{oe['free_run_rmse_after']:.4g} (segmented {oe['segmented_rmse_before']:.4g} -> "
        f"{oe['segmented_rmse_after']:.4g})",
        "  closed form: " + closed_form_text(model),
    ]


def validate_cli(model_dir, csv, *, rows=None, time_col="t", x_col="x", force_col="F", sample_rate=None,
                 hold=None, substeps=None, out_dir=None) -> list[str]:
    """``charcurves validate``: free runs of a saved model on row spans of a CSV record.

    The initial state of each span is estimated from its first 128 samples
    (:func:`estimate_initial_state`); the RMSE is over every sample of the span.
    """
    import json
    import os

    from ..data._trajectory import Trajectory
    from ._model import load_model

    model = load_model(model_dir)
    if getattr(model.template, "is_general", False):
        raise ConfigError(f"validate simulates the separable family; the {model.template.family} template is "
                          "not supported")
    refined = model.info.get("output_error", {})
    hold = hold or refined.get("hold", DEFAULT_OPTIONS["hold"])
    substeps = substeps if substeps is not None else refined.get("substeps", DEFAULT_OPTIONS["substeps"])
    from ..simulate._sampled import _check_hold

    _check_hold(hold, substeps)
    full = Trajectory.from_csv(csv, time_col=time_col, x_col=x_col, force_col=force_col, sample_rate=sample_rate)
    spans = rows or [slice(0, full.n_samples)]
    results, sims = [], []
    for span in spans:
        start, stop, _ = span.indices(full.n_samples)
        if stop - start < 16:
            raise DataError(f"--rows {span.start}:{span.stop} selects {max(stop - start, 0)} of the record's "
                            f"{full.n_samples} rows; give a span of at least 16 rows inside the record")
        seg = full.slice(slice(start, stop))
        rmse, res = free_run_error(model, seg, hold=hold, substeps=substeps)
        x = np.asarray(seg.x)
        results.append({"rows": [start, stop], "status": res.status, "rmse": rmse,
                        "rmse_relative_to_std": rmse / float(np.std(x)) if np.std(x) > 0 else None,
                        "std_x": float(np.std(x)), "seconds": res.seconds})
        sims.append((seg, res, f"{start}:{stop}"))
    lines = [f"free run of {model_dir} ({model.method}; hold {hold}, {substeps} RK4 steps per sample; initial "
             "state fitted to the first 128 samples)"]
    for r in results:
        rel = "" if r["rmse_relative_to_std"] is None else f" ({100 * r['rmse_relative_to_std']:.3g} % of std x)"
        lines.append(f"  rows {r['rows'][0]}:{r['rows'][1]}: {r['status']}, RMSE {r['rmse']:.5g}{rel}, "
                     f"{r['seconds']:.2f} s")
    if out_dir is not None:
        from ..io._csv import atomic_write_bytes

        os.makedirs(out_dir, exist_ok=True)
        doc = {"model": os.path.abspath(os.fspath(model_dir)), "csv": os.path.abspath(os.fspath(csv)), "hold": hold,
               "substeps": int(substeps), "segments": results}
        atomic_write_bytes(os.path.join(out_dir, "validation.json"), json.dumps(doc, indent=1).encode())
        _validation_figure(os.path.join(out_dir, "validation.png"), sims)
        lines.append(f"wrote {os.path.join(out_dir, 'validation.json')}, validation.png")
    return lines


def _validation_figure(path, sims) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(sims), 2, figsize=(12, 2.8 * len(sims)), squeeze=False,
                             gridspec_kw={"width_ratios": [1, 2]})
    for row, (seg, res, label) in enumerate(sims):
        t, x = np.asarray(seg.t), np.asarray(seg.x)
        n = res.x.size
        mid = x.size // 2
        win = slice(max(0, mid - 75), min(x.size, mid + 75))
        ax = axes[row, 0]
        ax.plot(t[win], x[win], "k", lw=1.5, label="measured")
        if n:
            ax.plot(t[:n][win], res.x[win], "C1", lw=1.0, label="free run")
        ax.set_title(f"{seg.name} rows {label}: zoom", fontsize=9)
        ax.set_xlabel("t")
        ax.set_ylabel("x")
        ax.legend(fontsize=7)
        ax = axes[row, 1]
        if n:
            ax.plot(t[:n], res.x - x[:n], "C3", lw=0.5)
        ax.set_title(f"simulation error ({res.status}; std x {np.std(x):.4g})", fontsize=9)
        ax.set_xlabel("t")
        ax.set_ylabel("simulated - measured")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
