"""Appendix F of the paper, noise on x: the paper's protocol beside charcurves' default, run and reported.

Only x is measured (``corrupt(..., on="state")`` drops v and a; the forcing stays clean, as in the
authors' scripts). Two protocols fit every record:

* ``paper``: v and a from the Savitzky-Golay filter (window 31, order 3, the scripts' setting) and
  equation error, as the paper's Appendix F;
* ``default``: what ``charcurves fit`` does on such a record (``objective="auto"``): an
  equation-error start from the default differentiator, then output error (simulation error on
  multiple-shooting segments). With the ``paper`` training preset ``auto`` means equation error, so
  only the paper protocol runs then.

Each protocol has its own results store (``appendix_f.sqlite``, ``appendix_f_default.sqlite``, to
resume a rerun) and CSV (``appendix_f.csv``, ``appendix_f_default.csv``, what the report is built from).
"""

from __future__ import annotations

import os

import numpy as np

from . import _paper_values as paper
from ._results import BENCHMARK_TAG, _write_csv, committed_csv, read_results_csv, results_frame
from ._run_files import _Context, _log, _sr_budget
from ._tables import _snr_of, _snr_text, a_fit_table, ensemble_table

__all__ = ["PROTOCOLS", "appendix_f", "appendix_f_section", "protocol_frames"]

#: name -> (store stem, fit options, description)
PROTOCOLS: dict[str, tuple[str, dict, str]] = {
    "paper": ("appendix_f", {"derivatives": "savgol", "objective": "equation-error"},
              "Savitzky-Golay v, a (window 31, order 3, as the scripts) and equation error (the paper)"),
    "default": ("appendix_f_default", {},
                "charcurves' default (objective auto): equation-error start from the default differentiator, "
                "then output error on the measured x"),
}


def _protocols_for(preset: str) -> list[str]:
    # with the paper preset, objective "auto" is equation error: the default protocol would repeat the paper's
    return ["paper"] if preset == "paper" else ["paper", "default"]


def appendix_f(ctx: _Context) -> tuple[int, int, int]:
    """Run the Appendix F sweeps (noise on x, CC errors only, no forward validation, as the scripts).
    Returns (jobs, jobs run now, jobs failed in the stores) over the protocols."""
    from ._sweep import Sweep, run_sweep

    reals = min(int(ctx.sizes["realizations"]), int(ctx.sizes["appendix_f_realizations"]))
    n_jobs = n_run = n_failed = 0
    for name in _protocols_for(ctx.preset):
        stem, options, text = PROTOCOLS[name]
        sweep = Sweep(systems=ctx.systems, methods=ctx.methods, snr_db=ctx.sizes["snr_db"],
                      realizations=reals, noise_on="state", options=dict(options),
                      method_options=_sr_budget(ctx.methods, ctx.sizes["sr_generations"]),
                      preset=ctx.preset, t_end=ctx.t_end, n_points=ctx.n_points, base_seed=ctx.base_seed,
                      tag=BENCHMARK_TAG, variant={s: ctx.sweep.variant_of(s) for s in ctx.systems})
        _log(ctx.progress, f"Appendix F, {name} protocol ({text}): {len(sweep.jobs())} jobs")
        store = os.path.join(ctx.out_dir, f"{stem}.sqlite")
        rep = run_sweep(sweep, store, executor=ctx.executor, workers=ctx.workers, progress=ctx.progress,
                        address=ctx.address)
        n_jobs, n_run = n_jobs + rep.n_jobs, n_run + rep.n_run
        frame = results_frame(store, noise_on="state")
        n_failed += int((frame["status"] != "ok").sum())
        _write_csv(frame, os.path.join(ctx.out_dir, f"{stem}.csv"))
    return n_jobs, n_run, n_failed


def protocol_frames(out_dir: str, *, required_for: str | None = None) -> dict:
    """``{protocol: results frame}`` from the Appendix F CSVs in ``out_dir`` (``appendix_f.csv``,
    ``appendix_f_default.csv``), what the report is built from. ``required_for``: the preset of a
    run whose Appendix F ran; the CSV of every protocol that run has must be there (a ConfigError
    names the missing one)."""
    from .._errors import ConfigError

    out = {}
    for name, (stem, _, _) in PROTOCOLS.items():
        path = os.path.join(out_dir, f"{stem}.csv")
        found = committed_csv(out_dir, f"{stem}.csv")
        if found is not None:
            out[name] = read_results_csv(found)
        elif required_for is not None and name in _protocols_for(required_for):
            raise ConfigError(f"cannot rebuild the report: {path} is missing (the Appendix F jobs of the {name} "
                              "protocol, which run.json says were run); restore the file, or run `charcurves benchmark` into this folder "
                              "to write it")
    return out


