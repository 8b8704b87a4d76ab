"""Claims of the docs checked against the code and the committed results (issue 23, item 5)."""

from __future__ import annotations

import pathlib
import re

import numpy as np
import pandas as pd
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
DOCS = sorted((ROOT / "docs").glob("*.md")) + [ROOT / "README.md"]
FULL = ROOT / "benchmarks" / "results" / "duffing-full" / "results.csv"


def _page(name: str) -> str:
    """A docs page with every run of whitespace made one space (a quoted figure may be wrapped)."""
    return re.sub(r"\s+", " ", (ROOT / "docs" / name).read_text(encoding="utf-8"))


def _note(folder: str) -> str:
    """A results folder's provenance note (benchmarks/results/<folder>/PROVENANCE.md), whitespace as :func:`_page`."""
    return re.sub(r"\s+", " ", (ROOT / "benchmarks" / "results" / folder / "PROVENANCE.md").read_text(encoding="utf-8"))


def _g3(x: float) -> str:
    """A value as the docs' tables write it: three significant digits, trailing zeros kept (0.0510, 17.0)."""
    return f"{x:#.3g}".rstrip(".")


def _section(text: str, start: str, end: str) -> str:
    """The text from the heading ``start`` up to the heading ``end``."""
    return text[text.index(start):text.index(end)]


@pytest.mark.parametrize("page", DOCS, ids=lambda p: p.name)
def test_no_page_announces_code_as_planned(page):
    text = page.read_text(encoding="utf-8")
    for phrase in ("planned: not in this release", "not in this release yet", "charcurves will use"):
        assert phrase not in text.lower(), f"{page.name}: {phrase!r}"


@pytest.mark.skipif(not FULL.exists(), reason="the committed full-grid results are not in this checkout")
def test_the_committed_sr_cc_is_the_refit_equal_to_parametric_in_525_of_610_jobs():
    df = pd.read_csv(FULL)
    key = ["snr_db", "realization"]
    par = df[df["method"] == "parametric"].set_index(key)[["rmse_f1", "rmse_f2"]]
    srcc = df[df["method"] == "sr-cc"].set_index(key)[["rmse_f1", "rmse_f2"]].reindex(par.index)
    equal = int((np.abs(srcc - par) < 1e-6).all(axis=1).sum())
    assert (len(par), equal) == (610, 525)
    for page in ("benchmark.md", "deviations-symbolic.md"):
        text = _page(page)
        assert "525 of" in text and "610" in text, page


#: committed benchmark folders that carry run.json: their report must rebuild from the repo alone
COMMITTED_RUNS = ["scripts-stick-slip", "paper-cpu", pytest.param("scripts-duffing", marks=pytest.mark.slow),
                  pytest.param("appendix-f", marks=pytest.mark.slow), pytest.param("full", marks=pytest.mark.slow)]
STUDY = ROOT / "benchmarks" / "results" / "full" / "results.csv.gz"  # 3.5 MB as CSV: committed gzipped


def _a_x(df, method, eta_max=None):
    """Slope-1 A of the mean RMSE[x] per level over the levels with a value (every case of a level can fail)."""
    g = df[df["method"] == method].groupby("eta")["rmse_x"].mean()
    eta, ens = g.index.to_numpy(), g.to_numpy()
    keep = (eta > 0) & (eta <= (eta_max if eta_max is not None else np.inf)) & np.isfinite(ens) & (ens > 0)
    return float(np.exp(np.mean(np.log(ens[keep]) - np.log(eta[keep]))))


def _a(df, method, system="duffing", eta_max=None):
    """Slope-1 A of the mean ensemble per level (the scripts' statistic), per curve."""
    g = df[(df["system"] == system) & (df["method"] == method)].groupby("eta")[["rmse_f1", "rmse_f2"]].mean()
    eta = g.index.to_numpy()
    keep = (eta > 0) & (eta <= (eta_max if eta_max is not None else np.inf))
    return tuple(float(np.exp(np.mean(np.log(g[c].to_numpy()[keep]) - np.log(eta[keep])))) for c in g.columns)


