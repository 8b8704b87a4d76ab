"""The benchmark's side studies: the Lyapunov exponent, MIW ensembles (Table 1), the NN-CC
sensitivity (Appendix C); noise on the state (Appendix F) is in ``_appendix_f``. Each stores its result in
``extras.json`` (or its own results store) under a signature of its settings, so reruns skip it."""

from __future__ import annotations

import time
from typing import Any

from ._results import MIW_METHODS
from ._run_files import _Context, _Extras, _log

__all__ = ["lyapunov", "miw_study", "sensitivity", "SENSITIVITY_VARIATIONS", "SENSITIVITY_FULL_EXTRA"]


def _dataset(ctx: _Context, system: str, snr: float, realization: int, noise_on: str = "force"):
    """The exact noisy record the sweep's jobs of (system, snr, realization) saw."""
    from ..data import corrupt
    from ..systems import get_system
    from ._sweep import dataset_seed

    variant = ctx.sweep.variant_of(system)
    clean = get_system(system, variant).simulate(ctx.t_end, ctx.n_points)
    seed = dataset_seed("noise", system, variant, noise_on, snr, realization, ctx.base_seed)
    return clean, corrupt(clean, snr, on=noise_on, seed=seed)


def lyapunov(ctx: _Context, extras: _Extras) -> None:
    from ..metrics import largest_lyapunov_exponent
    from ..systems import get_system

    system = get_system("duffing", ctx.sweep.variant_of("duffing"))
    sig = {"variant": system.variant, "params": system.parameters(), "t_total": ctx.sizes["lyapunov_time"]}
    if extras.get("lyapunov", sig) is not None:
        return
    _log(ctx.progress, f"Lyapunov exponent of the true Duffing over {ctx.sizes['lyapunov_time']:g} time units")
    t0 = time.perf_counter()
    p = system.parameters()
    lam = largest_lyapunov_exponent(system.f1, system.f2, system.forcing, p["x0"], p["v0"],
                                    t_total=float(ctx.sizes["lyapunov_time"]), rtol=1e-9, atol=1e-11)
    extras.put("lyapunov", sig, {"lambda_max": lam, "T_L": 1.0 / lam if lam > 0 else float("nan"),
                                 "seconds": time.perf_counter() - t0})


def _estimator(ctx: _Context, system: str, method: str, preset=None, **extra_opts):
    from ..fitting import CharacteristicCurves

    opts = ctx.sweep.fit_options(system, method)
    opts.update(extra_opts)
    opts.setdefault("threads", 1)
    if "derivatives" in opts:  # the sweeps' stored name of the differentiator
        opts["differentiator"] = opts.pop("derivatives")
    return CharacteristicCurves.from_method(method, preset=preset if preset is not None else ctx.preset, **opts)


def miw_study(ctx: _Context, extras: _Extras) -> None:
    """Table 1: f2 residuals at the training points, (i) K training seeds on one 20 dB dataset,
    (ii) one run on each of R noise realisations; MIW_range and MIW_99 of each ensemble."""
    from ..metrics import curve_residuals, miw
    from ..systems import get_system

    truth = get_system("duffing", ctx.sweep.variant_of("duffing")).true_curves()
    k, r = int(ctx.sizes["miw_seeds"]), int(ctx.sizes["miw_realizations"])
    methods = [m for m in MIW_METHODS if m in ctx.methods]
    sigs = {m: {"method": m, "preset": ctx.preset, "seeds": k, "realizations": r, "base_seed": ctx.base_seed,
                "n_points": ctx.n_points, "t_end": ctx.t_end} for m in methods}
    todo = [m for m in methods if extras.get(f"miw:{m}:{ctx.preset}", sigs[m]) is None]
    # a method and its +post-sr sibling fit the same networks (same data, same seeds): trained once
    from ..fitting import shared_fit_base

    pairs = {m: b for m in todo if (b := shared_fit_base(m)) in todo}
    for method in [m for m in todo if m not in pairs]:
        partner = next((m for m, b in pairs.items() if b == method), None)
        names = [method] + ([partner] if partner else [])
        _log(ctx.progress, f"MIW ensembles of {' and '.join(names)}: {k} seeds on one dataset, {r} noise "
                           "realisations (20 dB)")
        t0 = time.perf_counter()
        _, data0 = _dataset(ctx, "duffing", 20.0, 0)
        seed_fits = _miw_fits(ctx, names, [data0] * k, list(range(k)))
        t1 = time.perf_counter()
        datasets = [_dataset(ctx, "duffing", 20.0, i)[1] for i in range(r)]
        real_fits = _miw_fits(ctx, names, datasets, list(range(r)))
        t2 = time.perf_counter()
        for name in names:
            z, res = zip(*(curve_residuals(m, data0, truth, "f2") for m in seed_fits[name]))
            m_seeds = miw(list(z), list(res))
            z2, res2 = zip(*(curve_residuals(m, d, truth, "f2") for m, d in zip(real_fits[name], datasets)))
            m_real = miw(list(z2), list(res2))
            # seconds: the whole ensemble's, shared between the methods trained together
            extras.put(f"miw:{name}:{ctx.preset}", sigs[name], {
                "seeds": {"miw_range": m_seeds.miw_range, "miw_99": m_seeds.miw_99, "n": k,
                          "seconds": (t1 - t0) / len(names)},
                "realizations": {"miw_range": m_real.miw_range, "miw_99": m_real.miw_99, "n": r,
                                 "seconds": (t2 - t1) / len(names)}})


