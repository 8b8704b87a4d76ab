"""Figures of the benchmark report that simulate models and systems: forward integrations (Fig. 6)
and the phase space of the training data and validation trajectories (Fig. 7).

The simulations run once, with the benchmark (:func:`figure_data`, which needs the saved models),
and their trajectories are kept in ``extras.json``; the report draws them from there, so that it
can be rebuilt from the committed files alone."""

from __future__ import annotations

import math
import os
from typing import cast

import numpy as np

__all__ = ["forward_panels", "phase_space", "figure_data"]


def _fig(*args, **kw):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt.subplots(*args, **kw)


def _systems(df) -> list[str]:
    return [s for s in ("duffing", "stick-slip") if len(df) and s in set(df["system"])]


# ---------------------------------------------------------------------- data (run stage)
_FORWARD_ICS = (("training ICs", None, None), ("new ICs x0 = 0.6, v0 = −0.1", 0.6, -0.1))


def _forward_choice(df):
    """(SNR level, realisation-0 rows of the chosen methods) of Fig. 6, or None without Duffing fits."""
    sub = df[(df["system"] == "duffing") & (df["status"] == "ok")] if len(df) else df
    if not len(sub):
        return None
    levels = set(sub["snr_db"])
    snr = 20.0 if 20.0 in levels else float(sorted(levels)[len(levels) // 2])
    avail = sub[(sub["snr_db"] == snr) & (sub["realization"] == sub["realization"].min())]
    prefer = ["nn-cc", "nn-cc+sym", "nn-cc+sym+post-sr"]
    chosen = [m for m in prefer if m in set(avail["method"])] or list(dict.fromkeys(avail["method"]))[:3]
    return snr, avail, chosen


def figure_data(df, variants: dict, extras) -> None:
    """Simulate what Figs. 6 and 7 draw and keep it in ``extras`` ("forward:duffing", "phase:SYSTEM:VARIANT").

    ``df``: the store's frame (with the saved models' paths); ``variants``: system -> variant.
    """
    _forward_data(df, extras)
    for name, variant in variants.items():
        _phase_data(name, variant, extras)


def _forward_data(df, extras) -> None:
    from ..model import load_model
    from ..simulate import simulate_model
    from ..systems import BenchmarkSystem, get_system

    choice = _forward_choice(df)
    if choice is None:
        return
    snr, avail, chosen = choice
    rows = {m: avail[avail["method"] == m].iloc[0] for m in chosen}
    variant = str(avail["variant"].iloc[0])
    sig = {"snr": snr, "variant": variant, "methods": chosen,
           "finished": [str(rows[m].get("_finished", "")) for m in chosen]}
    if extras.get("forward:duffing", sig) is not None:
        return
    system = get_system("duffing", variant)
    assert isinstance(system, BenchmarkSystem)
    p = system.parameters()
    t = np.linspace(0.0, 40.0, 1000)
    value: dict = {"snr": snr, "realization": int(avail["realization"].iloc[0]), "variant": variant, "methods": {},
                   "notes": []}
    for method in chosen:
        path = rows[method].get("_model_path")
        if not (isinstance(path, str) and os.path.isdir(path)):
            value["notes"].append(f"{method}: no saved model")
            continue
        try:
            model = load_model(path)
        except Exception as exc:  # noqa: BLE001
            value["notes"].append(f"{method}: saved model unreadable ({type(exc).__name__})")
            continue
        runs = []
        for _, x0, v0 in _FORWARD_ICS:
            res = simulate_model(model, t, p["x0"] if x0 is None else x0, p["v0"] if v0 is None else v0,
                                 lambda tt: p["A"] * math.cos(p["Omega"] * tt), rtol=1e-8, atol=1e-10,
                                 time_budget=20.0)
            on_grid = len(res.t) <= len(t) and np.array_equal(np.asarray(res.t), t[:len(res.t)])
            runs.append({"status": res.status, "x": [round(float(v), 7) for v in res.x],
                         **({} if on_grid else {"t": [round(float(v), 9) for v in res.t]})})
        value["methods"][method] = runs
    extras.put("forward:duffing", sig, value)


def _phase_data(name: str, variant: str, extras) -> None:
    from ..systems import get_system
    from ..metrics import make_validation_cases, training_box

    sig = {"system": name, "variant": variant, "cases": 10}
    if extras.get(f"phase:{name}:{variant}", sig) is not None:
        return
    train = get_system(name, variant).simulate()
    # a picture only: looser tolerances than the validation itself, about 3x faster
    loose = get_system(name, variant, rtol=1e-6, atol=1e-8)
    cases = make_validation_cases(loose, 10, seed=0, box=training_box(train), warn=False)
    # make_validation_cases fills the true trajectories
    others = [([round(float(v), 6) for v in cast(np.ndarray, c.x_true)[::2]],
               [round(float(v), 6) for v in cast(np.ndarray, c.v_true)[::2]]) for c in cases]
    extras.put(f"phase:{name}:{variant}", sig, others)


def _value(extras, key: str):
    entry = extras.data.get(key)
    return entry.get("value") if entry else None


# ---------------------------------------------------------------------- Fig. 6
def forward_panels(rep, df, extras) -> None:
    from ..report import plot_forward
    from ..systems import BenchmarkSystem, get_system

    rep.heading("Forward integrations, training and new initial conditions (Fig. 6)")
    data = _value(extras, "forward:duffing")
    if _forward_choice(df) is None or data is None:
        rep.paragraph("Not drawn: no fitted Duffing model in this run." if _forward_choice(df) is None else
                      "Not drawn: extras.json holds no forward integrations (written by a benchmark run since "
                      "this release, from the saved models).")
        return
    chosen = list(data["methods"]) or ["(none)"]
    system = get_system("duffing", data["variant"])
    assert isinstance(system, BenchmarkSystem)
    p = system.parameters()
    t = np.linspace(0.0, 40.0, 1000)
    fig, axes = _fig(len(_FORWARD_ICS), len(chosen), figsize=(4.6 * len(chosen), 3.0 * len(_FORWARD_ICS)),
                     squeeze=False)
    for j, method in enumerate(chosen):
        for i, (label, x0, v0) in enumerate(_FORWARD_ICS):
            truth = system.simulate(t_eval=t, x0=p["x0"] if x0 is None else x0, v0=p["v0"] if v0 is None else v0)
            models = {}
            if method in data["methods"]:
                r = data["methods"][method][i]
                key = f"{method} ({r['status']})" if r["status"] != "ok" else method
                x = np.asarray(r["x"], dtype=float)
                models[key] = (np.asarray(r["t"], dtype=float) if "t" in r else t[:len(x)], x)
            plot_forward(t, truth.x, models, ax=axes[i][j], title=f"{method}: {label}")
    fig.tight_layout()
    rep.figure(fig, "forward-duffing", caption=f"Duffing, models fitted at {data['snr']:g} dB (realisation "
                                               f"{data['realization']}), integrated from the training initial "
                                               "conditions (top) and from x0 = 0.6, v0 = −0.1 (bottom) under the "
                                               "training forcing.")
    if data["notes"]:
        rep.bullets(data["notes"])


# ---------------------------------------------------------------------- Fig. 7
def phase_space(rep, df, run, extras) -> None:
    from ..report import plot_phase_space
    from ..systems import get_system
    from ..metrics import training_box

    rep.heading("Dynamics interpolation: training data and validation trajectories (Fig. 7)")
    variants = dict(run.get("variants", {}))
    systems = [s for s in (_systems(df) or list(variants)) if _value(extras, f"phase:{s}:{variants.get(s, 'paper')}")]
    if not systems:
        rep.paragraph("No validation trajectories in extras.json (no system run, or a run of an older release).")
        return
    fig, axes = _fig(len(systems), 2, figsize=(9.0, 4.0 * len(systems)), squeeze=False)
    for i, name in enumerate(systems):
        variant = variants.get(name, "paper")
        train = get_system(name, variant).simulate()
        assert train.v is not None  # a simulated record has the velocity
        box = training_box(train)
        others = _value(extras, f"phase:{name}:{variant}")
        plot_phase_space(train.x, train.v, ax=axes[i][0], box=box, title=f"{name}: training record")
        plot_phase_space([], [], ax=axes[i][1], box=box, others=others,
                         title=f"{name}: {len(others)} validation trajectories")
    fig.tight_layout()
    rep.figure(fig, "phase-space", caption="Left: the training trajectory and its box (grey). Right: validation "
                                           "trajectories of the true system from random initial conditions and "
                                           "forcing, kept only when they stay inside the box.")