@pytest.mark.skipif(not STUDY.exists(), reason="the committed full study is not in this checkout")
def test_the_committed_full_study_has_every_job_of_both_systems():
    df = pd.read_csv(STUDY)
    default = df[df["preset"] == "default"]
    counts = default.groupby(["system", "method"]).size()
    assert len(counts) == 26 and set(counts) == {610}  # 2 systems x 13 methods x 61 levels x 10 realisations
    failed = default[default["status"] != "ok"]
    # the only failures: SINDy's sparse regression dropping the forcing term of a very noisy stick-slip record,
    # refused with a one-line error rather than kept as a model without input
    assert set(failed["method"]) <= {"sindy"} and set(failed["system"]) <= {"stick-slip"}
    assert failed["error"].str.contains("the learned gain is zero or not finite").all()
    assert (failed["snr_db"] < 0).all() and len(failed) < 0.02 * 610
    assert (default.loc[default["status"] == "ok", "n_cases"] == 10).all()  # ten validation cases per model, as the paper


@pytest.mark.skipif(not STUDY.exists(), reason="the committed full study is not in this checkout")
def test_sr_cc_differs_from_parametric_as_the_papers_does_and_the_refit_does_not():
    """The paper's SR-CC keeps its searches' coefficients and lands above Parametric (A 1.19 / 2.89 against
    1.09 / 1.58); so does ours, while sr-cc+refit is Parametric wherever SR found the true basis. The docs
    give the counts and the A values; they must be these."""
    df = pd.read_csv(STUDY)
    duff = df[(df["system"] == "duffing") & (df["preset"] == "default")]
    key = ["snr_db", "realization"]
    par = duff[duff["method"] == "parametric"].set_index(key)[["rmse_f1", "rmse_f2"]]
    equal = {}
    for m in ("sr-cc", "sr-cc+refit"):
        other = duff[duff["method"] == m].set_index(key)[["rmse_f1", "rmse_f2"]].reindex(par.index)
        equal[m] = int((np.abs(other - par) < 1e-6).all(axis=1).sum())
    assert equal["sr-cc"] < 0.05 * len(par) and equal["sr-cc+refit"] > 0.8 * len(par)
    a_sr, a_par, a_refit = _a(duff, "sr-cc"), _a(duff, "parametric"), _a(duff, "sr-cc+refit")
    assert a_sr[0] > 1.05 * a_par[0] and a_sr[1] > 1.03 * a_par[1]
    assert abs(a_refit[0] / a_par[0] - 1) < 0.25
    text = _page("benchmark.md")
    assert f"{equal['sr-cc']} of 610" in text and f"{equal['sr-cc+refit']} of 610" in text
    for a in (a_sr, a_par):
        assert f"{a[0] * 100:.2f} / {a[1] * 100:.2f}" in text


@pytest.mark.parametrize("folder", COMMITTED_RUNS)
def test_a_committed_report_rebuilds_byte_for_byte_from_the_repo_alone(folder, tmp_path):
    """`charcurves benchmark --report-only` on a copy of the folder's small committed files (no
    results.sqlite, no models) gives the committed report.md byte for byte, report.html byte for byte
    outside its embedded images, and the same figures at the same pixel size (the images' bytes
    depend on matplotlib's version, which the project does not pin)."""
    import shutil

    from charcurves.cli import main

    src = ROOT / "benchmarks" / "results" / folder
    copy = tmp_path / folder
    copy.mkdir()
    inputs = [p for p in src.iterdir() if p.name.endswith((".csv", ".csv.gz", ".json"))]
    assert {p.name for p in inputs} >= {"run.json"}
    for p in inputs:
        shutil.copy(p, copy / p.name)
    assert main(["benchmark", "--out", str(copy), "--report-only", "--quiet"]) == 0
    built = sorted(p.relative_to(copy) for p in copy.rglob("*") if p.suffix in (".md", ".html", ".png"))
    committed = sorted(p.relative_to(src) for p in src.rglob("*")
                       if p.suffix in (".md", ".html", ".png") and p.name != "PROVENANCE.md")  # the run's history, not the report's
    assert built == committed and len(built) > 3
    for rel in committed:
        ours, theirs = (copy / rel).read_bytes(), (src / rel).read_bytes()
        if rel.suffix == ".md":
            assert ours == theirs, rel
        elif rel.suffix == ".html":
            strip = re.compile(rb"data:image/png;base64,[A-Za-z0-9+/=]+")
            assert strip.sub(b"", ours) == strip.sub(b"", theirs), rel
        else:  # PNG: width and height from the IHDR chunk
            assert ours[:8] == b"\x89PNG\r\n\x1a\n" and ours[16:24] == theirs[16:24], rel