def _miw_fits(ctx: _Context, names: list[str], records: list, seeds: list[int]) -> dict[str, list]:
    """The fits of one method, or of a method and its +post-sr sibling from one training."""
    from ..fitting import fit_with_post_sr

    if len(names) == 1:
        return {names[0]: _estimator(ctx, "duffing", names[0]).fit_many(records, seeds=seeds)}
    plain, distilled = fit_with_post_sr(_estimator(ctx, "duffing", names[0]), _estimator(ctx, "duffing", names[1]),
                                        records, seeds=seeds)
    return {names[0]: plain, names[1]: distilled}


#: Appendix C variations tried on the run's preset (a few of the paper's rows that are quick here).
SENSITIVITY_VARIATIONS: tuple[tuple[str, Any], ...] = (
    ("activation", "softplus"), ("activation", "tanh"), ("activation", "relu"),
    ("adam_lr", 1e-3), ("adam_lr", 1e-2), ("adam_lr", 1e-1),
    ("width", 5), ("width", 10), ("width", 25),
)
#: Added with ``full``: a 100-wide network costs ~1-2 min per fit with the default preset's LM.
SENSITIVITY_FULL_EXTRA: tuple[tuple[str, Any], ...] = (("width", 100),)


def sensitivity(ctx: _Context, extras: _Extras) -> None:
    """Appendix C, feasible part: NN-CC on one 20 dB dataset per system, one setting changed at a time."""
    from ..fitting import get_preset
    from ..metrics import curve_errors
    from ..systems import get_system

    base = get_preset(ctx.preset)
    for system in ctx.systems:
        variations = SENSITIVITY_VARIATIONS + (SENSITIVITY_FULL_EXTRA if ctx.full else ())
        sig = {"system": system, "preset": base.to_dict(), "base_seed": ctx.base_seed, "n_points": ctx.n_points,
               "variations": [list(v) for v in variations]}
        if extras.get(f"sensitivity:{system}:{ctx.preset}", sig) is not None:
            continue
        _log(ctx.progress, f"Appendix C sensitivity of NN-CC on {system} (20 dB, one dataset)")
        truth = get_system(system, ctx.sweep.variant_of(system)).true_curves()
        _, data = _dataset(ctx, system, 20.0, 0)
        rows = []
        for setting, value in variations:
            change = {"hidden": (int(value),) * len(base.hidden)} if setting == "width" else {setting: value}
            preset = base.replace(name=f"{base.name}*", **change)
            t0 = time.perf_counter()
            try:
                model = _estimator(ctx, system, "nn-cc", preset=preset).fit(data).model_
                err = curve_errors(model, truth)
                rows.append({"setting": setting, "value": value, "loss": float(model.loss), "rmse_f1": err.get("f1"),
                             "rmse_f2": err.get("f2"), "seconds": time.perf_counter() - t0,
                             "is_default": _is_base(base, setting, value),
                             "effective_parameters": model.info.get("effective_parameters")})
            except Exception as exc:  # noqa: BLE001 - a diverging setting is a result, not a crash
                rows.append({"setting": setting, "value": value, "error": f"{type(exc).__name__}: {exc}"[:300],
                             "seconds": time.perf_counter() - t0, "is_default": _is_base(base, setting, value)})
        extras.put(f"sensitivity:{system}:{ctx.preset}", sig, rows)


def _is_base(base, setting: str, value) -> bool:
    if setting == "width":
        return all(h == int(value) for h in base.hidden)
    return getattr(base, setting) == value
