"""What ``CharacteristicCurves.fit_many`` does, step by step, for every method and composition.

1. resolve the template and a representation per curve (method presets fill unset curves);
2. prepare each record: derivatives given or estimated by the differentiator, identifiability checks;
3. the samples each record fits (sticking phases left out) and the learned jumps (dry friction);
4. the fit by equation error through the one fitting path (:mod:`._fit_path`);
5. the objective's refit of the fitted curves, on the records it refines (``objective.refines``;
   output error: every record; "auto": those whose derivatives were estimated);
6. post-SR (closed forms), when asked: it distils the curves output error refined (not the
   equation-error fit, whose curves carry the differentiated noise), and output error then refits
   the closed forms' constants (records that went through step 5);
7. the settings that shaped the answer, stored in each model's ``info["settings"]``;
8. the self-check (:mod:`._self_check`): each equation's loss against the record's noise floor,
   in ``info["self_check"]``, with a warning in ``info["warnings"]`` when far above it.

Ctrl-C during training keeps the best weights so far; during post-SR or output error it keeps the
finished fit and says what was skipped.
"""

from __future__ import annotations

from .._errors import ConfigError
from ._fit_path import fit_records, fitter_kind, resolve_jumps
from ._methods import METHODS, check_method_options
from ..objectives import resolve_objective
from ._sticking import sticking_masks
from ._self_check import derivative_noise, measured_state_noise, self_check
from ._priors import name_prior_in_warnings, priors_record
from ._records import RecordSet, per_record_residual_tests, record_report

__all__ = ["run_pipeline", "raw_fit", "fit_with_post_sr", "check_device", "differentiator_used"]


def check_device(device: str) -> None:
    """A torch device that exists on this machine (only gradient-trained curves use one)."""
    import torch

    try:
        dev = torch.device(device)
    except (RuntimeError, TypeError, ValueError):
        raise ConfigError(f"unknown device {device!r}; use --device cpu or cuda") from None
    if dev.type == "cuda" and not torch.cuda.is_available():
        raise ConfigError(f"device {device!r} asked for, but CUDA is not available on this machine; use --device cpu")
    if dev.type not in ("cpu", "cuda"):
        raise ConfigError(f"device {device!r} is not supported; use --device cpu or cuda")


def differentiator_used(record, value, estimated: bool) -> str:
    """What gave the derivatives: the record's own columns, or the differentiator ("auto" resolved)."""
    from ..data import make_differentiator

    if not estimated:
        return "given (the record's derivative columns)"
    if isinstance(value, str) and value.strip().lower() in ("auto", "given"):
        uniform = getattr(record, "sampling_nonuniformity", lambda: 0.0)() <= 1e-3
        return repr(make_differentiator("spectral" if uniform else "spline")) + " (auto)"
    return repr(make_differentiator(value))


def raw_fit(est, records, seeds=None):
    """The equation-error fits alone (no post-SR, no output error) and the prepared records.

    Examples
    --------
    >>> from charcurves.data import corrupt
    >>> from charcurves.fitting import CharacteristicCurves, raw_fit
    >>> from charcurves.systems import get_system
    >>> measured = corrupt(get_system("duffing").simulate(), 30, on="state", seed=0)
    >>> [model], [prepared] = raw_fit(CharacteristicCurves.from_method(method="parametric", basis="f1=z; f2=z, z**3"), [measured])
    >>> measured.has_derivatives, prepared.has_derivatives, "output_error" in model.info
    (False, True, False)
    """
    ctx = _fit_stage(est, list(records), seeds)
    return ctx["models"], ctx["prepared"]