def _level_rows(frames: dict) -> list[list]:
    """RMSE at the paper's levels (40, 20, 0 dB) when the run has them, else at most six of the run's."""
    rows = []
    for proto, df in frames.items():
        tabs = {col: ensemble_table(df, col) for col in ("rmse_f1", "rmse_f2")}
        for (system, preset, method), (eta1, e1, _) in tabs["rmse_f1"].items():
            eta2, e2, _ = tabs["rmse_f2"].get((system, preset, method), (eta1, np.full_like(e1, np.nan), None))
            pv = paper.APPENDIX_F.get(system, {}).get(method)
            snrs = [_snr_of(eta) for eta in eta1]
            shown = [x for x in snrs if any(abs(x - q) < 1e-6 for q in paper.APPENDIX_F_SNR)] or snrs[:6]
            for i, snr in enumerate(snrs):
                if snr not in shown:
                    continue
                k = next((k for k, s in enumerate(paper.APPENDIX_F_SNR) if abs(s - snr) < 1e-6), None)
                i2 = np.flatnonzero(np.isclose(eta2, eta1[i]))
                rows.append([system, method, proto, preset, _snr_text(snr), e1[i],
                             pv[0][k] if pv and k is not None else None, e2[i2[0]] if i2.size else None,
                             pv[1][k] if pv and k is not None else None])
    return rows


def _a_rows(frames: dict) -> list[list]:
    """Per (system, method): slope-1 A of f1 and f2, the paper protocol's beside the default's, with
    the ratio paper protocol / default (above 1: the default is more accurate)."""
    # {protocol: {(system, method): fit}}; a folder with two presets' rows shows the first preset's fit
    fits: dict[str, dict] = {}
    for proto, df in frames.items():
        for (s, _, m), v in a_fit_table(df, "mean").items():
            fits.setdefault(proto, {}).setdefault((s, m), v)
    keys = list(dict.fromkeys(k for f in fits.values() for k in f))
    rows = []
    for system, method in keys:
        row: list = [system, method]
        for term in ("f1", "f2"):
            a = {proto: fits.get(proto, {}).get((system, method), {}).get("A", {}).get(term, float("nan"))
                 for proto in ("paper", "default")}
            pa = paper.APPENDIX_F_A.get(system, {}).get(method)
            ratio = a["paper"] / a["default"] if np.isfinite(a["paper"]) and np.isfinite(a["default"]) and a[
                "default"] > 0 else None
            row += [pa[0 if term == "f1" else 1] if pa else None, a["paper"], a["default"], ratio]
        rows.append(row)
    return rows


def appendix_f_section(rep, frames: dict, fig) -> None:
    """The report's Appendix F section: the paper protocol beside the default, tables and figures.
    ``frames``: as :func:`protocol_frames`; ``fig`` makes a (figure, axes) pair (the report's
    matplotlib helper)."""
    from ..report import plot_rmse_vs_noise

    rep.heading("Appendix F: noise on x (only x measured), the paper's protocol beside charcurves' default")
    frames = {p: df for p, df in (frames or {}).items() if len(df)}
    if not frames:
        rep.paragraph("Not run (the `appendix-f` section was skipped, or neural methods ran with the paper "
                      "preset without --full).")
        return
    rep.paragraph("Gaussian noise on x only (σ² = var(x) / 10^(SNR/10)); the forcing is clean, v and a are not "
                  "measured. Protocols: " + "; ".join(f"**{p}**: {PROTOCOLS[p][2]}" for p in frames) + ". Every "
                  "RMSE is the mean over the realisations of a level of the per-run RMSE on the curve's grid "
                  "(the scripts' statistic).")
    rep.table(["system", "method", "protocol", "preset", "SNR dB", "RMSE f1", "paper", "RMSE f2", "paper"],
              _level_rows(frames),
              caption=f"Ensemble RMSE (mean of per-run values). Paper values (SG + equation error) at 40/20/0 dB: "
                      f"{paper.SOURCES['appendix_f']}.")
    rep.table(["system", "method", "paper A f1", "A f1 (paper protocol)", "A f1 (default)", "ratio f1",
               "paper A f2", "A f2 (paper protocol)", "A f2 (default)", "ratio f2"],
              _a_rows(frames),
              caption="Slope-1 A of RMSE = A η (mean ensemble per level) over every level run (SR at the scripts' "
                      "η range). Ratio = A (paper protocol) / A (default): above 1, the default is more accurate. "
                      "Where the error stops falling with the noise (the paper protocol's Savitzky-Golay bias on "
                      "f2, about 0.04 on Duffing) the rows of the table above show the plateau. 'paper A': fits "
                      f"of the authors' Appendix F files ({paper.SOURCES['appendix_f_a']}).")
    for system in ("duffing", "stick-slip"):
        for proto, df in frames.items():
            sub = df[df["system"] == system]
            for preset in sorted(set(sub["preset"])):
                part = sub[sub["preset"] == preset]
                f, axes = fig(1, 2, figsize=(10.0, 3.6), squeeze=False)
                for j, col in enumerate(("rmse_f1", "rmse_f2")):
                    tab = ensemble_table(part, col)
                    plot_rmse_vs_noise({m: (v[0], v[1]) for (s, p, m), v in tab.items()}, ax=axes[0][j],
                                       ylabel=col.replace("rmse_", "RMSE[") + "]",
                                       title=f"{system}, {proto} protocol ({preset} preset)")
                f.tight_layout()
                rep.figure(f, f"appendix-f-{system}-{proto}-{preset}",
                           caption=f"Appendix F, {system}, {proto} protocol: ensemble RMSE vs η with noise on x "
                                   "(the paper's Figs. F2 and F4 show the paper protocol).")
    for proto, df in frames.items():
        failed = int((df["status"] != "ok").sum())
        if failed:
            rep.paragraph(f"{failed} Appendix F jobs of the {proto} protocol failed; their errors are in "
                          f"{PROTOCOLS[proto][0]}.csv.")