PAPER_CPU = ROOT / "benchmarks" / "results" / "paper-cpu" / "results.csv"


@pytest.mark.skipif(not (PAPER_CPU.exists() and STUDY.exists()), reason="the committed runs are not in this checkout")
def test_the_paper_preset_on_the_cpu_is_what_the_docs_say():
    """The `paper` preset's CPU run (13 levels x 3 realisations of NN-CC and NN-CC+sym) against the default
    on the same records of the full study: every job validated (the OverflowError that emptied 12 jobs of
    its first invocation is gone), the default more accurate on every record, the A values the docs
    quote, and the 40 dB realisation-0 fits that the docs say reproduce the first invocation's."""
    paper = pd.read_csv(PAPER_CPU)
    assert len(paper) == 78 and set(paper["preset"]) == {"paper"} and (paper["status"] == "ok").all()
    assert set(paper.groupby(["method", "snr_db"]).size()) == {3} and paper["snr_db"].nunique() == 13
    assert (paper["n_cases"] == 10).all() and (paper["n_failed_cases"] < 10).all()
    full = pd.read_csv(STUDY)
    key = ["method", "snr_db", "realization"]
    default = full[(full["system"] == "duffing") & (full["preset"] == "default")].set_index(key)
    default = default.reindex(paper.set_index(key).index)
    assert default["rmse_f1"].notna().all()
    worse = (paper.set_index(key)[["rmse_f1", "rmse_f2"]] > default[["rmse_f1", "rmse_f2"]]).all(axis=1)
    assert worse.all()  # the paper's protocol is less accurate than the default on each of the 78 records
    text = _page("benchmark.md")
    for method in ("nn-cc", "nn-cc+sym"):
        a_paper = _a(paper, method)
        a_default = _a(default.reset_index(), method)
        assert f"{a_paper[0]:.4f} / {a_paper[1]:.4f}" in text, method
        assert f"{a_default[0]:.4f} / {a_default[1]:.4f}" in text, method
    # refitted in a batch with another partner, the 40 dB realisation-0 fits are the first invocation's (the run's
    # provenance note tells it)
    row = paper.set_index(key).loc[("nn-cc", 40.0, 0)]
    assert f"against {row['rmse_f1']:.6f} / {row['rmse_f2']:.6f} and {row['rmse_x']:.3f}" in _note("paper-cpu")


SCRIPTS_DUFFING = ROOT / "benchmarks" / "results" / "scripts-duffing" / "results.csv.gz"


@pytest.mark.skipif(not SCRIPTS_DUFFING.exists(), reason="the committed scripts-variant run is not in this checkout")
def test_table_2_on_the_scripts_system_is_what_the_docs_say():
    """The paper's Table 2 was made with the scripts' Duffing (alpha = -1.05, beta = 1.02): every method on it,
    the estimators without a training protocol within 15 % of Table 2 (the issue's acceptance), the neural
    methods ahead of the paper on both curves, and the A values docs/benchmark.md quotes."""
    table2 = {  # the paper's Table 2, A of RMSE[f1], RMSE[f2] (printed there x 1e-2)
        "parametric": (0.0109, 0.0158), "poly-cc": (0.0523, 0.0475), "sindy-cc": (0.051, 0.0436),
        "sindy-cc+sym": (0.0303, 0.0261), "nn-cc": (0.112, 0.104), "nn-cc+post-sr": (0.0474, 0.0444),
        "nn-cc+sym": (0.0473, 0.055), "nn-cc+sym+post-sr": (0.0179, 0.0200)}
    df = pd.read_csv(SCRIPTS_DUFFING)
    counts = df.groupby("method").size()
    assert len(counts) == 13 and set(counts) == {610} and (df["status"] == "ok").all()
    assert df["n_cases"].between(4, 10).all() and (df["n_cases"] == 10).mean() > 0.85 and df["t_sep"].notna().all()
    assert set(df["variant"]) == {"scripts"} and set(df["system"]) == {"duffing"}
    text = _page("benchmark.md")
    section = _section(text, "## Duffing on the scripts' system", "## Stick-slip on the scripts' system")
    for method in counts.index:
        a = _a(df, method, eta_max=8.0 if method == "sr" else None)  # SR fitted at eta <= 8, as the paper
        assert f"| {_g3(a[0])} / {_g3(a[1])} |" in section, method
        paper = table2.get(method)
        if method in ("parametric", "poly-cc", "sindy-cc", "sindy-cc+sym"):
            assert all(abs(ours / theirs - 1) < 0.15 for ours, theirs in zip(a, paper)), (method, a, paper)
        if method.startswith("nn-cc"):
            assert all(theirs / ours > 1.25 for ours, theirs in zip(a, paper)), (method, a, paper)