def _fit_stage(est, records: list, seeds):
    from ._records import prepare_any

    tmpl, structure, sym, method = est.resolve()
    objective = resolve_objective(est.objective, est.refine, est.refine_options)
    preset = est.preset_object()
    reps = tmpl.curves
    kind = fitter_kind(reps)
    if kind == "gradient":
        check_device(est.device)
    options = check_method_options(method, est.options) if method in METHODS else dict(est.options or {})
    diff = est.differentiator_value()
    prepared, estimated = [], []
    for rec in records:
        p, e = prepare_any(rec, structure, sym, diff, f"method {method}", est.without_prior)
        prepared.append(p)
        estimated.append(e)
    if seeds is None:
        seeds = [est.random_state + i for i in range(len(prepared))]
    # --jump none says the record has no dry friction: then no sample is left out as sticking either
    exclude = bool(est.exclude_sticking) and bool(options.get("exclude_sticking", True)) and \
        not (isinstance(est.jump, str) and est.jump.strip().lower() in ("none", ""))
    masks = sticking_masks(prepared, structure, estimated, exclude=exclude, kind=kind,
                           stick_tol=options.get("stick_tol", "default"))
    jumps = resolve_jumps(reps, prepared, structure, estimated, preset) if kind == "gradient" else \
        [((), (), ()) for _ in prepared]
    use_oe = [objective.refines(e, preset) for e in estimated]
    fit_preset = objective.start_preset(preset, estimated)  # output error keeps every member of the start
    fit_kw = {"method": method, "options": options, "sr_options": dict(est.sr_options or {}), "device": est.device,
              "threads": est.threads, "progress": est.progress}
    models = fit_records(prepared, structure, reps, fit_preset, seeds, masks=masks, jumps=jumps, **fit_kw)
    if kind == "gradient" and preset.auto_terms and preset.check_auto_terms and \
            not any(m.info.get("interrupted") for m in models):
        # a term a test added stays only where it helps (held out: ._heldout_terms; AIC: ._auto_terms)
        plain = resolve_jumps(reps, prepared, structure, estimated, preset, automatic=False)
        models, jumps, notes = _check_terms(prepared, models, masks, jumps, plain, structure, reps, preset,
                                            lambda idx, lay, msk: fit_records(
                                                [prepared[i] for i in idx], structure, reps, fit_preset,
                                                [seeds[i] for i in idx], masks=list(msk), jumps=list(lay), **fit_kw))
        for m, note in zip(models, notes):
            if note is not None:
                m.info["automatic_terms"] = note
    return {"models": models, "prepared": prepared, "estimated": estimated, "seeds": seeds,
            "objective": objective, "preset": preset, "reps": reps, "structure": structure, "sym": sym,
            "method": method, "diff": diff, "jumps": jumps, "use_oe": use_oe, "masks": masks}


def _check_terms(prepared, models, masks, jumps, plain, structure, reps, preset, fit):
    """The models and layouts after the check of the automatic terms that ``preset.auto_terms_rule`` names."""
    if preset.auto_terms_rule == "aic":
        from ._auto_terms import check_layouts

        models, notes = check_layouts(prepared, models, masks, jumps, plain, n_equations=structure.n_equations,
                                      refit=lambda idx: fit(idx, [plain[i] for i in idx], [masks[i] for i in idx]))
        return models, [j if n is None or n["kept"] else p for j, p, n in zip(jumps, plain, notes)], notes
    from ._heldout_terms import choose_terms

    names = [n for n, r in reps.items() if r.kind == "neural"]
    return choose_terms(prepared, models, masks, jumps, plain, structure, names, fit)


def run_pipeline(est, records: list, seeds=None) -> list:
    return _finish(est, _fit_stage(est, records, seeds), records)


