"""Curves linear in their parameters (Parametric, Poly-CC, SINDy, any LinearCurve) on any template:
one design matrix, solved by least squares or by pysindy's sparse regression.

Columns: each feature of each curve times the curve's coefficient signal (all equations stacked),
the scalars' signals, a constant where the template needs one, and the input when the gain is
free. Constants: a Polynomial curve may carry one (the template's gauge then decides where it
sits, as the paper's f2(0) = 0), a Basis or user curve gets one only through the equation's free
constant when no curve can carry it, a SparseLibrary never (pysindy's library has no bias, as in
the paper's scripts).
"""

from __future__ import annotations

import time
import warnings
from typing import Any

import numpy as np

from .._errors import ConfigError, DataError, FitError
from ..templates import EquationTemplate
from ..model import finish_model
from ._sr3 import constrained_sr3

__all__ = ["fit_linear", "l0_weight", "column_name"]

_INSTALL = "pip install 'charcurves[sindy]'"


def l0_weight(threshold: float, nu: float = 1.0) -> float:
    """pysindy 1.x l0 threshold -> pysindy 2.x ``reg_weight_lam`` (prox threshold sqrt(2 lam nu)).

    Examples
    --------
    >>> from charcurves.fitting import l0_weight
    >>> f"{l0_weight(1e-5):.3g}", f"{l0_weight(0.1, nu=0.5):.3g}"
    ('5e-11', '0.01')
    """
    return threshold**2 / (2.0 * nu)


def import_pysindy(constrained: bool):
    try:
        import pysindy as ps
    except ImportError:
        raise ConfigError(f"the SINDy methods need pysindy; install it with {_INSTALL}") from None
    if constrained:
        try:
            import cvxpy  # noqa: F401  (pysindy exports ConstrainedSR3 only when cvxpy imports)
        except ImportError:
            raise ConfigError(f"sindy-cc needs cvxpy for pysindy's ConstrainedSR3; install both with {_INSTALL}") from None
        if not hasattr(ps, "ConstrainedSR3"):
            raise ConfigError(f"this pysindy has no ConstrainedSR3; install pysindy>=2 and cvxpy with {_INSTALL}")
    return ps


def column_name(argument: str, power: int) -> str:
    """pysindy-style feature name of a power of a curve's argument ("x", "v^3" for x'^3)."""
    var = "v" if argument == "x'" else argument
    return var if power == 1 else f"{var}^{power}"


def _features_numpy(rep, u: np.ndarray) -> np.ndarray:
    from ..curves import Polynomial, column_numpy

    if isinstance(rep, Polynomial):  # numpy's Chebyshev series, as the columns were always built
        return np.column_stack([column_numpy(u, k, rep.basis_name) for k in rep.powers()])
    import torch

    with torch.no_grad():
        return rep.features(torch.as_tensor(u, dtype=torch.float64)).double().numpy()


def _argument_order(template: EquationTemplate) -> list[str]:
    """Curves by the derivative order of their argument, then by name (pysindy's x, v order)."""
    def key(name):
        arg = str(template.argument_exprs[name])
        order = int(arg[-1]) if "__d" in arg else 0
        return order, int(name[1:])

    return sorted(template.curve_names, key=key)