SCRIPTS_STICK_SLIP = ROOT / "benchmarks" / "results" / "scripts-stick-slip" / "results.csv.gz"


@pytest.mark.skipif(not SCRIPTS_STICK_SLIP.exists(), reason="the committed scripts-variant run is not in this checkout")
def test_table_3_on_the_scripts_system_is_what_the_docs_say():
    """Table 3 was made with the scripts' stick-slip (Omega = 0.3, tanh(500 v)): every method on it, the neural
    methods ahead of Table 3 on both curves, Parametric within 10 % of it, SR-CC behind it, and the A values
    docs/benchmark.md quotes."""
    table3 = {"parametric": (0.061, 0.028), "nn-cc": (0.549, 0.514), "nn-cc+post-sr": (0.389, 0.368),
              "nn-cc+sym": (0.182, 0.168), "nn-cc+sym+post-sr": (0.111, 0.106)}  # the paper's Table 3
    df = pd.read_csv(SCRIPTS_STICK_SLIP)
    counts = df.groupby("method").size()
    assert len(counts) == 13 and set(counts) == {610} and set(df["variant"]) == {"scripts"}
    failed = df[df["status"] != "ok"]
    assert set(failed["method"]) == {"sindy"} and len(failed) == 4 and (failed["snr_db"] < -15).all()
    assert failed["error"].str.contains("the learned gain is zero or not finite").all()
    text = _page("benchmark.md")
    section = _section(text, "## Stick-slip on the scripts' system", "## Appendix F, noise on x")
    for method, paper in table3.items():
        a = _a(df, method, system="stick-slip")
        assert f"| {_g3(a[0])} / {_g3(a[1])} |" in section, method
        if method == "parametric":
            assert all(abs(ours / theirs - 1) < 0.10 for ours, theirs in zip(a, paper)), a
        else:
            assert all(theirs / ours > 1.4 for ours, theirs in zip(a, paper)), (method, a, paper)
    # where the docs say we do not beat the paper: SR-CC (A over the 61 levels, as the report) against 0.190 / 0.041
    a = _a(df, "sr-cc", system="stick-slip")
    assert f"| {_g3(a[0])} / {_g3(a[1])} | 0.190 / 0.0410 |" in section and a[0] > 0.190 and a[1] > 0.041
    # forward-validated: ten validation cases per model (the paper's protocol), RMSE[x] beside Table 3's
    ok = df[df["status"] == "ok"]
    assert (ok["n_cases"] == 10).all() and (ok["rmse_x"].isna() == (ok["n_failed_cases"] == 10)).all()
    table3_x = {"nn-cc": 0.336, "nn-cc+post-sr": 0.225, "nn-cc+sym": 0.164, "nn-cc+sym+post-sr": 0.133, "sr": 0.402,
                "sr-cc": 0.248, "parametric": 0.065}
    for method, paper in table3_x.items():
        # the scripts' masks: the neural methods' RMSE[x] at eta <= 0.3, SR's every term at eta <= 5
        ax = _a_x(df, method, eta_max=0.3 if method.startswith("nn-cc") else 5.0 if method == "sr" else None)
        assert f"| {_g3(ax)} / {_g3(paper)} ({_g3(paper / ax)}) |" in section, (method, ax)
        if method == "parametric":
            assert round(ax / paper - 1, 2) == 0.15  # the docs: 15 % worse than Table 3 on RMSE[x]
            assert "A x 0.0749 against Table 3's 0.065 (15 % worse)" in section
        else:
            assert paper / ax > 1.5, (method, ax, paper)  # ours ahead of Table 3, SR-CC included


