"""Gradient-trained fits (NN-CC and any mix of representations) on any template, many records at once.

Every equation's residual ``known + sum m f(u) + sum s a + b - g F`` is stacked equation after
equation, so one batched problem covers all equations and all records (the curves' coefficient
signals are per-sample multipliers). Each record trains ``preset.n_starts`` starts; the starts
within ``combine_tol`` of the best loss are averaged (``combine="mean"``). Unknown scalars and the
free constants of further equations are one-parameter curves times their signal.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

import numpy as np

from .._errors import ConfigError, DataError, FitError
from ..templates import EquationTemplate
from ..model import FittedModel, finish_model
from ._linear_fit import constant_carriers, constant_slots
from ._presets import TrainingPreset

__all__ = ["fit_gradient", "ConstantParametrisation"]


class ConstantParametrisation:
    """One parameter, the value everywhere (an unknown scalar or an equation's free constant)."""

    n_params = 1
    symmetry = "none"
    exact_symmetry = "none"
    symmetry_mode = "exact"
    pinned_at_zero = False

    def init(self, K, generator, dtype):
        import torch

        return torch.zeros(K, 1, dtype=dtype)

    def evaluate(self, theta, u, u_both=None):
        return theta[:, :1].expand(-1, u.shape[-1])

    def evaluate_jacobian(self, theta, u, u_both=None):
        import torch

        return self.evaluate(theta, u), torch.ones(u.shape[0], u.shape[-1], 1, dtype=theta.dtype, device=theta.device)

    def evaluate_all(self, theta, u):
        f, J = self.evaluate_jacobian(theta, u)
        return f, J, f.new_zeros(f.shape)

    def decay_groups(self) -> list:
        return []

    def linear_parts(self, theta, u, u_both=None) -> list:
        import torch

        return [(0, torch.ones(theta.shape[0], u.shape[-1], dtype=theta.dtype, device=theta.device), False)]


def fit_gradient(records: Sequence, template: EquationTemplate, reps: dict, preset: TrainingPreset,
                 seeds: Sequence[int], *, method: str, masks: Sequence[np.ndarray], jumps: Sequence[str] = (),
                 powers: dict | None = None, harmonics: dict | None = None, device: str = "cpu", threads: int | None = None, progress: Callable | None = None,
                 chunk_models: int | None = None) -> list[FittedModel]:
    """Fit K records of equal length as one batched computation; returns K fitted models.

    Parameters
    ----------
    records : sequence of Trajectory or MultiTrajectory
        Prepared records (derivatives filled in).
    template : EquationTemplate
    reps : dict
        Curve name -> representation (``Neural``, ``Polynomial``, any AbstractCurve with a parametrisation).
    preset : TrainingPreset
    seeds : sequence of int
        One per record; each record's starts come from its own seed, so records trained together
        equal records trained one by one, to rounding (a batch of one record can differ in the
        last bits; see :mod:`._problem`).
    masks : sequence of bool arrays
        The samples each record fits (sticking phases of dry friction left out).
    jumps : sequence of str
        Neural curves that get a learned jump at 0 (one layout for the whole batch).
    """
    import torch

    from ._train import chunk_log, start_weights
    from ._warm import gain_estimate, sharpen_unresolved_jumps, train_batched

    if len(records) != len(seeds):
        raise ConfigError("give one seed per trajectory")
    if len({r.n_samples for r in records}) != 1:
        raise DataError("records fitted in one batch must have the same number of samples; fit them separately")
    dtype = torch.float64 if preset.dtype == "float64" else torch.float32
    names = template.curve_names
    R = preset.n_starts
    t_start = time.perf_counter()
    params = {}
    for name in names:
        rep = reps[name]
        params[name] = (rep.network(preset, jump=name in jumps, powers=(powers or {}).get(name, ()),
                                    harmonics=(harmonics or {}).get(name, ()))
                        if rep.kind == "neural" else rep.parametrisation(preset))
    pinned = {n: bool(params[n].pinned_at_zero) for n in names}
    template.check_identifiable(pinned)
    offsets = template.offsets_needed(pinned)
    E = template.n_equations
    # linear curves without a constant column (Polynomial...) get their own constant where the gauge
    # leaves one, as in the linear fitter: a polynomial f1 of f1(x) x' needs it (without it, it was
    # pinned at its centre and bent elsewhere to make up for it)
    carriers = constant_carriers(template, reps)
    own = [n for kind, n in constant_slots(template, pinned, offsets, carriers) if kind == "curve"] if carriers else []
    # scalars, the offsets of equations 2.. and the carriers' constants are constant curves times their
    # signal; equation 1's offset is the bias
    const_names = (list(template.scalar_names) + [f"b{e + 1}" for e in offsets if E > 1]
                   + [f"const:{n}" for n in own])
    const = ConstantParametrisation()
    force_side = template.free_gain and template.gain_on == "force"

    designs, scales, scale_out, g_est, sig_scale, rows_used = [], [], [], [], [], []
    for rec, mask in zip(records, masks):
        if mask.sum() < 10:
            raise DataError("fewer than 10 samples remain after removing sticking phases; give a longer record")
        D = template.design(rec)
        designs.append(D)
        scales.append({k: reps[k].scaling(D["args"][k], preset, **({"jump": k in jumps} if reps[k].kind == "neural"
                                                                  else {})) for k in names})
        signals = dict(D["scalars"])
        signals.update({f"const:{n}": np.broadcast_to(np.asarray(D["mult"][n], dtype=float), (E * D["n"],))
                        for n in own})
        for e in offsets:
            if E > 1:
                ind = np.zeros(E * D["n"])
                ind[e * D["n"]:(e + 1) * D["n"]] = 1.0
                signals[f"b{e + 1}"] = ind
        D["const_signals"] = signals
        sig_scale.append({k: max(float(np.max(np.abs(v))), 1e-300) for k, v in signals.items()})
        rows = np.tile(mask, E)
        rows_used.append(rows)
        if force_side:
            # F = h x'' + f~ + b~: the target is the forcing. x'' is divided by a least-squares
            # estimate of g so that the learned coefficient h' = g_est / g is of order one
            # whatever the units (volts and 1e5 1/s^2 on real records).
            g_est.append(gain_estimate(D, mask, template.gain))
            s_out = float(np.std(D["F"][rows])) if preset.scale_output else 1.0
        else:
            g_est.append(1.0)
            s_out = float(np.std((D["y"] - template.gain * D["F"])[rows])) if preset.scale_output else 1.0
        scale_out.append(s_out if s_out > 0 else 1.0)

    K = len(records)
    KR = K * R
    T = lambda arr: torch.as_tensor(arr, dtype=dtype, device=device)  # noqa: E731

    def rep_(arr_list):
        """One row per (record, start): the records' rows repeated ``R`` times; a single record's
        rows are a view (no copy: the data of a long record is held once, not once per start)."""
        a = T(np.stack(arr_list))
        return a.expand(R, -1) if K == 1 else a.repeat_interleave(R, dim=0)

    y = rep_([D["y"] / so_ / g_ for D, so_, g_ in zip(designs, scale_out, g_est)])
    F = rep_([D["F"] / so_ for D, so_ in zip(designs, scale_out)])
    w = rep_([r / np.sqrt(r.sum()) for r in rows_used])

    from ._problem import BatchedProblem, CurveTerm

    terms = []
    for name in names:
        p = params[name]
        z = rep_([(np.tile(D["args"][name], E) - s[name][0]) / s[name][1] for D, s in zip(designs, scales)])
        mults = [D["mult"][name] for D in designs]
        mult = None if all(np.all(m == 1.0) for m in mults) else rep_(mults)
        sym_pts = None
        if p.symmetry != "none" and p.symmetry_mode == "penalty":
            zs = [(np.linspace(D["args"][name].min(), D["args"][name].max(), preset.n_sym) - s[name][0]) / s[name][1]
                  for D, s in zip(designs, scales)]
            sym_pts = rep_(zs)
        terms.append(CurveTerm(p, z, mult, sym_pts))
    n_rows = E * designs[0]["n"]
    for cname in const_names:
        sig = rep_([D["const_signals"][cname] / s[cname] for D, s in zip(designs, sig_scale)])
        terms.append(CurveTerm(const, torch.ones(1, n_rows, dtype=dtype, device=device).expand(KR, -1), sig, None))
    bias = E == 1 and bool(offsets)
    problem = BatchedProblem(terms, y, F, w, free_gain=template.free_gain, gain=template.gain,
                             gain_on=template.gain_on, bias=bias, lambda_sym=preset.lambda_sym, weight_decay=0.0,
                             bayesian=preset.bayesian, decay_groups=preset.decay_groups)

    def draw(gen):
        parts = [params[nm].init(1, gen, dtype) for nm in names]
        parts += [const.init(1, gen, dtype) for _ in const_names]
        if template.free_gain:
            parts.append(torch.full((1, 1), 1.0 if force_side else float(template.gain), dtype=dtype))
        if bias:
            parts.append(torch.zeros(1, 1, dtype=dtype))
        return parts

    theta, logs, log, total_loss = train_batched(problem, start_weights(seeds, R, draw).to(device), preset,
                                                 threads=threads, device=device, chunk_models=chunk_models,
                                                 progress=progress, profile_jumps=bool(jumps),
                                                 row_seeds=np.repeat(np.asarray(seeds, dtype=np.int64), R))
    decay = torch.cat([sub.decay_per_group(sub.K).to(theta.dtype) for _, sub, _ in logs])  # (KR, G)
    elapsed = time.perf_counter() - t_start
    theta = theta.double().cpu()
    # the problem's terms follow ``names``: (1, "layer 1 weights") -> "f2 layer 1 weights"
    group_names = [" ".join(filter(None, ("all networks" if i is None else names[i], part)))
                   for i, part in problem.decay_group_parts]
    # a jump whose tanh is saturated at every fitted sample has a width the data cannot see:
    # take the sharpest law they allow (Coulomb's sign) rather than an arbitrary width
    unresolved_jump = sharpen_unresolved_jumps(problem, theta) if jumps else None

    models, member_rows = [], []
    for k in range(K):
        losses = total_loss[k * R:(k + 1) * R]
        if not np.isfinite(losses).any():
            raise FitError(f"every training start of record {k} diverged to a non-finite loss; check the record "
                           "for outliers or try --preset default / another seed")
        losses = np.where(np.isfinite(losses), losses, np.inf)  # a diverged start never joins
        best = int(np.argmin(losses))
        members = (np.flatnonzero(losses <= losses[best] * (1.0 + preset.combine_tol)) if preset.combine == "mean"
                   else np.array([best]))
        rows = theta[k * R + members]
        member_rows.append(k * R + members)
        s_out = scale_out[k]
        g = float(problem.gain_of(rows).mean())
        factor = s_out
        if force_side:
            # F = h x'' + f~ + b~  <=>  x'' + g f~ + g b~ = g F with g = 1/h
            g = g_est[k] / g
            factor = s_out * g
        scal = {}
        for j, cname in enumerate(const_names):
            val = float(problem.block(rows, len(names) + j)[:, 0].mean())
            scal[cname] = val * factor / sig_scale[k][cname]
        own_const = {n: scal.pop(f"const:{n}") for n in own}
        fitted = {}
        for i, name in enumerate(names):
            z = designs[k]["args"][name]
            center, half = scales[k][name]
            extra = {"network": params[name]} if reps[name].kind == "neural" else {}
            if name in own_const:
                extra["constant"] = own_const[name]
            fitted[name] = reps[name].fitted(name, template.arguments[name], (float(z.min()), float(z.max())),
                                             problem.block(rows, i).numpy(), center, half, factor, **extra)
        offs = {e: scal.pop(f"b{e + 1}") for e in offsets if E > 1}
        if bias:
            offs[0] = float(problem.bias_of(rows).mean()) * factor
        mask = masks[k]
        info = {
            "preset": preset.name,
            "preset_settings": preset.to_dict(),
            "seed": int(seeds[k]),
            "n_starts": R,
            "best_start": best,
            "ensemble_members": int(members.size),
            "adam_steps": log.adam_steps,
            "lm_iterations": log.lm_iterations,
            **({"long_record": {"subset_samples": log.subset_samples, "refine_iterations": log.refine_iterations}}
               if log.subset_samples else {}),
            "stopped_by": log.stopped_by,
            "interrupted": log.interrupted,
            "n_samples": int(mask.size),
            "n_fitted_samples": int(mask.sum()),
            "n_sticking_samples": int(mask.size - mask.sum()),
            "total_loss": float(total_loss[k * R + best] * s_out**2),
            "train_seconds": elapsed / K,
            "batch_size": K,
            "weight_decay": [float(d) for d in decay[k * R + best]],
            "weight_decay_groups": group_names,
            "effective_parameters": (log.effective_parameters[k * R + best] if log.effective_parameters else None),
        }
        if E > 1:
            info["n_equations"] = E
        if log.interrupted:  # say what this record's own chunk did: finished, interrupted or never trained
            chunk = chunk_log(logs, k * R)
            info.update(adam_steps=chunk.adam_steps, lm_iterations=chunk.lm_iterations, stopped_by=chunk.stopped_by)
        if unresolved_jump is not None:
            info["jump_width_unresolved"] = bool(unresolved_jump[k * R + members].all())
        models.append(finish_model(template, method, fitted, g, offs, scal, records[k], info,
                                   mask if E == 1 else None))
    if not log.interrupted:  # the Laplace posterior of each fit (._posterior_network)
        from ._posterior_network import network_posteriors

        ctx = {"template": template, "names": list(names), "params": params, "const_names": const_names, "own": own,
               "neural": {nm: reps[nm].kind == "neural" for nm in names}, "force_side": force_side,
               "gain": template.gain, "gain_index": problem.gain_index, "bias_index": problem.bias_index,
               "offsets": problem.offsets, "offset_keys": list(offsets), "E": E, "n": designs[0]["n"],
               "N_rows": n_rows,
               "per_record": [{"scales": scales[k], "s_out": scale_out[k], "g_est": g_est[k],
                               "sig_scale": sig_scale[k]} for k in range(K)]}
        gauge_offs = sorted(({0} if bias else set()) | ({e for e in offsets} if E > 1 else set()))
        from ._posterior_network import gauge_map

        ctx["gauge"] = gauge_map(template, list(names), gauge_offs, pinned)
        network_posteriors(problem, theta, decay.double().cpu(), ctx, member_rows, models)
    return models