def fit_linear(record, template: EquationTemplate, reps: dict, *, method: str, mask: np.ndarray | None = None,
               constant: bool = True):
    """One joint fit of every linear curve's coefficients (and scalars, constants, the gain when free);
    ``constant=False`` gives Polynomial curves no constant column (the scripts' option)."""
    from ..curves import Polynomial, SparseLibrary

    t0 = time.perf_counter()
    D = template.design(record)
    E, n = D["E"], D["n"]
    mask = np.ones(n, bool) if mask is None else np.asarray(mask, bool)
    rows = np.tile(mask, E)
    names = template.curve_names
    sparse = [nm for nm in names if isinstance(reps[nm], SparseLibrary)]
    carriers = constant_carriers(template, reps) if constant else set()
    scalings, pinned = {}, {}
    cols: list = []
    owners: list[tuple[str, Any]] = []  # (curve name or "__scalar"/"__offset", what the column is)
    for nm in _argument_order(template):
        rep = reps[nm]
        u_raw = D["args"][nm]
        c, h = rep.scaling(u_raw, None)
        scalings[nm] = (c, h)
        pinned[nm] = rep.symmetry_name == "odd" if nm in carriers else bool(rep.pinned_at_zero)
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                phi = _features_numpy(rep, (u_raw - c) / h)
            except (TypeError, ValueError, RuntimeError, OverflowError) as exc:  # torch on an odd closed form
                funcs = rep.function_list() if hasattr(rep, "function_list") else None
                raise ConfigError(f"the curve {nm} ({', '.join(funcs)[:80] if funcs else type(rep).__name__}) cannot "
                                  f"be evaluated on the record ({type(exc).__name__}: {str(exc)[:80]}); write plain "
                                  "closed forms of z such as 'z**3' or 'tanh(50*z)'") from None
        _check_columns(rep, nm, template, phi, u_raw)
        for k in range(phi.shape[1]):
            cols.append(D["mult"][nm] * np.tile(phi[:, k], E))
            owners.append((nm, k))
    template.check_identifiable(pinned)
    for s, sig in D["scalars"].items():
        _check_signal(f"the signal multiplying the scalar {s}", sig, template)
        cols.append(sig)
        owners.append(("__scalar", s))
    # constants: a Polynomial carries one on the slots that keep one after the gauge (pivot slots
    # are 0 by the anchors); the equations' free constants where no curve can carry one
    offsets = template.offsets_needed(pinned)
    if carriers:
        for kind, name in constant_slots(template, pinned, offsets, carriers):
            if kind == "curve":
                cols.append(D["mult"][name])
                owners.append((name, "const"))
            else:
                cols.append(_indicator(int(name[1:]) - 1, E, n))
                owners.append(("__offset", int(name[1:]) - 1))
    elif len(sparse) < len(names) and not any(isinstance(reps[nm], Polynomial) for nm in names):
        for e in offsets:
            cols.append(_indicator(e, E, n))
            owners.append(("__offset", e))
    force_side = template.free_gain and template.gain_on == "force"
    info: dict = {"n_samples": n, "n_fitted_samples": int(mask.sum()), "n_sticking_samples": int(n - mask.sum())}
    if E > 1:
        info["n_equations"] = E
    if sparse:
        coef, gain = _sparse_fit(template, reps, sparse, D, cols, owners, rows, info, method)
    else:
        target = template.gain * D["F"] - D["y"]
        if template.free_gain:
            cols.append(D["y"] if force_side else -D["F"])
            owners.append(("__gain", 0))
            target = D["F"] if force_side else -D["y"]
        A = np.column_stack(cols)[rows]
        _check_signal("the known part of the equation (the terms without unknowns, or the forcing)", target[rows],
                      template)
        norms = np.linalg.norm(A, axis=0)
        norms[norms == 0] = 1.0
        try:
            coef_scaled, *_ = np.linalg.lstsq(A / norms, target[rows], rcond=None)
        except np.linalg.LinAlgError as exc:  # any failure left after the column checks: one line, not a traceback
            raise FitError(f"the least-squares fit of {template.equation} failed ({exc}); the columns of its curves "
                           "and scalars are too close to dependent or too large: simplify the basis or the equation"
                           ) from None
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
        info["n_columns"] = int(A.shape[1])

    by_curve: dict[str, dict] = {nm: {} for nm in names}
    scalars, offs = {}, {}
    for (owner, key), v in zip(owners, coef):
        if owner == "__scalar":
            scalars[key] = float(v)
        elif owner == "__offset":
            offs[key] = float(v)
        elif owner not in ("__gain", "__input"):
            by_curve[owner][key] = float(v)
    curves = {}
    for nm in names:
        rep = reps[nm]
        z = D["args"][nm]
        k = rep.n_features()
        theta = np.array([[by_curve[nm].get(j, 0.0) for j in range(k)]])
        curves[nm] = rep.fitted(nm, template.arguments[nm], (float(z.min()), float(z.max())), theta,
                                scalings[nm][0], scalings[nm][1], 1.0, constant=by_curve[nm].get("const", 0.0))
    _describe(info, reps, curves, scalings, template)
    info["train_seconds"] = time.perf_counter() - t0
    model = finish_model(template, method, curves, gain, offs, scalars, record, info, mask)
    # the Gaussian posterior of the solution (._posterior_linear); a sparse fit's on its active terms
    from ._posterior_linear import LinearPosterior, active_design

    t1 = time.perf_counter()
    if sparse:
        A, norms, target, coef_scaled, owners, force_side = active_design(template, D, cols, owners, rows, coef, gain)
    model.posterior = LinearPosterior(
        template=template, reps=reps, scalings=scalings, owners=owners, A=A / norms, norms=norms,
        target=target[rows], coef_scaled=coef_scaled, rows=rows, n=n, force_side=force_side,
        pinned={nm: c.pinned_at_zero for nm, c in model.curves.items()}, features=_features_numpy)
    model.info["posterior_seconds"] = time.perf_counter() - t1
    if model.posterior.warnings():
        model.info.setdefault("warnings", []).extend(model.posterior.warnings())
    return model