APPENDIX_F = ROOT / "benchmarks" / "results" / "appendix-f"


@pytest.mark.skipif(not (APPENDIX_F / "appendix_f_default.csv.gz").exists(),
                    reason="the committed Appendix F run is not in this checkout")
def test_appendix_f_is_what_the_docs_say():
    """The Appendix F run (noise on x; the paper's protocol beside the default on the same records): every
    job of both protocols on 61 levels x the realisations the docs say, the table of A values in
    docs/benchmark.md row by row (computed here as the report computes it), the default ahead on every
    curve of every method, and the per-record counts the docs quote."""
    from charcurves.experiments._appendix_f import _a_rows, protocol_frames

    frames = protocol_frames(str(APPENDIX_F))
    n_real = int(frames["paper"]["realization"].nunique())
    for df in frames.values():
        assert len(df) == 2 * 13 * 61 * n_real
        assert set(df.groupby(["system", "method", "snr_db"]).size()) == {n_real} and df["snr_db"].nunique() == 61
        assert sorted(df["realization"].unique()) == list(range(n_real))
    text = _section(_page("benchmark.md"), "## Appendix F, noise on x", "## The paper's protocol on this CPU")
    assert ("with all 10 of its realisations" if n_real == 10 else f"with {n_real} of its 10 realisations") in text
    assert f"{2 * 13 * 61 * n_real * 2:,} jobs".replace(",", " ") in text
    # failed jobs: only the default's refusals of an odd prior its smoothed x cannot support, as many as the docs say
    assert (frames["paper"]["status"] == "ok").all()
    failed = frames["default"][frames["default"]["status"] != "ok"]
    assert all(str(e).startswith("IdentifiabilityError: an odd prior on f2") for e in failed["error"])
    assert {0: "every one `ok`.", 4: "every one `ok` but four:"}[len(failed)] in text
    # run without --full: the symbolic searches had the quick grid's budget, and the page says so
    import json

    run = json.loads((APPENDIX_F / "run.json").read_text(encoding="utf-8"))
    assert run["full"] is False and run["sizes"]["sr_generations"] == 20
    assert "SR, SR-CC and SR-CC+refit searched with the quick grid's budget, 20 Operon generations instead of 40" in text
    rows = {(s, m): r for s, m, *r in _a_rows(frames)}
    quoted = re.findall(r"\| (Duffing|stick-slip) \| ([a-z+-]+) \| ([^|]+) \| ([^|]+) \| ([^|]+) \| ([^|]+) \| ([^|]+) \| "
                        r"([^|]+) \|", text)
    assert len(quoted) == 26  # every method of both systems
    for system, method, *cells in quoted:
        _, ap1, ad1, r1, _, ap2, ad2, r2 = rows[("duffing" if system == "Duffing" else system, method)]
        assert [c.strip() for c in cells] == [_g3(v) for v in (ap1, ad1, r1, ap2, ad2, r2)], (system, method)
    ratios = {s: [v for (sy, _), r in rows.items() if sy == s for v in (r[3], r[7])] for s in ("duffing", "stick-slip")}
    assert all(v > 1 for v in ratios["duffing"] + ratios["stick-slip"])
    for system, label in (("duffing", "Duffing"), ("stick-slip", "stick-slip")):
        lo, hi = min(ratios[system]), max(ratios[system])
        assert f"{_g3(lo)}–{_g3(hi)}× on {label}" in text, (system, lo, hi)
    key = ["system", "method", "snr_db", "realization"]
    both = frames["paper"].merge(frames["default"], on=key, suffixes=("_p", "_d"))
    both = both[(both["status_p"] == "ok") & (both["status_d"] == "ok")]
    worst_p = both[["rmse_f1_p", "rmse_f2_p"]].max(axis=1)
    worst_d = both[["rmse_f1_d", "rmse_f2_d"]].max(axis=1)
    for system in ("duffing", "stick-slip"):
        sel = (both["system"] == system).to_numpy()
        better = int((worst_d[sel] < worst_p[sel]).sum())
        median = float(np.median(worst_p[sel] / worst_d[sel]))
        assert f"{better} of {int(sel.sum())}" in text and f"median ratio {median:.3g}×" in text, (system, better, median)