def fit_with_post_sr(plain, distilled, records, seeds=None) -> tuple[list, list]:
    """The fits of two estimators that differ only in post-SR, from one equation-error fit.

    ``plain`` fits without post-SR (e.g. method "nn-cc"), ``distilled`` with it ("nn-cc+post-sr"):
    the networks (or libraries) they train are the same, so they are trained once and finished
    twice. Each list equals what ``est.fit_many(records, seeds)`` returns for that estimator.
    Output error, where it runs, comes before post-SR (:func:`run_pipeline`), so it is shared too:
    the distilled models start from the plain ones.

    Examples
    --------
    >>> from charcurves.fitting import CharacteristicCurves, fit_with_post_sr
    >>> from charcurves.systems import get_system
    >>> record = get_system("duffing").simulate()
    >>> plain, closed = fit_with_post_sr(CharacteristicCurves.from_method(method="sindy-cc+sym"),
    ...                                  CharacteristicCurves.from_method(method="sindy-cc+sym+post-sr"), [record])
    >>> plain[0].method, closed[0].method, closed[0].curves["f2"].kind
    ('sindy-cc+sym', 'sindy-cc+sym+post-sr', 'symbolic')
    """
    import copy

    check = _post_sr_pair(plain, distilled)
    if check:
        raise ConfigError(f"fit_with_post_sr needs two estimators that differ only in post-SR: {check}")
    records = list(records)
    if any(e.tests_priors() or (isinstance(e.symmetry, str) and e.symmetry.strip().lower() == "auto")
           for e in (plain, distilled)):
        return plain.fit_many(records, seeds), distilled.fit_many(records, seeds)  # parities detected per fit
    ctx = _fit_stage(plain, records, seeds)
    refined = _refine(plain, ctx, records)
    models, stop = refined
    copies = [copy.copy(m) for m in models]
    for m in copies:  # post-SR builds new models; the plain ones get their own info to finish
        m.info = copy.deepcopy(m.info)
    out = (_finish(plain, ctx, records, refined),
           _finish(distilled, dict(ctx, method=distilled.resolve()[3]), records, (copies, stop)))

    for est, fitted in zip((plain, distilled), out):
        for m in fitted:
            m.info["priors"] = priors_record(est, m)
            name_prior_in_warnings(m)  # as fit_many does: the two fits done apart warn alike
    return out


def _post_sr_pair(plain, distilled) -> str:
    """Why two estimators are not a (without, with) post-SR pair; "" when they are."""
    if plain.wants_post_sr() or not distilled.wants_post_sr():
        return "the first must fit without post-SR and the second with it"
    a, b = plain.get_params(deep=False), distilled.get_params(deep=False)
    ma, mb = plain.method_name(), distilled.method_name()
    spec_a = {k: v for k, v in METHODS.get(ma, {}).items() if k != "post_sr"}
    spec_b = {k: v for k, v in METHODS.get(mb, {}).items() if k != "post_sr"}
    if spec_a != spec_b:
        return f"methods {ma!r} and {mb!r} fit different curves"
    if spec_a.get("representation") in ("sr", "sr-cc"):
        return "symbolic fits take their SR options in the fit itself"
    differ = sorted(k for k in set(a) | set(b) if k not in ("method", "post_sr", "sr_options") and a.get(k) != b.get(k))
    return f"they differ in {', '.join(differ)}" if differ else ""


def _refine(est, ctx: dict, records: list, models=None, stop: bool | None = None) -> tuple[list, bool]:
    """The objective's refit of the models (the fit stage's by default) on the records it refines."""
    models = ctx["models"] if models is None else models
    if stop is None:
        stop = any(m.info.get("interrupted") for m in models)
    return _objective_stage(models, ctx["prepared"], records, ctx["use_oe"], ctx["objective"], ctx["preset"],
                            est.progress, stop)


def _finish(est, ctx: dict, records: list, refined: tuple[list, bool] | None = None) -> list:
    """Output error (unless ``refined`` gives its result), post-SR and output error of the closed
    forms, the settings and the self-check of the fit stage's models."""
    prepared, estimated, seeds = ctx["prepared"], ctx["estimated"], ctx["seeds"]
    objective, preset, reps = ctx["objective"], ctx["preset"], ctx["reps"]
    structure, sym, method, diff, jumps = ctx["structure"], ctx["sym"], ctx["method"], ctx["diff"], ctx["jumps"]
    models, stop = _refine(est, ctx, records) if refined is None else refined
    if est.wants_post_sr():
        models, stop = _post_sr(est, models, prepared, seeds, stop)
        models, stop = _refine(est, ctx, records, models, stop)
    for k, m in enumerate(models):
        m.method = method
        if stop:
            m.info["interrupted"] = True
        m.info["settings"] = {
            "template": structure.equation,
            "family": structure.family,
            "curves": {n: repr(r) for n, r in reps.items()},
            "differentiator": differentiator_used(prepared[k], diff, estimated[k]),
            "objective": objective.applied(estimated[k], preset),
            "objective_requested": objective.name,
            "post_sr": est.wants_post_sr(),
            **({"sr_operators": _sr_operators(est)} if est.wants_post_sr() or method.startswith("sr") else {}),
            "preset": preset.name,
            "symmetry": dict(sym),
            "jumps": list(jumps[k][0]),
            "polynomial_terms": {n: list(p) for n, p in jumps[k][1]},
            "harmonic_terms": _harmonic_terms(m, jumps[k]),
            "gauge": list(structure.anchors),
        }
        _check(est, ctx, m, records[k], k)
        if isinstance(records[k], RecordSet):  # several records in one fit: each one's losses
            per_record_residual_tests(m, records[k], prepared[k], ctx["masks"][k])
            m.info["records"] = record_report(m, records[k], prepared[k], ctx["masks"][k])
    return models