#: largest magnitude a design column may reach (the record's own values are bounded the same way)
MAX_COLUMN = 1e100


def _check_columns(rep, name: str, template, phi: np.ndarray, u: np.ndarray) -> None:
    """Refuse a curve whose features are not finite or beyond :data:`MAX_COLUMN` on the record, naming the
    function (a Basis) and where it fails: ``exp(exp(z))``, ``z/0`` or ``log(z)`` ended in "SVD did not
    converge" before (issue 50)."""
    funcs = rep.function_list() if hasattr(rep, "function_list") else None
    arg = template.arguments.get(name, "z") if isinstance(getattr(template, "arguments", None), dict) else "z"
    for k in range(phi.shape[1]):
        col = phi[:, k]
        bad = ~np.isfinite(col) | (np.abs(np.nan_to_num(col, nan=0.0, posinf=np.inf, neginf=np.inf)) > MAX_COLUMN)
        if not bad.any():
            if funcs and k < len(funcs) and not col.any():  # a zero column: nothing to fit, a singular problem
                raise ConfigError(f"basis function {funcs[k]!r} of {name} is 0 on every sample of the record; "
                                  "drop it or give a function of z that varies, e.g. 'z**3'")
            continue
        i = int(np.argmax(bad))
        what = f"basis function {funcs[k]!r} of {name}" if funcs and k < len(funcs) else f"feature {k} of {name}"
        kind = "is not finite" if not np.isfinite(col[i]) else f"exceeds {MAX_COLUMN:g} in size"
        raise ConfigError(f"{what} {kind} on the record (at {arg} = {float(u[i]):.4g}, {int(bad.sum())} of "
                          f"{bad.size} samples; {arg} spans {float(np.min(u)):.4g} ... {float(np.max(u)):.4g}); "
                          "use functions that stay finite and moderate there, e.g. 'tanh(z)' or 'z**3'")


def _check_signal(what: str, sig: np.ndarray, template) -> None:
    sig = np.asarray(sig, dtype=float)
    bad = ~np.isfinite(sig) | (np.abs(np.nan_to_num(sig, nan=0.0)) > MAX_COLUMN)
    if bad.any():
        raise ConfigError(f"{what} in {template.equation} is not finite or exceeds {MAX_COLUMN:g} at "
                          f"{int(bad.sum())} of {bad.size} samples; write terms that stay finite on the record "
                          "(log and sqrt of positive signals, no division by a signal that crosses 0)")