def test_deviations_states_the_default_preset_as_the_code_has_it():
    """Item 10 of the deviations (deviations-training.md) names the default preset's network and budgets: read them
    from the preset."""
    from charcurves.fitting import PRESETS

    p = PRESETS["default"]
    text = _section(_page("deviations-training.md"), "## 10. Default training", "## 11.")
    hidden = ",".join(str(h) for h in p.hidden)
    assert f"a ({hidden},) {p.activation} MLP" in text
    assert f"{p.adam_steps} Adam steps (lr 1e{round(np.log10(p.adam_lr))})" in text
    assert f"up to {p.lm_max_iter} Levenberg–Marquardt iterations" in text
    assert f"{p.n_starts} random starts per model" in text
    assert f"within {p.combine_tol:.0%} of the best loss" in text.replace("2 %", "2%")


def test_no_page_names_an_api_that_does_not_exist():
    """Call spellings of the docs that name a keyword of a public function must match its signature."""
    import importlib
    import inspect

    import charcurves as cc

    spaces = [cc] + [importlib.import_module(f"charcurves.{p}") for p in (
        "data", "io", "systems", "templates", "curves", "fitting", "symbolic", "simulate", "metrics", "selection",
        "experiments", "report")]
    for page in DOCS:
        text = page.read_text(encoding="utf-8")
        for name, kw in re.findall(r"`(\w+)\(\.\.\., (\w+)=", text):
            func = next((getattr(m, name) for m in spaces if hasattr(m, name)), None)
            assert func is not None, f"{page.name}: {name} is not a public name of charcurves"
            params = inspect.signature(func).parameters
            takes_any = any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values())  # StateSpace(**curves)
            assert kw in params or takes_any, f"{page.name}: {name}() has no {kw}="


