"""Sections of the benchmark report: each puts our numbers beside the paper's and says so when
its data are absent from the run (a method not run, a side study skipped)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from . import _paper_values as paper
from ._results import METHOD_GROUPS
from ._tables import (
    BIAS_LIMITED,
    NN_X_ETA_MAX,
    a_fit_table,
    cost_table,
    ensemble_table,
    mixed_terms_table,
    performance_table,
    status_table,
    tsep_failure_snr,
)
from ._appendix_f import appendix_f_section
from ._tables import _snr_text
from ._report_figures import forward_panels, phase_space

__all__ = ["write_all"]


def _fig(*args, **kw):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt.subplots(*args, **kw)


def _presets(df) -> list[str]:
    order = {"default": 0, "paper": 1}
    return sorted(df["preset"].unique().tolist(), key=lambda p: (order.get(p, 2), p)) if len(df) else []


def _systems(df) -> list[str]:
    return [s for s in ("duffing", "stick-slip") if len(df) and s in set(df["system"])]


def _methods_in(df, system: str) -> list[str]:
    from ..fitting import METHODS

    present = set(df.loc[df["system"] == system, "method"])
    return [m for m in METHODS if m in present]


def _lyap(extras) -> dict | None:
    entry = extras.data.get("lyapunov")
    return entry.get("value") if entry else None


def write_all(rep, *, df, run: Mapping[str, Any], extras, appendix_f, timing: Mapping[str, float]) -> None:
    fits = {how: a_fit_table(df, how) for how in ("mean", "rms")} if len(df) else {"mean": {}, "rms": {}}
    sections = [
        ("What was run", lambda: _overview(rep, df, run, timing)),
        ("Run status", lambda: _status(rep, df)),
        ("Table 1", lambda: _table1(rep, extras)),
        ("Table 2", lambda: _table2(rep, df, fits)),
        ("SR mixed terms", lambda: _mixed(rep, df)),
        ("Table 3", lambda: _table3(rep, df, fits)),
        ("RMSE figures", lambda: _rmse_figures(rep, df, fits["mean"])),
        ("Separation time", lambda: _tsep(rep, df, extras)),
        ("Forward integrations", lambda: forward_panels(rep, df, extras)),
        ("Phase space", lambda: phase_space(rep, df, run, extras)),
        ("Performance", lambda: _performance(rep, df, fits["mean"])),
        ("Appendix F", lambda: _appendix_f(rep, appendix_f)),
        ("Appendix C", lambda: _sensitivity(rep, extras)),
        ("Appendix G", lambda: _cost(rep, df)),
    ]
    if run.get("noise_on") == "state":  # `benchmark --noise-on state`: Appendix F alone
        sections = [sec for sec in sections if sec[0] in ("What was run", "Appendix F")]
    for name, build in sections:
        try:
            build()
        except Exception as exc:  # noqa: BLE001 - one broken section must not cost the whole report
            import matplotlib.pyplot as plt

            plt.close("all")
            rep.paragraph(f"The section '{name}' could not be built ({type(exc).__name__}: {exc}); the data are "
                          "in results.csv and the stores. Please report this.")


# ---------------------------------------------------------------------- overview
def _overview(rep, df, run, timing) -> None:
    rep.heading("What was run")
    if not len(df):
        if run.get("noise_on") == "state":
            rep.paragraph("This folder holds the Appendix F study alone (`benchmark --noise-on state`): noise on x, "
                          "no main study (noise on the forcing).")
            if timing:
                rep.table(["stage", "wall time (s)"], [[k, float(v)] for k, v in timing.items()],
                          caption="Wall time of this invocation's stages (a resumed run skips finished jobs).")
        else:
            rep.paragraph("The results store holds no benchmark rows yet: every section below is empty.")
        return
    grid = []
    for system in _systems(df):
        for preset in _presets(df):
            g = df[(df["system"] == system) & (df["preset"] == preset)]
            if not len(g):
                continue
            levels = sorted(set(g["snr_db"]), reverse=True)
            shown = ", ".join(_snr_text(s) for s in levels[:8]) + (", ..." if len(levels) > 8 else "")
            variants = ", ".join(sorted(set(g["variant"].astype(str))))
            grid.append(f"{system} (parameters: `{variants}` variant), preset `{preset}`: {g['method'].nunique()} "
                        f"methods x {len(levels)} SNR levels ({shown} dB) x {g['realization'].nunique()} noise "
                        f"realisations = {len(g)} jobs")
    rep.bullets(grid)
    if run.get("sizes"):
        s, ran = run["sizes"], set(run.get("sections", ()))
        kind = "the paper's grid (`--full`)" if run.get("full") else "the quick grid (the default)"
        text = [f"The last invocation used {kind}: {s['forward_cases']} validation cases per model, drawn afresh "
                "for each SNR level and shared by the methods (the paper: 10), "
                f"per-case simulation budget {s['case_time_budget']:g} s (a case over it counts as failed)."]
        if "miw" in ran:
            text.append(f"MIW ensembles of {s['miw_seeds']} seeds and {s['miw_realizations']} realisations (the "
                        "paper: 100 and 10).")
        if "lyapunov" in ran:
            text.append(f"The Lyapunov exponent over {s['lyapunov_time']:g} time units.")
        if "post_sr" in s:
            text.append(f"Symbolic regression uses Operon with one population of 300: SR and SR-CC "
                        f"{s.get('sr_generations') or 40} generations on at most 400 points of the record (library "
                        f"default 40; the paper: PySR, 10 x 100, 200 iterations), post-SR {s['post_sr']['generations']} "
                        f"generations on {s['post_sr']['max_points']} of a curve's 1000 samples (library default 20 on "
                        "100; the paper: PySR, 20 x 100 iterations).")
        else:  # run.json of a release before post-SR had its own settings
            text.append(f"Symbolic regression (SR, SR-CC, post-SR) uses Operon with one population of 300 and "
                        f"{s.get('sr_generations') or 40} generations (library default 40; the paper: PySR, 10 x 100, "
                        "200 iterations).")
        if "appendix-f" in ran:
            text.append(f"Appendix F uses {min(s['realizations'], s.get('appendix_f_realizations', s['realizations']))}"
                        " realisation(s) per level.")
        n_levels = df["snr_db"].nunique()
        if n_levels < 61:
            text.append(f"With {n_levels} SNR levels the A fits rest on few points: read them as estimates, not as "
                        "the paper's 61-level fits.")
        rep.paragraph(" ".join(text))
    if timing:
        rep.table(["stage", "wall time (s)"], [[k, float(v)] for k, v in timing.items()],
                  caption="Wall time of the last invocation's stages (a resumed run skips finished jobs).")
    if run.get("previous"):
        rows = []
        for i, p in enumerate(run["previous"]):
            sz = p.get("sizes") or {}
            size = f"{len(sz.get('snr_db', ())) or '?'} levels x {sz.get('realizations', '?')}"
            stage_times = ", ".join(f"{k} {float(v):.0f} s" for k, v in (p.get("timing") or {}).items())
            rows.append([i + 1, p.get("preset", "?"), ", ".join(p.get("systems", ())), len(p.get("methods", ())),
                         size, stage_times])
        rep.table(["invocation", "preset", "systems", "methods", "grid", "stage wall times"], rows,
                  caption="Earlier invocations into this folder, oldest first (their rows are in results.csv too).")
    rep.paragraph("Ensembles over noise realisations use the authors' scripts' mean of per-run RMSEs (which "
                  "reproduces the paper's Tables 2 and 3); the paper's Eq. 19 (root mean square) is given beside "
                  "it in Table 2. A is the slope-1 log-log fit RMSE = A η over the levels run. The report is built "
                  "from `results.csv` (one row per job), `run.json` (what was run), `extras.json` (side studies "
                  "and the simulated figures' data) and `appendix_f.csv` (when Appendix F ran): "
                  "`charcurves benchmark --out DIR --report-only` rebuilds it from these files alone.")


def _status(rep, df) -> None:
    rep.heading("Run status and failures")
    if not len(df):
        rep.paragraph("No jobs in the store.")
        return
    st = status_table(df)
    rows = []
    for (system, preset, method), v in st.items():
        rows.append([system, preset, method, v["jobs"], v["failed_jobs"], v["cases"], v["failed_cases"]])
    rep.table(["system", "preset", "method", "jobs", "failed jobs", "validation cases", "failed cases"], rows,
              caption="Failed jobs keep their error in results.csv; failed validation cases (model left the "
                      "training box, diverged, or ran out of its time budget) count in t_sep as the time they "
                      "reached and are left out of RMSE[x].")
    errs = df[df["status"] != "ok"]
    if len(errs):
        rep.bullets([f"{r.system}/{r.method} @ {_snr_text(r.snr_db)} dB #{r.realization}: {str(r.error)[:200]}"
                     for r in errs.head(12).itertuples()])


# ---------------------------------------------------------------------- Table 1
def _table1(rep, extras) -> None:
    rep.heading("Table 1: mean interval width (MIW) of f2 residuals, Duffing 20 dB")
    rows = []
    order = {m: i for i, m in enumerate(("nn-cc", "nn-cc+sym", "nn-cc+sym+post-sr"))}
    for key in sorted((k for k in extras.data if k.startswith("miw:")),
                      key=lambda k: (k.split(":")[2], order.get(k.split(":")[1], 9))):
        _, method, preset = key.split(":", 2)
        v = extras.data[key]["value"]
        for kind, label in (("seeds", "(b)/(e) one dataset"), ("realizations", "(c)/(f) realisations")):
            p = paper.TABLE1_MIW.get((kind, method), (None, None))
            rows.append([label, method, preset, v[kind]["n"], v[kind]["miw_range"], p[0], v[kind]["miw_99"],
                         p[1] if isinstance(p[1], str) or p[1] is None else float(p[1])])
    if not rows:
        rep.paragraph("Not run: Table 1 needs Duffing and at least one of nn-cc, nn-cc+sym, nn-cc+sym+post-sr "
                      "(and the `miw` section not skipped; with the paper preset it runs only with --full).")
        return
    rep.table(["ensemble", "method", "preset", "runs", "MIW_range", "paper", "MIW_99", "paper"], rows,
              caption=f"Residuals f̂2(x) − f2(x) at the training points, binned 0.03 wide. One dataset: training "
                      f"seeds on one noisy record (paper: 100 runs); realisations: one run per noise "
                      f"realisation (paper: 10). Paper: {paper.SOURCES['table1']}.")


# ---------------------------------------------------------------------- Tables 2 and 3
def _a_rows(df, fits, system: str, terms: tuple[str, ...]):
    rows = []
    for method in _methods_in(df, system):  # presets of one method side by side
        for preset in _presets(df):
            f = fits["mean"].get((system, preset, method))
            if f is None:
                continue
            r: list[Any] = [method, preset]
            for t in terms:
                r.append(f["A"].get(t, float("nan")))
            pa: tuple[float | None, ...]
            if system == "duffing":
                pa = paper.TABLE2_DUFFING_A.get(method, (None, None))
                rows.append(r + [pa[0], pa[1], fits["rms"][(system, preset, method)]["A"]["f1"],
                                 fits["rms"][(system, preset, method)]["A"]["f2"],
                                 _bias_text(f["bias"]["f1"]), _bias_text(f["bias"]["f2"]), f["levels"]])
            else:
                pa = paper.TABLE3_STICK_SLIP_A.get(method, (None, None, None))
                rows.append(r + [pa[0], pa[1], pa[2], _bias_text(f["bias"]["f1"]), _bias_text(f["bias"]["f2"]),
                                 _paper_bias(method), f["levels"]])
    return rows


def _bias_text(bA) -> str:
    b, a = bA
    if not (np.isfinite(b) and np.isfinite(a)):
        return "–"
    return f"{b:.2g}, {a:.3g}"


def _paper_bias(method: str) -> str:
    b = paper.TABLE3_BIAS.get(method)
    return f"{b[0]:.3g} / {b[1]:.3g}" if b else "–"


def _table2(rep, df, fits) -> None:
    rep.heading("Table 2: Duffing, fitted A of RMSE[f1] and RMSE[f2]")
    if "duffing" not in _systems(df):
        rep.paragraph("Not run: Duffing is not among this run's systems.")
        return
    rows = _a_rows(df, fits, "duffing", ("f1", "f2"))
    rep.table(["method", "preset", "A f1", "A f2", "paper A f1", "paper A f2", "A f1 (rms)", "A f2 (rms)",
               "bias fit f1 (b, A)", "bias fit f2 (b, A)", "levels"], rows,
              caption="Slope-1 fits RMSE = A η of the ensemble (mean of per-run RMSEs; '(rms)': the paper's "
                      "Eq. 19); bias fits sqrt(b² + (A η)²). SR is fitted at η ≤ 8 as the paper. "
                      f"Paper: {paper.SOURCES['table2']}.")


def _mixed(rep, df) -> None:
    rep.heading("SR runs whose expression mixes x and x'", level=3)
    rep.paragraph("SR searches one expression in x and x'. Its expanded terms in x alone form f2, those in x' "
                  "alone f1, a pure number the free constant; a term in both (e.g. x·x') has no place in the "
                  "separable template. Such terms are dropped and the coefficients of the remaining separable "
                  "terms (with the constant) are refitted jointly by least squares on the equation; the curve "
                  "RMSEs score these curves (fitting/_symbolic_fit.py). SR-CC never mixes (one search per curve).")
    tab = mixed_terms_table(df) if len(df) else {}
    if not tab:
        rep.paragraph("This results.csv does not record the mixed terms (no SR rows, or written before the "
                      "`mixed_terms` column existed).")
        return
    rows = []
    for (system, preset, method), v in tab.items():
        per = ", ".join(f"{_snr_text(s)} dB: {k}/{n}" for s, (k, n) in v["levels"].items() if k)
        rows.append([system, preset, method, v["mixed"], v["runs"], per or "none"])
    rep.table(["system", "preset", "method", "runs with mixed terms", "runs", "per level (mixed/runs)"], rows,
              caption="From the `mixed_terms` column of results.csv (the number of mixed terms SR returned).")


def _table3(rep, df, fits) -> None:
    rep.heading("Table 3: stick-slip, fitted A of RMSE[f1], RMSE[f2] and RMSE[x]")
    if "stick-slip" not in _systems(df):
        rep.paragraph("Not run: stick-slip is not among this run's systems.")
        return
    rows = _a_rows(df, fits, "stick-slip", ("f1", "f2", "x"))
    rep.table(["method", "preset", "A f1", "A f2", "A x", "paper A f1", "paper A f2", "paper A x",
               "bias fit f1 (b, A)", "bias fit f2 (b, A)", "paper bias f1 / f2", "levels"], rows,
              caption=f"As Table 2; RMSE[x] over 40 s of forward simulation from the validation cases (no value "
                      f"when every case failed). As the scripts: SR fitted at η ≤ 5, the NN variants' RMSE[x] at "
                      f"η ≤ {NN_X_ETA_MAX:g}; the paper's A for {', '.join(BIAS_LIMITED)} comes from the bias "
                      f"fit. Paper: {paper.SOURCES['table3']}.")


# ---------------------------------------------------------------------- Figs. 5 / 11
def _rmse_figures(rep, df, fits) -> None:
    from ..report import plot_rmse_vs_noise

    rep.heading("RMSE of the curves vs noise (Figs. 5 and 11)")
    if not len(df):
        rep.paragraph("No data.")
        return
    for system in _systems(df):
        for preset in _presets(df):
            sub = df[(df["system"] == system) & (df["preset"] == preset)]
            if not len(sub):
                continue
            terms = [("f1", "rmse_f1"), ("f2", "rmse_f2")] + ([("x", "rmse_x")] if system == "stick-slip" else [])
            groups = [(g, [m for m in ms if m in set(sub["method"])]) for g, ms in METHOD_GROUPS.items()]
            groups = [(g, ms) for g, ms in groups if ms]
            fig, axes = _fig(len(terms), len(groups), figsize=(max(4.2 * len(groups), 7.0), 3.4 * len(terms)),
                             squeeze=False)
            for j, (gname, ms) in enumerate(groups):
                for i, (t, col) in enumerate(terms):
                    tab = ensemble_table(sub[sub["method"].isin(ms)], col)
                    series = {m: (tab[(system, preset, m)][0], tab[(system, preset, m)][1])
                              for m in ms if (system, preset, m) in tab}
                    afits = {m: fits[(system, preset, m)]["A"][t] for m in series if (system, preset, m) in fits}
                    bfits = {m: fits[(system, preset, m)]["bias"][t] for m in series
                             if system == "stick-slip" and m in BIAS_LIMITED and (system, preset, m) in fits}
                    plot_rmse_vs_noise(series, ax=axes[i][j], fits=afits, bias_fits=bfits,
                                       ylabel=f"RMSE[{t}]", title=f"{gname}: RMSE[{t}]")
            fig.suptitle(f"{system}, preset {preset}: ensemble RMSE vs η (dashed: A η; dotted: bias fit)",
                         fontsize=10)
            fig.tight_layout()
            rep.figure(fig, f"rmse-{system}-{preset}",
                       caption=f"{system} ({preset}): ensemble RMSE per SNR level against η = 10^(−SNR/20), with "
                               "the slope-1 fits (paper Fig. 5 for Duffing, Fig. 11 and Fig. 12 for stick-slip).")


# ---------------------------------------------------------------------- Fig. 8
def _tsep(rep, df, extras) -> None:
    from ..report import plot_tsep_vs_noise

    rep.heading("Separation time vs noise with the Lyapunov time (Fig. 8)")
    ly = _lyap(extras)
    if ly:
        rep.paragraph(f"Largest Lyapunov exponent of the true Duffing (Benettin, variational equations): "
                      f"λ_max = {ly['lambda_max']:.4f}, T_L = {ly['T_L']:.2f} ({ly['seconds']:.1f} s to compute); "
                      f"the paper: λ_max ≈ {paper.LYAPUNOV['duffing']['lambda_max']}, T_L ≈ "
                      f"{paper.LYAPUNOV['duffing']['T_L']} (which belongs to the scripts' α = −1.05, β = 1.02; "
                      "see docs/deviations.md).")
    else:
        rep.paragraph("The Lyapunov exponent was not computed in this run (section skipped or no Duffing); "
                      f"the paper's T_L = {paper.LYAPUNOV['duffing']['T_L']} is used below.")
    t_l = ly["T_L"] if ly else paper.LYAPUNOV["duffing"]["T_L"]
    sub = df[df["system"] == "duffing"] if len(df) else df
    if not len(sub) or not sub["t_sep"].notna().any():
        rep.paragraph("No separation times: Duffing was not run with validation cases (`forward` skipped or 0 cases).")
        return
    presets = [p for p in _presets(sub) if sub.loc[sub["preset"] == p, "t_sep"].notna().any()]
    fig, axes = _fig(len(presets), len(METHOD_GROUPS), figsize=(4.3 * len(METHOD_GROUPS), 3.4 * len(presets)),
                     squeeze=False)
    for i, preset in enumerate(presets):
        s = sub[sub["preset"] == preset]
        tab = ensemble_table(s, "t_sep", "mean")
        for j, (gname, ms) in enumerate(METHOD_GROUPS.items()):
            series = {m: (tab[("duffing", preset, m)][0], tab[("duffing", preset, m)][1])
                      for m in ms if ("duffing", preset, m) in tab}
            plot_tsep_vs_noise(series, ax=axes[i][j], lyapunov_time=t_l, title=f"{gname} ({preset})")
    fig.tight_layout()
    rep.figure(fig, "tsep-duffing", caption="Mean separation time ⟨t_sep⟩ (ε = 0.2, censored at 80 s) against η; "
                                            "red dashed: the Lyapunov time.")
    fail = tsep_failure_snr(sub, t_l)
    rows = []
    for (system, preset, method), snr in fail.items():
        p = paper.TSEP_FAILURE_SNR.get(method)
        ours = "never below T_L" if snr == -math.inf else ("–" if not np.isfinite(snr) else f"≲ {snr:g} dB")
        rows.append([method, preset, ours, f"≲ {p:g} dB" if p is not None else "–"])
    rep.table(["method", "preset", "⟨t_sep⟩ < T_L from", "paper"], rows,
              caption="Highest SNR level whose ⟨t_sep⟩ is below T_L (the paper's 'fails at SNR ≲ X'; with a "
                      f"coarse grid this is only as fine as its levels). Paper: {paper.SOURCES['tsep']}.")


# ---------------------------------------------------------------------- Figs. 9 / 13
def _performance(rep, df, fits) -> None:
    from ..report import plot_performance

    rep.heading("Performance relative to Parametric (Figs. 9 and 13)")
    perf = performance_table(fits) if fits else {}
    if not perf or all(not np.isfinite(v) for v in perf.values()):
        rep.paragraph("Not available: performance % needs Parametric and another method on the same system.")
        return
    rows = []
    for system in _systems(df):
        series = {f"charcurves ({preset})": {m: v for (s, p, m), v in perf.items() if s == system and p == preset}
                  for preset in _presets(df)}
        series = {k: v for k, v in series.items() if v}
        if not series:
            continue
        methods = list(dict.fromkeys(m for v in series.values() for m in v))
        fig, ax = _fig(figsize=(max(6.0, 0.8 * len(methods) + 2), 3.8))
        plot_performance(series, {m: v for m, v in paper.PERFORMANCE_PERCENT.get(system, {}).items() if m in methods},
                         ax=ax, title=system)
        fig.tight_layout()
        rep.figure(fig, f"performance-{system}",
                   caption=f"{system}: mean over the terms of A_Parametric / A_method x 100 % (Duffing: f1, f2; "
                           "stick-slip: f1, f2, x). Hatched: the paper.")
        for m in methods:
            for preset in _presets(df):
                if (system, preset, m) in perf:
                    rows.append([system, preset, m, perf[(system, preset, m)],
                                 paper.PERFORMANCE_PERCENT.get(system, {}).get(m)])
    rep.table(["system", "preset", "method", "performance %", "paper %"], rows,
              caption=f"Paper: {paper.SOURCES['performance']}. The paper gives SINDy no A (its models have cross "
                      "terms); ours is computed when its curves are separable.")


# ---------------------------------------------------------------------- App. F
def _appendix_f(rep, frames) -> None:
    appendix_f_section(rep, frames, _fig)


# ---------------------------------------------------------------------- App. C
def _sensitivity(rep, extras) -> None:
    rep.heading("Appendix C: sensitivity of NN-CC to its hyperparameters (20 dB, one dataset)")
    keys = sorted(k for k in extras.data if k.startswith("sensitivity:"))
    if not keys:
        rep.paragraph("Not run: needs nn-cc among the methods and the `sensitivity` section (with the paper "
                      "preset it runs only with --full, its fits take minutes each).")
        return
    for key in keys:
        _, system, preset = key.split(":", 2)
        rows = []
        for r in extras.data[key]["value"]:
            pv = paper.SENSITIVITY.get((r["setting"], r["value"]), {}).get(system, (None, None, None))
            label = f"{r['value']}" + (" (preset's own)" if r.get("is_default") else "")
            if "error" in r:
                rows.append([r["setting"], label, "failed", None, None, None, None, None, r["seconds"]])
                continue
            rows.append([r["setting"], label, r["loss"], pv[0], r["rmse_f1"], pv[1], r["rmse_f2"], pv[2],
                         r["seconds"]])
        rep.table(["setting", "value", "loss", "paper L", "RMSE f1", "paper", "RMSE f2", "paper", "seconds"], rows,
                  caption=f"{system}, NN-CC with the `{preset}` preset, one setting changed at a time (width: "
                          "neurons per hidden layer). The paper's rows are its protocol (3x100 ReLU, Adam 1e-4, "
                          f"20 000 epochs) with that setting changed, so only the trends compare. "
                          f"Paper: {paper.SOURCES['sensitivity']}.")
        same = _same_curves(extras.data[key]["value"])
        if same:
            rep.paragraph(f"{system}: every setting gives the same curves (RMSE f1 and f2 agree to {same:.0e} "
                          "relative). This is a result, not a table error: the preset's Bayesian (evidence) "
                          "regularisation switched the networks off on this record" + _eff_text(extras.data[key]["value"])
                          + ", so the curves are the linear term and the learned jump, which no network setting "
                          "changes.")


def _same_curves(rows) -> float:
    """The largest relative spread of RMSE f1/f2 over the settings when below 1e-6 (else 0)."""
    ok = [r for r in rows if "error" not in r and r.get("rmse_f1") is not None and r.get("rmse_f2") is not None]
    if len(ok) < 2:
        return 0.0
    spread = 0.0
    for col in ("rmse_f1", "rmse_f2"):
        v = np.array([float(r[col]) for r in ok])
        spread = max(spread, float(np.ptp(v) / max(np.max(np.abs(v)), 1e-300)))
    return max(spread, 1e-16) if spread < 1e-6 else 0.0


def _eff_text(rows) -> str:
    eff = sorted({round(float(r["effective_parameters"]), 1) for r in rows if r.get("effective_parameters") is not None})
    return f" (effective parameters {', '.join(f'{e:g}' for e in eff)})" if eff else ""


# ---------------------------------------------------------------------- App. G
def _cost(rep, df) -> None:
    rep.heading("Appendix G: computational cost per training run")
    if not len(df):
        rep.paragraph("No timings.")
        return
    c = cost_table(df)
    rows = []
    for (system, preset, method), v in c.items():
        rows.append([system, preset, method, v["jobs"], v["fit_median"], v["job_median"], v["total"],
                     paper.COST_SECONDS.get(method)])
    rep.table(["system", "preset", "method", "jobs", "median fit s", "median job s (with validation)",
               "total s", "paper s"], rows,
              caption="Measured in this run, one thread per job on this machine (neural jobs of one SNR level are "
                      "trained as one batch; their fit time is the batch's share; a method that extends another's "
                      "fit on the same record, +post-SR or sr-cc+refit, counts the shared training or searches in "
                      "its own time, as if run alone). Paper: "
                      f"{paper.SOURCES['cost']}; its SR time is PySR's.")
