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
    for page in ("benchmark.md", "deviations.md"):
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
    committed = sorted(p.relative_to(src) for p in src.rglob("*") if p.suffix in (".md", ".html", ".png"))
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
    # refitted in a batch with another partner, the 40 dB realisation-0 fits are the first invocation's
    row = paper.set_index(key).loc[("nn-cc", 40.0, 0)]
    assert f"against {row['rmse_f1']:.6f} / {row['rmse_f2']:.6f} and {row['rmse_x']:.3f}" in text


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
    section = _section(text, "### Duffing on the scripts' system", "### Stick-slip on the scripts' system")
    for method in counts.index:
        a = _a(df, method, eta_max=8.0 if method == "sr" else None)  # SR fitted at eta <= 8, as the paper
        assert f"| {a[0]:.4f} / {a[1]:.4f} |" in section, method
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
    section = _section(text, "### Stick-slip on the scripts' system", "## The two-system full study")
    for method, paper in table3.items():
        a = _a(df, method, system="stick-slip")
        assert f"| {a[0]:.4f} / {a[1]:.4f} |" in section, method
        if method == "parametric":
            assert all(abs(ours / theirs - 1) < 0.10 for ours, theirs in zip(a, paper)), a
        else:
            assert all(theirs / ours > 1.4 for ours, theirs in zip(a, paper)), (method, a, paper)
    # where the docs say we do not beat the paper: SR-CC (A over the 61 levels, as the report) against 0.190 / 0.041
    a = _a(df, "sr-cc", system="stick-slip")
    assert f"| {a[0]:.3f} / {a[1]:.4f} | 0.190 / 0.041 |" in section and a[0] > 0.190 and a[1] > 0.041
    # forward-validated: ten validation cases per model (the paper's protocol), RMSE[x] beside Table 3's
    ok = df[df["status"] == "ok"]
    assert (ok["n_cases"] == 10).all() and (ok["rmse_x"].isna() == (ok["n_failed_cases"] == 10)).all()
    table3_x = {"nn-cc": 0.336, "nn-cc+post-sr": 0.225, "nn-cc+sym": 0.164, "nn-cc+sym+post-sr": 0.133, "sr": 0.402,
                "sr-cc": 0.248, "parametric": 0.065}
    for method, paper in table3_x.items():
        # the scripts' masks: the neural methods' RMSE[x] at eta <= 0.3, SR's every term at eta <= 5
        ax = _a_x(df, method, eta_max=0.3 if method.startswith("nn-cc") else 5.0 if method == "sr" else None)
        assert f"| {ax:.3g} / {paper:.3g} ({paper / ax:.2f}) |" in section, (method, ax)
        if method == "parametric":
            assert round(ax / paper - 1, 2) == 0.15  # the docs: 15 % worse than Table 3 on RMSE[x]
            assert "A x 0.0749 against Table 3's 0.065 (15 % worse)" in section
        else:
            assert paper / ax > 1.5, (method, ax, paper)  # ours ahead of Table 3, SR-CC included


APPENDIX_F = ROOT / "benchmarks" / "results" / "appendix-f"


def _g3(x: float) -> str:
    """A value as the docs' tables write it (three significant digits)."""
    return f"{x:.3g}"


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
    text = _section(_page("benchmark.md"), "## Appendix F, noise on x", "## The scripts' systems")
    assert ("with all 10 of its realisations" if n_real == 10 else f"with {n_real} of its 10 realisations") in text
    assert f"{2 * 13 * 61 * n_real * 2:,} jobs".replace(",", " ") in text
    # failed jobs: only the default's refusals of an odd prior its smoothed x cannot support, as many as the docs say
    assert (frames["paper"]["status"] == "ok").all()
    failed = frames["default"][frames["default"]["status"] != "ok"]
    assert all(str(e).startswith("IdentifiabilityError: an odd prior on f2") for e in failed["error"])
    assert {0: "every one `ok`.", 4: "every one `ok` but four:"}[len(failed)] in text
    rows = {(s, m): r for s, m, *r in _a_rows(frames)}
    quoted = re.findall(r"\| (Duffing|stick-slip) \| ([a-z+-]+) \| ([^|]+) \| ([^|]+) \| ([^|]+) \| ([^|]+) \| ([^|]+) \| "
                        r"([^|]+) \|", text)
    assert len(quoted) == 14
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


def test_the_post_sr_forms_figures_are_those_of_the_committed_run():
    """docs/training-defaults.md quotes benchmarks/results/postsr_forms.json (bench_postsr_forms.py)."""
    import json

    doc = json.loads((ROOT / "benchmarks" / "results" / "postsr_forms.json").read_text())
    text = _section(_page("training-defaults.md"), "## Post-SR operators", "## Harmonic terms")
    for half in ("tune", "report"):
        s = doc["summary"][half]
        row = (f"| {s['recovered_before']} of {s['n_in_set']} | {s['recovered_after']} of {s['n_in_set']} | "
               f"{s['mean_cpu_seconds_before']:.2f} | {s['mean_cpu_seconds_after']:.2f} |")
        assert row in text, row
    assert doc["summary"]["polynomial_truths_kept_polynomial_after"] == [7, 7] and "All 7 polynomial truths" in text
    assert len(doc["curves"]) == 23 and sum(r["in_set"] for r in doc["curves"]) == 18