def _sr_operators(est):
    """The operator option of post-SR / SR as asked: "auto" or the list of names."""
    from ..symbolic import operators_option

    ops = operators_option(est.sr_options)
    return "auto" if ops is None else list(ops)


def _harmonic_terms(model, layout) -> dict:
    """The harmonic terms of each curve as angular frequencies per unit of its argument."""
    out = {}
    for name, ws in layout[2]:
        scale = getattr(model.curves.get(name), "in_scale", 1.0)
        out[name] = [round(w / scale, 8) for w in ws]
    return out


def _check(est, ctx, model, raw, k: int) -> None:
    """The self-check of one model, with the state's noise carried through the estimated derivatives
    or, for measured derivative columns, through the curves."""
    from ._lack_of_fit import apply_lack_of_fit
    from ._records import prepare_any

    prepared, mask, estimated = ctx["prepared"][k], ctx["masks"][k], bool(ctx["estimated"][k])
    if estimated:
        def prepare(rec):
            return prepare_any(rec, ctx["structure"], ctx["sym"], ctx["diff"], f"method {ctx['method']}",
                                  est.without_prior)[0]

        noise = derivative_noise(model, raw, prepared, prepare, mask, seed=ctx["seeds"][k])
        via = "the estimated derivatives"
    else:  # measured x, x' (and x''): their noise passes through the curves
        noise = measured_state_noise(model, prepared, mask, seed=ctx["seeds"][k])
        via = "the curves (errors in variables: noisy measured x and x' columns)"
    self_check(model, prepared, mask, estimated=estimated, snr_db=est.snr_db, state_noise=noise, raw=raw,
               state_noise_via=via)
    apply_lack_of_fit(model, prepared, mask)  # the bands of curves the residual says are misfitted


def _post_sr(est, models, prepared, seeds, stop):
    """Distil every model (Ctrl-C keeps the finished networks of the models not distilled yet: Operon
    does not watch for Ctrl-C, it takes effect when the current curve's search returns)."""
    from ._post_sr import distill_model

    done = []
    for m, s, tr in zip(models, seeds, prepared):
        if not stop:
            try:
                d = distill_model(m, sr_options=dict(est.sr_options or {}), random_state=int(s), traj=tr,
                                  progress=est.progress)
                if "output_error" in d.info:  # the curves' refinement; the closed forms get their own
                    d.info["output_error_before_post_sr"] = d.info.pop("output_error")
                done.append(d)
                continue
            except KeyboardInterrupt:
                stop = True
        m.info["post_sr"] = "skipped: interrupted"
        done.append(m)
    return done, stop


def _objective_stage(models, prepared, raw, use_oe, objective, preset, progress, stop):
    out = []
    for m, p, r, wanted in zip(models, prepared, raw, use_oe):
        if wanted and not stop:
            try:
                named = None if progress is None else \
                    (lambda phase, *rest: progress(f"output error {phase}", *rest))  # noqa: B023 (called here only)
                out.append(objective.refine(m, p, r, preset=preset, progress=named))
                stop = stop or bool(out[-1].info.get("interrupted"))
                continue
            except KeyboardInterrupt:  # keep the finished fit, without output error, and say so
                stop = True
        if wanted and stop:
            m.info["refine"] = "skipped: interrupted"
        out.append(m)
    return out, stop