def constant_carriers(template, reps) -> set[str]:
    """The linear curves without a constant column that carry their own constant where the gauge
    lets them: Polynomial curves, and SparseLibrary curves outside the separable family (pysindy's
    library has no bias: the separable family keeps the paper's SINDy)."""
    from ..curves import Polynomial, SparseLibrary

    return {nm for nm in template.curve_names if isinstance(reps[nm], Polynomial)
            or (isinstance(reps[nm], SparseLibrary) and template.family != "separable")}


def constant_slots(template, pinned: dict, offsets: list[int], carriers) -> list[tuple[str, str]]:
    """The constant columns a fit with ``carriers`` needs: ``("curve", name)`` for a carrier's own
    constant (odd carriers are pinned and carry none) and ``("offset", "b<e>")`` for an equation's,
    on the slots the gauge leaves free (its pivots are fixed at 0 by the anchors). A carrier that
    multiplies a signal (f1(x) x') always keeps its constant: nothing else can stand in for it."""
    slots, vecs = template._freedoms(pinned, template._priority(pinned, template.anchors, offsets))
    pivots = {p for p, _ in vecs}
    return [(kind, name) for kind, name in slots
            if (kind, name) not in pivots and kind != "scalar" and not (kind == "curve" and name not in carriers)]


def _indicator(e: int, E: int, n: int) -> np.ndarray:
    ind = np.zeros(E * n)
    ind[e * n:(e + 1) * n] = 1.0
    return ind


def _describe(info: dict, reps: dict, curves: dict, scalings: dict, template) -> None:
    """What the linear representations report in ``info`` (basis, degree, mapping, expression form...)."""
    from ..curves import Basis, Polynomial

    polys = [nm for nm, r in reps.items() if isinstance(r, Polynomial)]
    if polys:
        first = reps[polys[0]]
        info.update({"degree": int(first.degree), "rescaling": first.rescaling, "basis": first.basis_name,
                     "symmetry": {nm: reps[nm].symmetry_name for nm in polys}})
        info["mapping"] = {nm: {"center": scalings[nm][0], "half_width": scalings[nm][1]} for nm in polys}
        meta = {nm: getattr(curves[nm], "poly_info", {}) for nm in polys}
        info["coefficients_in_s"] = {nm: m.get("coefficients_in_s") for nm, m in meta.items()}
        info["expression_form"] = {nm: m.get("form") for nm, m in meta.items()}
        info["expansion_error"] = {nm: m.get("expansion_error") for nm, m in meta.items()}
    bases = {nm: r.function_list() for nm, r in reps.items() if isinstance(r, Basis)}
    if bases:
        info["basis"] = bases if not polys else info.get("basis")
        info["basis_functions"] = bases