def test_the_typed_figures_of_the_benchmark_page_are_the_committed_ones():
    """The figures docs/benchmark.md states in its prose (its tables are rendered: test_docs_tables.py)."""
    import json

    from charcurves.experiments._tables import tsep_failure_snr

    text = _page("benchmark.md")
    full = pd.read_csv(STUDY)
    assert f"{len(full):,} jobs".replace(",", " ") == "15 860 jobs" and "15 860 jobs" in text
    failed = full[full["status"] != "ok"]
    assert len(failed) == 10 and set(failed["method"]) == {"sindy"} and set(failed["system"]) == {"stick-slip"}
    assert (failed["snr_db"] < 0).all() and "10 stick-slip SINDy jobs below 0 dB failed" in text
    # the stage times of run.json add up to the end-to-end wall time the page gives (the report took seconds)
    run = json.loads((STUDY.parent / "run.json").read_text(encoding="utf-8"))
    assert run["skip"] == ["sensitivity", "appendix-f"] and round(sum(run["timing"].values()) / 60) == 103
    assert "--full --skip sensitivity,appendix-f" in text and "1 h 43 min on 2 cores" in text
    duff = full[(full["system"] == "duffing") & (full["preset"] == "default")]
    ratio = [a / p for a, p in zip(_a(duff, "nn-cc+sym+post-sr"), _a(duff, "parametric"))]
    assert all(1 < r < 1.02 for r in ratio) and "NN-CC+sym+post-SR is within 2 % of Parametric on Duffing" in text
    # the t_sep thresholds where the defaults fail at a higher SNR than the paper (Fig. 8's "fails at SNR <~ X")
    t_l = json.loads((STUDY.parent / "extras.json").read_text(encoding="utf-8"))["lyapunov"]["value"]["T_L"]
    ours = tsep_failure_snr(full[full["system"] == "duffing"], t_l)
    from charcurves.experiments._paper_values import TSEP_FAILURE_SNR

    worse = {m: ours[("duffing", "default", m)] - p for m, p in TSEP_FAILURE_SNR.items() if ours[("duffing", "default", m)] > p}
    assert worse == {"nn-cc+sym+post-sr": 1.0, "poly-cc": 1.0, "sindy-cc": 2.0}, worse
    assert "t_sep thresholds of NN-CC+sym+post-SR, Poly-CC and SINDy-CC (1–2 dB higher)" in text
    # the scripts' Duffing: its Lyapunov time and the shared estimators within 7 % of Table 2
    t_l = json.loads((SCRIPTS_DUFFING.parent / "extras.json").read_text(encoding="utf-8"))["lyapunov"]["value"]["T_L"]
    assert f"T_L is {t_l:.2f} (the paper's 7.8)" in text
    df = pd.read_csv(SCRIPTS_DUFFING)
    table2 = {"parametric": (0.0109, 0.0158), "poly-cc": (0.0523, 0.0475), "sindy-cc": (0.051, 0.0436),
              "sindy-cc+sym": (0.0303, 0.0261)}
    gap = max(abs(a / p - 1) for m, paper in table2.items() for a, p in zip(_a(df, m), paper))
    assert 0.06 < gap < 0.07 and "The estimators without a training protocol are the paper's within 7 %" in text
    # the paper preset on the CPU within 22 % of Table 2
    paper = pd.read_csv(PAPER_CPU)
    t2 = {"nn-cc": (0.112, 0.104), "nn-cc+sym": (0.0473, 0.055)}
    gap = max(abs(a / p - 1) for m, ref in t2.items() for a, p in zip(_a(paper, m), ref))
    assert round(100 * gap) == 22 and "It lands within 22 % of Table 2" in text
    # Appendix F: the paper protocol's plateau of Duffing's RMSE[f2] near 0.05 at 40 dB
    af = pd.read_csv(APPENDIX_F / "appendix_f.csv.gz")
    at40 = af[(af["system"] == "duffing") & (af["snr_db"] == 40.0)]["rmse_f2"]
    assert round(float(at40.median()), 2) == 0.05 and "Duffing's RMSE[f2] near 0.05" in text


@pytest.mark.skipif(not STUDY.exists(), reason="the committed full study is not in this checkout")
def test_deviations_21_and_22_quote_the_committed_full_study():
    """Items 21 (SR-CC's own coefficients against the refit) and 22 (SR's mixed terms) of the deviations
    (docs/deviations-symbolic.md)."""
    df = pd.read_csv(STUDY)
    duff = df[(df["system"] == "duffing") & (df["preset"] == "default")]
    a_sr, a_refit = _a(duff, "sr-cc"), _a(duff, "sr-cc+refit")
    assert 0.01 < max(abs(r / s - 1) for s, r in zip(a_sr, a_refit)) < 0.02
    text = _page("deviations-symbolic.md")
    assert "A of `sr-cc` and `sr-cc+refit` differ by under 2 %" in text
    sr = df[(df["method"] == "sr") & (df["status"] == "ok")]
    mixed = {s: (int((g["mixed_terms"] > 0).sum()), len(g)) for s, g in sr.groupby("system")}
    assert mixed == {"duffing": (5, 610), "stick-slip": (2, 610)}
    assert "5 of Duffing's 610 SR runs and 2 of stick-slip's had a mixed term" in text


def test_the_post_sr_forms_figures_are_those_of_the_committed_run():
    """docs/post-sr.md quotes benchmarks/results/postsr_forms.json (bench_postsr_forms.py)."""
    import json

    doc = json.loads((ROOT / "benchmarks" / "results" / "postsr_forms.json").read_text())
    text = _page("post-sr.md")
    for half in ("tune", "report"):
        s = doc["summary"][half]
        row = (f"| {s['recovered_before']} of {s['n_in_set']} | {s['recovered_after']} of {s['n_in_set']} | "
               f"{s['mean_cpu_seconds_before']:.2f} | {s['mean_cpu_seconds_after']:.2f} |")
        assert row in text, row
    assert doc["summary"]["polynomial_truths_kept_polynomial_after"] == [7, 7] and "All 7 polynomial truths" in text
    assert len(doc["curves"]) == 23 and sum(r["in_set"] for r in doc["curves"]) == 18
