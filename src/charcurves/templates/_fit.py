"""Fitters of general templates (EquationTemplate): neural curves, and the linear-in-parameters
methods (Parametric, Poly-CC, SINDy and SINDy-CC) on one design matrix.

Every equation's residual ``known + sum m f(u) + sum s a + b - g F`` is stacked equation after
equation, so one batched neural problem (the curves' coefficient signals are per-sample
multipliers) or one least-squares / sparse regression covers all equations at once.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

import numpy as np

from .._errors import ConfigError, DataError
from ._general import EquationTemplate, display

__all__ = ["fit_neural_template", "fit_linear_template", "template_residual", "template_scalars"]

#: Default Parametric basis of general templates: a cubic polynomial per curve (constants that
#: curves trade are resolved by the gauge after the fit).
DEFAULT_GENERAL_BASIS = ["1", "z", "z**2", "z**3"]


def template_scalars(model) -> dict[str, float]:
    """Learned scalars ``a1, a2, ...`` and per-equation offsets ``b2, b3, ...`` of a model."""
    return {k: float(v) for k, v in dict(model.info.get("scalars", {})).items()}


def template_residual(model, record) -> np.ndarray:
    """Residual of every equation: shape (N,) for one equation, (N, E) for several."""
    template: EquationTemplate = model.template
    D = template.design(record)
    n, E = D["n"], D["E"]
    r = D["y"] - model.gain * D["F"]
    for name, c in model.curves.items():
        r = r + D["mult"][name] * np.tile(np.asarray(c(D["args"][name]), dtype=float), E)
    sc = template_scalars(model)
    for s, sig in D["scalars"].items():
        r = r + sig * sc.get(s, 0.0)
    r = r.reshape(E, n)
    r[0] += model.offset
    for e in range(1, E):
        r[e] += sc.get(f"b{e + 1}", 0.0)
    return r[0] if E == 1 else r.T


def _finish(template, method, curves, gain, offsets, scalars, record, info):
    """FittedModel with the gauge applied and the loss computed."""
    from ..fitting._model import FittedModel

    pinned = {n: c.pinned_at_zero for n, c in curves.items()}
    raw0 = {n: float(c.raw(np.array([0.0]))[0]) for n, c in curves.items()}
    shifts, new_off = template.normalise(raw0, pinned, offsets)
    for n, c in curves.items():
        c.shift = shifts[n]
    scal = dict(scalars)
    for e, v in new_off.items():
        if e > 0:
            scal[f"b{e + 1}"] = float(v)
    info = dict(info)
    info["scalars"] = scal
    info["gauge_conditions"] = template.gauge_conditions(pinned)
    info["gauge_freedoms"] = template.gauge_freedoms(pinned)
    model = FittedModel(template, method, curves, gain, float(new_off.get(0, 0.0)), 0.0, info)
    model.loss = float(np.mean(template_residual(model, record) ** 2))
    return model


# ---------------------------------------------------------------------------------------- neural
def _gain_estimate(D, fallback):
    """Least-squares g from F = h * known + smooth powers of the arguments times their coefficients."""
    E = D["E"]
    cols = [D["y"], np.ones_like(D["y"])]
    for name, u in D["args"].items():
        z = np.tile(u / max(float(np.max(np.abs(u))), 1e-300), E)
        m = D["mult"][name]
        cols += [m * z, m * z**2, m * z**3, m]
    cols += list(D["scalars"].values())
    A = np.column_stack(cols)
    norms = np.linalg.norm(A, axis=0)
    norms[norms == 0] = 1.0
    coef, *_ = np.linalg.lstsq(A / norms, D["F"], rcond=None)
    h = coef[0] / norms[0]
    return float(1.0 / h) if np.isfinite(h) and h != 0 else float(fallback)


def fit_neural_template(records: Sequence, template: EquationTemplate, curves: dict, preset, seeds: Sequence[int], *,
                        method: str = "nn-cc", device: str = "cpu", threads: int | None = None,
                        progress: Callable | None = None, chunk_models: int | None = None) -> list:
    """NN-CC on a general template: K records (equal lengths) trained as one batch, as
    :func:`charcurves.fitting._neural_fit.fit_neural` does for the separable family.

    Unknown scalars and the offsets of further equations are curves evaluated at a constant
    argument (their value times the signal), so they train with everything else.
    """
    import torch

    from ..curves._fitted import NeuralFittedCurve
    from ..curves._neural import NeuralCurve
    from ..fitting._gradient import BatchedProblem, CurveTerm
    from ..fitting._neural_fit import chunk_log, start_weights, train_batched

    if len(records) != len(seeds):
        raise ConfigError("give one seed per trajectory")
    if len({r.n_samples for r in records}) != 1:
        raise DataError("records fitted in one batch must have the same number of samples; fit them separately")
    dtype = torch.float64 if preset.dtype == "float64" else torch.float32
    names = template.curve_names
    R = preset.n_starts
    t_start = time.perf_counter()
    pinned = {n: curves[n].pinned_at_zero for n in names}
    template.check_identifiable(pinned)
    offsets = template.offsets_needed(pinned)
    E = template.n_equations
    # scalars and the offsets of equations 2.. are constant-argument curves; equation 1's is the bias
    const_names = list(template.scalar_names) + [f"b{e + 1}" for e in offsets if E > 1]
    const_spec = NeuralCurve(hidden=(1,), activation=curves[names[0]].activation if names else "tanh")
    force_side = template.free_gain and template.gain_on == "force"

    designs, scales_in, scale_out, g_est, sig_scale = [], [], [], [], []
    for rec in records:
        template.check_excitation(rec)
        D = template.design(rec)
        designs.append(D)
        scales_in.append({k: (float(np.max(np.abs(D["args"][k]))) if preset.scale_inputs else 1.0) for k in names})
        signals = dict(D["scalars"])
        for e in offsets:
            if E > 1:
                ind = np.zeros(E * D["n"])
                ind[e * D["n"]:(e + 1) * D["n"]] = 1.0
                signals[f"b{e + 1}"] = ind
        D["const_signals"] = signals
        sig_scale.append({k: max(float(np.max(np.abs(v))), 1e-300) for k, v in signals.items()})
        if force_side:
            g_est.append(_gain_estimate(D, template.gain))
            s_out = float(np.std(D["F"])) if preset.scale_output else 1.0
        else:
            g_est.append(1.0)
            s_out = float(np.std(D["y"] - template.gain * D["F"])) if preset.scale_output else 1.0
        scale_out.append(s_out if s_out > 0 else 1.0)

    K = len(records)
    KR = K * R
    rep = lambda arr_list: np.repeat(np.stack(arr_list), R, axis=0)  # noqa: E731
    T = lambda arr: torch.as_tensor(arr, dtype=dtype, device=device)  # noqa: E731
    so = np.repeat(np.array(scale_out), R)[:, None]
    y = T(rep([D["y"] for D in designs]) / so / np.repeat(np.array(g_est), R)[:, None])
    F = T(rep([D["F"] for D in designs]) / so)
    n_rows = E * designs[0]["n"]
    w = T(np.full((KR, n_rows), 1.0 / np.sqrt(n_rows)))

    terms = []
    for name in names:
        spec = curves[name]
        z = rep([np.tile(D["args"][name], E) for D in designs]) / np.repeat([s[name] for s in scales_in], R)[:, None]
        mult = rep([D["mult"][name] for D in designs])
        sym_pts = None
        if spec.symmetry != "none" and spec.symmetry_mode == "penalty":
            zs = [np.linspace(D["args"][name].min(), D["args"][name].max(), preset.n_sym) / s[name]
                  for D, s in zip(designs, scales_in)]
            sym_pts = T(np.repeat(np.stack(zs), R, axis=0))
        terms.append(CurveTerm(spec, T(z), T(mult), sym_pts))
    for cname in const_names:
        sig = rep([D["const_signals"][cname] / s[cname] for D, s in zip(designs, sig_scale)])
        terms.append(CurveTerm(const_spec, T(np.ones((KR, n_rows))), T(sig), None))
    bias = E == 1 and bool(offsets)
    problem = BatchedProblem(terms, y, F, w, free_gain=template.free_gain, gain=template.gain,
                             gain_on=template.gain_on, bias=bias, lambda_sym=preset.lambda_sym, weight_decay=0.0,
                             bayesian=preset.bayesian, decay_groups=preset.decay_groups)

    def draw(gen):
        parts = [curves[nm].init(1, gen, dtype) for nm in names]
        parts += [const_spec.init(1, gen, dtype) for _ in const_names]
        if template.free_gain:
            parts.append(torch.full((1, 1), 1.0 if force_side else float(template.gain), dtype=dtype))
        if bias:
            parts.append(torch.zeros(1, 1, dtype=dtype))
        return parts

    theta, logs, log, total_loss = train_batched(problem, start_weights(seeds, R, draw).to(device), preset,
                                                 threads=threads, device=device, chunk_models=chunk_models,
                                                 progress=progress)
    elapsed = time.perf_counter() - t_start
    theta = theta.double().cpu()
    one = torch.ones(1, dtype=torch.float64)

    models = []
    for k in range(K):
        losses = total_loss[k * R:(k + 1) * R]
        best = int(np.argmin(losses))
        members = (np.flatnonzero(losses <= losses[best] * (1.0 + preset.combine_tol)) if preset.combine == "mean"
                   else np.array([best]))
        rows = theta[k * R + members]
        s_out = scale_out[k]
        g = float(problem.gain_of(rows).mean())
        factor = s_out
        if force_side:
            g = g_est[k] / g
            factor *= g
        fitted = {}
        for i, name in enumerate(names):
            z = designs[k]["args"][name]
            fitted[name] = NeuralFittedCurve(name, template.arguments[name], (float(z.min()), float(z.max())),
                                             curves[name], problem.block(rows, i).numpy(), scales_in[k][name], factor)
        scal = {}
        with torch.no_grad():
            for j, cname in enumerate(const_names):
                val = float(const_spec.evaluate(problem.block(rows, len(names) + j), one).mean())
                scal[cname] = val * factor / sig_scale[k][cname]
        offs = {e: scal.pop(f"b{e + 1}") for e in offsets if E > 1}
        if bias:
            offs[0] = float(problem.bias_of(rows).mean()) * factor
        info = {
            "preset": preset.name, "preset_settings": preset.to_dict(), "seed": int(seeds[k]), "n_starts": R,
            "best_start": best, "ensemble_members": int(members.size), "adam_steps": log.adam_steps,
            "lm_iterations": log.lm_iterations, "stopped_by": log.stopped_by, "interrupted": log.interrupted,
            "n_samples": int(designs[k]["n"]), "n_fitted_samples": int(designs[k]["n"]), "n_sticking_samples": 0,
            "n_equations": E, "total_loss": float(total_loss[k * R + best] * s_out**2),
            "train_seconds": elapsed / K, "batch_size": K,
        }
        if log.interrupted:  # this record's own chunk: finished, interrupted or never trained
            own = chunk_log(logs, k * R)
            info.update(adam_steps=own.adam_steps, lm_iterations=own.lm_iterations, stopped_by=own.stopped_by)
        models.append(_finish(template, method, fitted, g, offs, scal, records[k], info))
    return models


# ---------------------------------------------------------------------------------------- linear
_LINEAR_OPTIONS = ("degree", "rescaling", "basis", "expand_tol", "threshold", "max_iter", "alpha", "nu", "tol",
                   "exclude_sticking", "stick_tol", "constant")


def fit_linear_template(record, template: EquationTemplate, *, representation: str, method: str,
                        symmetry: dict | None = None, basis: dict | None = None, options: dict | None = None):
    """Parametric (``representation="basis"``), Poly-CC ("poly") and SINDy/SINDy-CC ("sindy") on a
    general template: one design matrix, columns ``m_i(t) * phi_k(u_i(t))`` per curve, the scalar
    signals, one constant per gauge carrier, and ``-F`` (or the known part) when the gain is free.
    """
    import sympy as sp

    from ..curves._fitted import BasisFittedCurve, parse_basis_function

    t0 = time.perf_counter()
    opts = dict(options or {})
    unknown = sorted(set(opts) - set(_LINEAR_OPTIONS))
    if unknown:
        raise ConfigError(f"unknown {method} option(s) {unknown}; valid: {', '.join(_LINEAR_OPTIONS)}")
    names = template.curve_names
    sym = {n: "none" for n in names}
    sym.update(symmetry or {})
    template.check_excitation(record)
    D = template.design(record)
    E, n = D["E"], D["n"]
    zsym = sp.Symbol("z")
    info: dict = {"n_samples": n, "n_equations": E}

    # ---- per-curve columns (functions of the curve's argument) and whether the curve is pinned at 0
    col_funcs: dict[str, list] = {}
    pinned: dict[str, bool] = {}
    poly_maps = {}
    if representation == "basis":
        if basis is None:
            basis = {nm: list(DEFAULT_GENERAL_BASIS) for nm in names}
        for nm in names:
            exprs = [parse_basis_function(b) for b in basis[nm]]
            col_funcs[nm] = [(b, sp.lambdify(zsym, e, modules="numpy")) for b, e in zip(basis[nm], exprs)]
            pinned[nm] = all(sp.simplify(e.subs(zsym, 0)) == 0 for e in exprs)
        info["basis"] = basis
    elif representation == "poly":
        from ..fitting._poly import _check_options as poly_options
        from ..fitting._poly import _column, _mapping, _powers

        po = poly_options({k: v for k, v in opts.items() if k in ("degree", "rescaling", "basis", "expand_tol")})
        degree, poly_kind = po["degree"], po["basis"]
        for nm in names:
            c, h = _mapping(D["args"][nm], sym[nm], po["rescaling"])
            poly_maps[nm] = (c, h)
            col_funcs[nm] = [(k, (lambda z, k=k, c=c, h=h: _column((z - c) / h, k, poly_kind)))
                             for k in _powers(degree, sym[nm])]
            pinned[nm] = sym[nm] == "odd"
        info.update({"degree": degree, "rescaling": po["rescaling"], "basis": poly_kind})
    elif representation == "sindy":
        from ..fitting._sindy import _check_options as sindy_options

        so = sindy_options({k: v for k, v in opts.items() if k in ("threshold", "degree", "max_iter", "alpha", "nu",
                                                                   "tol")}, method != "sindy")
        degree = so["degree"]
        for nm in names:
            from ..fitting._poly import _powers

            col_funcs[nm] = [(k, (lambda z, k=k: z**k)) for k in _powers(degree, sym[nm])]
            pinned[nm] = sym[nm] == "odd"
        info.update({k: so[k] for k in ("threshold", "degree")})
    else:  # pragma: no cover - the estimator only routes the three above
        raise ConfigError(f"representation {representation!r} is not linear")
    template.check_identifiable(pinned)

    cols, owners = [], []
    for nm in names:
        u = D["args"][nm]
        m = D["mult"][nm]
        for key, f in col_funcs[nm]:
            cols.append(m * np.tile(np.broadcast_to(f(u), u.shape).astype(float), E))
            owners.append((nm, key))
    for s, sig in D["scalars"].items():
        cols.append(sig)
        owners.append(("__scalar", s))
    # constants: only the slots that carry one after the gauge (pivot slots are 0 by the anchors)
    offsets = template.offsets_needed(pinned)
    if representation != "basis" and bool(opts.get("constant", True)):
        slots, vecs = template._freedoms(pinned, template._priority(pinned, template.anchors, offsets))
        pivots = {p for p, _ in vecs}
        for kind, name in slots:
            if (kind, name) in pivots or kind == "scalar":
                continue
            if kind == "curve":
                cols.append(D["mult"][name])
                owners.append((name, 0))
            else:
                e = int(name[1:]) - 1
                ind = np.zeros(E * n)
                ind[e * n:(e + 1) * n] = 1.0
                cols.append(ind)
                owners.append(("__offset", e))
    elif representation == "basis":
        for e in offsets:
            ind = np.zeros(E * n)
            ind[e * n:(e + 1) * n] = 1.0
            cols.append(ind)
            owners.append(("__offset", e))
    target = template.gain * D["F"] - D["y"]
    force_side = template.free_gain and template.gain_on == "force"
    if template.free_gain:
        cols.append(D["y"] if force_side else -D["F"])
        owners.append(("__gain", 0))
        target = D["F"] if force_side else -D["y"]
    A = np.column_stack(cols)
    norms = np.linalg.norm(A, axis=0)
    norms[norms == 0] = 1.0
    if representation == "sindy":
        coef = _sparse_solve(A, target, method, so, info)
    else:
        coef_scaled, *_ = np.linalg.lstsq(A / norms, target, rcond=None)
        coef = coef_scaled / norms
    info["condition_number"] = float(np.linalg.cond(A / norms))
    gain = template.gain
    if template.free_gain:
        gi = owners.index(("__gain", 0))
        if force_side:
            h = float(coef[gi])
            if not np.isfinite(h) or h == 0:
                raise DataError("the learned gain is zero or not finite; the record does not determine the gain")
            coef = coef / h
            gain = 1.0 / h
        else:
            gain = float(coef[gi])

    by_curve: dict[str, dict] = {nm: {} for nm in names}
    scalars, offs = {}, {}
    for (owner, key), v in zip(owners, coef):
        if owner == "__scalar":
            scalars[key] = float(v)
        elif owner == "__offset":
            offs[key] = float(v)
        elif owner != "__gain":
            by_curve[owner][key] = float(v)

    curves = {}
    for nm in names:
        u = D["args"][nm]
        domain = (float(u.min()), float(u.max()))
        if representation == "basis":
            keys = [b for b, _ in col_funcs[nm]]
            curves[nm] = BasisFittedCurve(nm, template.arguments[nm], domain, keys, [by_curve[nm][b] for b in keys])
        elif representation == "poly":
            from ..fitting._poly import _build_curve, _series_in_s

            c, h = poly_maps[nm]
            series = _series_in_s({k: v for k, v in by_curve[nm].items() if k != 0}, degree, poly_kind)
            series[0] += by_curve[nm].get(0, 0.0)
            curves[nm], _, _ = _build_curve(nm, template.arguments[nm], domain, series, c, h, sym[nm],
                                            po["expand_tol"])
        else:
            powers = sorted(by_curve[nm])
            nz = [k for k in powers if by_curve[nm][k] != 0.0] or [1]
            curves[nm] = BasisFittedCurve(nm, template.arguments[nm], domain,
                                          ["1" if k == 0 else ("z" if k == 1 else f"z**{k}") for k in nz],
                                          [by_curve[nm].get(k, 0.0) for k in nz])
    info["train_seconds"] = time.perf_counter() - t0
    return _finish(template, method, curves, gain, offs, scalars, record, info)


def _sparse_solve(A, target, method, so, info):
    """pysindy's sparse regression on the template's design matrix (columns equilibrated)."""
    import warnings

    from ..fitting._sindy import _import_pysindy, l0_weight

    ps = _import_pysindy(False)
    norms = np.linalg.norm(A, axis=0)
    norms[norms == 0] = 1.0
    # thresholds act on coefficients of unit-norm columns times sqrt(N): the scale of a unit-RMS column
    scale = norms / np.sqrt(A.shape[0])
    if method == "sindy":
        opt = ps.STLSQ(threshold=so["threshold"], alpha=so["alpha"], max_iter=so["max_iter"])
        info["optimizer"] = "STLSQ"
    else:
        opt = ps.SR3(reg_weight_lam=l0_weight(so["threshold"], so["nu"]), regularizer="L0",
                     relax_coeff_nu=so["nu"], tol=so["tol"], max_iter=so["max_iter"])
        info["optimizer"] = "SR3 (l0)"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        opt.fit(A / scale, target.reshape(-1, 1))
    coef = np.asarray(opt.coef_, dtype=float).reshape(-1) / scale
    info["n_active_terms"] = int(np.count_nonzero(coef))
    return coef


def template_to_sympy(model):
    """The identified equations of a general template as sympy ``Eq`` (a list for several)."""
    import sympy as sp

    template: EquationTemplate = model.template
    z = sp.Symbol("z")
    sc = template_scalars(model)
    out = []
    for e, eq in enumerate(template.equations):
        lhs = eq.known
        for name, m in eq.curves.items():
            lhs = lhs + m * model.curves[name].expression().subs(z, template.argument_exprs[name])
        for s, sig in eq.scalars.items():
            lhs = lhs + sp.Float(sc.get(s, 0.0)) * sig
        off = model.offset if e == 0 else sc.get(f"b{e + 1}", 0.0)
        if off:
            lhs = lhs + sp.Float(off)
        rhs = eq.input if model.gain == 1 else sp.Float(model.gain) * eq.input
        eq_ = sp.Eq(lhs, rhs)
        # data symbols as written (x', x1'') rather than the parser's internal names
        out.append(eq_.subs({s: sp.Symbol(display(s.name), real=True) for s in eq_.free_symbols}))
    return out[0] if len(out) == 1 else out


def prepare_record(record, template: EquationTemplate, sym: dict, derivatives: str, what: str,
                   without_prior: Callable | None = None):
    """Validate a record for a general template and fill in the derivatives it needs.

    The identifiability checks are those of the separable path (same wording): no excitation,
    a constant forcing with a free gain, a parity prior on a one-sided argument.
    ``without_prior(name, sym)`` says how to drop the prior on ``name`` (the estimator knows its
    method's options).
    """
    from .._errors import IdentifiabilityError
    from ..data._differentiate import estimate_derivatives
    from ..data._trajectory import MIN_SAMPLES, MultiTrajectory, Trajectory

    if not isinstance(record, (Trajectory, MultiTrajectory)):
        raise DataError(f"fit expects a Trajectory or MultiTrajectory, got {type(record).__name__}; build one with "
                        "Trajectory.from_csv or MultiTrajectory.from_csv")
    if template.multi_dof and isinstance(record, Trajectory):
        raise DataError(f"the {template.family} template uses {', '.join(template.states + template.forces)}; give a "
                        "multi-DOF record (MultiTrajectory, CSV columns t,x1,x2,F1,F2)")
    if isinstance(record, MultiTrajectory):
        missing = [s for s in template.states if s not in record.states]
        missing += [f for f in template.forces if f not in record.forces]
        if missing:
            raise DataError(f"the template uses {', '.join(missing)}, which the record lacks; the record has "
                            f"{', '.join(list(record.states) + list(record.forces))}")
    record.require_samples(MIN_SAMPLES, what)
    # a first-order template needs the velocities only
    velocities = record.v is not None if isinstance(record, Trajectory) else record.velocities is not None
    have = record.has_derivatives or (template.order == 1 and velocities)
    if derivatives == "given" and not have and template.order > 0:
        raise DataError("--derivatives given needs the derivative columns (v, a or v1, a1, ...) in the data; "
                        "use --derivatives spline|spectral|savgol to estimate them")
    if template.order > 0 and not (derivatives in ("auto", "given") and have):
        method = "auto" if derivatives == "given" else derivatives
        if isinstance(record, Trajectory):
            record = estimate_derivatives(record.replace(v=None, a=None), method)
        else:
            xs, vs, as_ = {}, {}, {}
            for s in record.states:
                one = estimate_derivatives(record.dof(s).replace(v=None, a=None), method)
                xs[s], vs[s], as_[s] = one.x, one.v, one.a
            record = record.replace(states=xs, velocities=vs, accelerations=as_)
    try:
        template.check_excitation(record)
    except DataError as exc:  # no excitation: the data cannot determine the curves at all
        raise IdentifiabilityError(f"no excitation: {exc}") from None
    if template.free_gain:
        design = template.design(record)
        inputs = design["F"].reshape(design["E"], design["n"])
        # g is shared by the equations: one equation with a varying input is enough to fix it
        if all(np.ptp(row) == 0 for row in inputs):
            forces = ", ".join(template.forces) or "input"
            noun = "forcings" if len(template.forces) > 1 else "forcing"
            raise IdentifiabilityError(
                f"the {noun} {forces} {'are' if len(template.forces) > 1 else 'is'} constant over the record, so the "
                "gain g cannot be told apart from a constant offset (not identifiable); drop --free-gain "
                "(free_gain=False) or give a record with varying forcing"
            )
    for name, z in template.arguments_of(record).items():
        if sym.get(name, "none") != "none" and (z.min() >= 0 or z.max() <= 0):
            fix = without_prior(name, sym) if without_prior is not None else "drop it"
            raise IdentifiabilityError(
                f"an {sym[name]} prior on {name} needs its argument {template.arguments[name]} on both "
                f"sides of 0, but the record covers only [{z.min():.3g}, {z.max():.3g}], so the prior can be "
                f"neither checked nor used; {fix} or give a record that crosses 0"
            )
    return record


#: methods (by representation) that general templates support
GENERAL_REPRESENTATIONS = ("neural", "basis", "poly", "sindy")


def fit_general(est, template: EquationTemplate, spec: dict, sym: dict, jumps, records, seeds) -> list:
    """The estimator's fitting step for general templates (see CharacteristicCurves)."""
    from ..curves._neural import NeuralCurve
    from ..fitting._presets import get_preset

    rep = spec["representation"]
    if rep not in GENERAL_REPRESENTATIONS:
        from ..fitting._estimator import METHODS

        ok = [m for m, sp_ in METHODS.items() if sp_["representation"] in GENERAL_REPRESENTATIONS]
        raise ConfigError(f"method {est.method!r} supports the separable family only; for the {template.family} "
                          f"template use one of {', '.join(ok)}")
    jumps = [] if jumps in ("auto", "none", None) else list(jumps)
    if jumps and rep != "neural":
        raise ConfigError(f"--jump applies to neural curves, not to method {est.method!r}")
    if rep == "neural":
        preset = get_preset(est.preset)
        curves = {
            name: NeuralCurve(hidden=tuple(est.hidden) if est.hidden else preset.hidden,
                              activation=est.activation or preset.activation, symmetry=sym[name],
                              symmetry_mode=preset.symmetry_mode, linear_term=preset.linear_term,
                              jump=name in jumps)
            for name in template.curve_names
        }
        out = [None] * len(records)
        groups: dict[int, list[int]] = {}
        for i, rec in enumerate(records):
            groups.setdefault(rec.n_samples, []).append(i)
        for idx in groups.values():
            models = fit_neural_template([records[i] for i in idx], template, curves, preset,
                                         [int(seeds[i]) for i in idx], method=est.method, device=est.device,
                                         threads=est.threads, progress=est.progress)
            for i, m in zip(idx, models):
                out[i] = m
        return out
    basis = None
    if rep == "basis" and est.basis is not None:
        from ..fitting._linear import parse_basis_option

        basis = parse_basis_option(est.basis, template.curve_names)
    return [fit_linear_template(rec, template, representation=rep, method=est.method, symmetry=sym, basis=basis,
                                options={k: v for k, v in dict(est.options or {}).items()
                                         if k not in ("exclude_sticking", "stick_tol")})
            for rec in records]


def read_record(path, *, family: str = "separable", equation: str | None = None, time_col: str = "t",
                x_col: str = "x", force_col: str = "F", sample_rate=None, rows=None):
    """Read a CSV record in the shape the template needs: a Trajectory (t,x,F[,v,a]) or, for
    multi-DOF templates, a MultiTrajectory (t,x1,x2,F1,F2[,v1,a1,v2,a2])."""
    from ..data._trajectory import MultiTrajectory, Trajectory
    from ._general import check_equation_option
    from ._separable import get_template

    check_equation_option(equation)
    template = get_template(family, equation=equation)
    if getattr(template, "multi_dof", False):
        if sample_rate is not None:
            raise ConfigError("--sample-rate is not supported for multi-DOF records; give a time column t")
        return MultiTrajectory.from_csv(path, states=template.states, forces=template.forces, time_col=time_col,
                                        rows=rows)
    return Trajectory.from_csv(path, time_col=time_col, x_col=x_col, force_col=force_col, sample_rate=sample_rate,
                               rows=rows)


def simulate_multi_cli(system, a, *, say) -> int:
    """``charcurves simulate two-dof``: the multi-DOF record with optional noise on the forcings."""
    from ..systems._families import corrupt_forces

    if a.snr is not None and a.noise_on != "force":
        raise ConfigError("multi-DOF records take noise on the forcings only; drop --noise-on state")
    traj = system.simulate(t_end=a.t_end, n_points=a.n_points)
    if a.snr is not None:
        traj = corrupt_forces(traj, a.snr, seed=a.seed, reference=a.noise_reference or "std")
    traj.to_csv(a.out)
    say(f"wrote {a.out}: {system.name} ({a.variant}), {traj.n_samples} samples"
        + (f", SNR {a.snr:g} dB on each forcing" if a.snr is not None else ", no noise"))
    return 0