def _sparse_fit(template, reps, sparse, D, cols, owners, rows, info, method):
    """pysindy's optimizer on the design: target x'' (the known part), columns -(features x coefficient
    signal), -(scalar signals), -(constants) and the input u, whose coefficient is the gain: fixed by
    an equality constraint (ConstrainedSR3, SINDy-CC) or free (STLSQ, the paper's SINDy)."""
    first = reps[sparse[0]]
    for nm in sparse[1:]:
        other = reps[nm]
        if (other.optimizer, other.threshold, other.alpha, other.nu, other.tol, other.max_iter) != \
                (first.optimizer, first.threshold, first.alpha, first.nu, first.tol, first.max_iter):
            raise ConfigError(f"the SparseLibrary curves {sparse[0]} and {nm} have different optimizer settings; all "
                              "SparseLibrary curves of one fit share one sparse regression")
    free = bool(template.free_gain)
    optimizer = first.resolved_optimizer(free)
    threshold = first.resolved_threshold(free)
    if optimizer == "constrained-sr3" and free:
        if method.startswith("sindy-cc"):
            raise ConfigError(f"{method} fixes the gain; use sindy for a free gain")
        raise ConfigError("the constrained SR3 optimizer fixes the gain; use optimizer='stlsq' for a free gain")
    if optimizer == "stlsq" and not free:
        raise ConfigError("sindy identifies the gain k (free_gain); use sindy-cc for a fixed gain")
    ps = import_pysindy(optimizer == "constrained-sr3")
    X = np.column_stack([-c for c in cols] + [D["F"]])[rows]
    target = D["y"][rows]
    # the library's own map (z / max|z|, SparseLibrary.scaling) and the target over its RMS: the coefficients
    # the threshold, nu and tol see are numbers relative to the target, whatever the record's units
    s = float(np.sqrt(np.mean(target**2))) if first.rescaling != "none" else 1.0
    s = s if np.isfinite(s) and s > 0 else 1.0
    X[:, -1] = X[:, -1] / s
    target = target / s
    n_feat = X.shape[1]
    if optimizer == "constrained-sr3":
        lam = l0_weight(threshold, first.nu)
        C = np.zeros((1, n_feat))
        C[0, -1] = 1.0
        opt = constrained_sr3(ps, reg_weight_lam=lam, regularizer="l0", relax_coeff_nu=first.nu, tol=first.tol,
                                max_iter=first.max_iter, constraint_lhs=C, constraint_rhs=np.array([template.gain]),
                                constraint_order="feature", equality_constraints=True)
        desc = {"optimizer": "ConstrainedSR3", "regularizer": "l0", "threshold": threshold, "reg_weight_lam": lam,
                "nu": first.nu, "tol": first.tol, "max_iter": first.max_iter}
    elif optimizer == "stlsq":
        opt = ps.STLSQ(threshold=threshold, alpha=first.alpha, max_iter=first.max_iter)
        desc = {"optimizer": "STLSQ", "threshold": threshold, "alpha": first.alpha, "max_iter": first.max_iter}
    else:
        lam = l0_weight(threshold, first.nu)
        opt = ps.SR3(reg_weight_lam=lam, regularizer="L0", relax_coeff_nu=first.nu, tol=first.tol,
                     max_iter=first.max_iter)
        desc = {"optimizer": "SR3 (l0)", "threshold": threshold, "reg_weight_lam": lam, "nu": first.nu,
                "tol": first.tol, "max_iter": first.max_iter}
    t_solve = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        opt.fit(X, target.reshape(-1, 1))
    coef = np.asarray(opt.coef_, dtype=float).reshape(-1)
    coef[:-1] = coef[:-1] * s  # back to the target's units (the input's coefficient is the gain either way)
    k_u = float(coef[-1])
    if optimizer == "sr3" or optimizer == "constrained-sr3":
        gain = float(template.gain)
    else:
        gain = k_u
        if not np.isfinite(gain) or gain == 0.0:
            raise DataError("the learned gain is zero or not finite; the record does not determine the gain")
    names = [column_name(template.arguments[o], reps[o].powers()[k]) if isinstance(k, int) and o in sparse
             else (o if o.startswith("__") else f"{o}:{k}") for o, k in owners] + ["u"]
    history = getattr(opt, "history_", None)
    info.update(desc)
    info.update({
        "library": "; ".join(f"{template.arguments[nm]}: {reps[nm].symmetry_name} powers {reps[nm].powers()}"
                             for nm in sparse) + "; identity(u)",
        "library_size": int(n_feat),
        "feature_names": names,
        "n_active_terms": int(np.count_nonzero(coef[:-1])),
        "active_terms": [nm for nm, c in zip(names[:-1], coef[:-1]) if c != 0.0],
        "u_coefficient": k_u,
        "gain_free": free,
        "converged": not any("converge" in str(w.message).lower() for w in caught),
        "iterations": None if history is None else max(len(history) - 1, 0),
        "warnings": sorted({str(w.message) for w in caught if "converge" not in str(w.message).lower()}),
        "solver_seconds": time.perf_counter() - t_solve,
        "pysindy_version": getattr(ps, "__version__", "unknown"),
        "symmetry": {nm: reps[nm].symmetry_name for nm in sparse},
    })
    return coef[:-1], gain
