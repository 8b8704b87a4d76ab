"""Figures of the benchmark report that simulate models and systems: forward integrations (Fig. 6)
and the phase space of the training data and validation trajectories (Fig. 7)."""

from __future__ import annotations

import math
import os
from typing import cast

import numpy as np

__all__ = ["forward_panels", "phase_space"]


def _fig(*args, **kw):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt.subplots(*args, **kw)


def _systems(df) -> list[str]:
    return [s for s in ("duffing", "stick-slip") if len(df) and s in set(df["system"])]


# ---------------------------------------------------------------------- Fig. 6
def forward_panels(rep, df, ctx) -> None:
    from ..report._study import plot_forward

    rep.heading("Forward integrations, training and new initial conditions (Fig. 6)")
    sub = df[(df["system"] == "duffing") & (df["status"] == "ok")] if len(df) else df
    if not len(sub):
        rep.paragraph("Not drawn: no fitted Duffing model in this run.")
        return
    snr = 20.0 if 20.0 in set(sub["snr_db"]) else float(sorted(set(sub["snr_db"]))[len(set(sub["snr_db"])) // 2])
    prefer = ["nn-cc", "nn-cc+sym", "nn-cc+sym+post-sr"]
    avail = sub[(sub["snr_db"] == snr) & (sub["realization"] == sub["realization"].min())]
    chosen = [m for m in prefer if m in set(avail["method"])] or list(dict.fromkeys(avail["method"]))[:3]
    from ..fitting import load_model
    from ..simulate import simulate_model
    from ..systems import BenchmarkSystem, get_system

    system = get_system("duffing", str(avail["variant"].iloc[0]))
    assert isinstance(system, BenchmarkSystem)
    p = system.parameters()
    t = np.linspace(0.0, 40.0, 1000)
    ics = [("training ICs", p["x0"], p["v0"]), ("new ICs x0 = 0.6, v0 = −0.1", 0.6, -0.1)]
    fig, axes = _fig(len(ics), len(chosen), figsize=(4.6 * len(chosen), 3.0 * len(ics)), squeeze=False)
    notes = []
    for j, method in enumerate(chosen):
        row = avail[avail["method"] == method].iloc[0]
        path = row["_model_path"] if "_model_path" in avail.columns else None
        model = None
        if isinstance(path, str) and os.path.isdir(path):
            try:
                model = load_model(path)
            except Exception as exc:  # noqa: BLE001
                notes.append(f"{method}: saved model unreadable ({type(exc).__name__})")
        for i, (label, x0, v0) in enumerate(ics):
            truth = system.simulate(t_eval=t, x0=x0, v0=v0)
            models = {}
            if model is not None:
                res = simulate_model(model, t, x0, v0, lambda tt: p["A"] * math.cos(p["Omega"] * tt),
                                     rtol=1e-8, atol=1e-10, time_budget=20.0)
                models[f"{method} ({res.status})" if res.status != "ok" else method] = (res.t, res.x)
            plot_forward(t, truth.x, models, ax=axes[i][j], title=f"{method}: {label}")
    fig.tight_layout()
    rep.figure(fig, "forward-duffing", caption=f"Duffing, models fitted at {snr:g} dB (realisation 0), integrated "
                                               "from the training initial conditions (top) and from x0 = 0.6, "
                                               "v0 = −0.1 (bottom) under the training forcing.")
    if notes:
        rep.bullets(notes)


# ---------------------------------------------------------------------- Fig. 7
def phase_space(rep, df, ctx, extras) -> None:
    from ..report._study import plot_phase_space
    from ..systems import get_system
    from ._validation import make_validation_cases, training_box

    rep.heading("Dynamics interpolation: training data and validation trajectories (Fig. 7)")
    systems = _systems(df) or (list(ctx.systems) if ctx is not None else [])
    if not systems:
        rep.paragraph("No system in this run.")
        return
    fig, axes = _fig(len(systems), 2, figsize=(9.0, 4.0 * len(systems)), squeeze=False)
    for i, name in enumerate(systems):
        variant = ctx.sweep.variant_of(name) if ctx is not None else "paper"
        system = get_system(name, variant)
        train = system.simulate()
        assert train.v is not None  # a simulated record has the velocity
        box = training_box(train)
        sig = {"system": name, "variant": variant, "cases": 10}
        others = extras.get(f"phase:{name}:{variant}", sig)
        if others is None:
            # a picture only: looser tolerances than the validation itself, about 3x faster
            loose = get_system(name, variant, rtol=1e-6, atol=1e-8)
            cases = make_validation_cases(loose, 10, seed=0, box=box, warn=False)
            # make_validation_cases fills the true trajectories
            others = [(cast(np.ndarray, c.x_true)[::2].tolist(), cast(np.ndarray, c.v_true)[::2].tolist())
                      for c in cases]
            extras.put(f"phase:{name}:{variant}", sig, others)
        plot_phase_space(train.x, train.v, ax=axes[i][0], box=box, title=f"{name}: training record")
        plot_phase_space([], [], ax=axes[i][1], box=box, others=others,
                         title=f"{name}: {len(others)} validation trajectories")
    fig.tight_layout()
    rep.figure(fig, "phase-space", caption="Left: the training trajectory and its box (grey). Right: validation "
                                           "trajectories of the true system from random initial conditions and "
                                           "forcing, kept only when they stay inside the box.")
