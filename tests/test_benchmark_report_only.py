"""`charcurves benchmark --report-only`: the report rebuilt from the small committed files alone
(results.csv, run.json, extras.json, appendix_f.csv), byte for byte, and a one-line error naming
the file that is missing."""

from __future__ import annotations

import json
import shutil

import pandas as pd
import pytest

from charcurves.cli import main
from charcurves.experiments import build_report

COMMITTED = ("results.csv", "run.json", "extras.json", "appendix_f.csv", "appendix_f_default.csv")


@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench") / "b"
    rc = main(["benchmark", "--systems", "duffing", "--methods", "parametric", "--snr", "20", "--realizations", "1",
               "--forward-cases", "1", "--skip", "lyapunov,miw,sensitivity", "--workers", "1", "--quiet",
               "--out", str(out)])
    assert rc == 0
    return out


def _report_bytes(folder):
    files = {"report.md": (folder / "report.md").read_bytes(), "report.html": (folder / "report.html").read_bytes()}
    files.update({f"figures/{p.name}": p.read_bytes() for p in sorted((folder / "figures").glob("*.png"))})
    return files


def test_the_report_rebuilds_byte_for_byte_from_the_committed_files_alone(bench, tmp_path, capsys):
    before = _report_bytes(bench)
    assert {"figures/forward-duffing.png", "figures/phase-space.png", "figures/rmse-duffing-default.png"} <= set(before)
    run = json.loads((bench / "run.json").read_text(encoding="utf-8"))
    assert run["sections"] == ["appendix-f"] and run["variants"] == {"duffing": "paper"}
    assert run["sizes"]["forward_cases"] == 1 and set(run["timing"]) == {"main sweep", "appendix-f"}
    # a copy with only the committed files: no results.sqlite, no models/, no report
    copy = tmp_path / "committed"
    copy.mkdir()
    for name in COMMITTED:
        shutil.copy(bench / name, copy / name)
    assert main(["benchmark", "--out", str(copy), "--report-only"]) == 0
    assert "rebuilt" in capsys.readouterr().out
    assert _report_bytes(copy) == before
    # and in place, after deleting the report and its figures
    for p in [bench / "report.md", bench / "report.html", *(bench / "figures").glob("*.png")]:
        p.unlink()
    md, page = build_report(bench)
    assert md.endswith("report.md") and page.endswith("report.html")
    assert _report_bytes(bench) == before
    text = before["report.md"].decode("utf-8")
    assert "could not be built" not in text
    assert "--report-only` rebuilds it from these files alone" in text
    # the run's sections: Appendix F is in the report, both protocols, from their CSVs
    assert "| duffing | parametric | paper | default | 20 |" in text
    assert "| duffing | parametric | default | default | 20 |" in text


def test_a_gzipped_results_csv_rebuilds_the_same_report(bench, tmp_path):
    """A large results.csv is committed as results.csv.gz (gzip -n); --report-only reads it and
    builds the same report.md, and the result names the file it read."""
    import gzip

    copy = tmp_path / "gz"
    copy.mkdir()
    for name in COMMITTED:
        if name == "results.csv":
            (copy / "results.csv.gz").write_bytes(gzip.compress((bench / name).read_bytes(), mtime=0))
        else:
            shutil.copy(bench / name, copy / name)
    from charcurves.experiments import run_benchmark

    res = run_benchmark(copy, report_only=True)
    assert res.results_csv == str(copy / "results.csv.gz") and res.n_jobs == 1
    assert (copy / "report.md").read_bytes() == (bench / "report.md").read_bytes()
    assert not (copy / "results.csv").exists()


@pytest.mark.parametrize("name, content, says", [
    ("results.csv.gz", "truncated", "is not a readable results CSV (EOFError: Compressed file ended"),
    ("results.csv", b"step,loss\n1,0.5\n", "lacks the column(s) system, method, snr_db, realization, rmse_f1, "
                                           "rmse_f2, status of a benchmark results CSV"),
    ("results.csv", b"", "is not a readable results CSV (EmptyDataError: No columns to parse from file)")])
def test_a_damaged_results_csv_exits_2_naming_it_and_keeps_the_report(bench, tmp_path, capsys, name, content, says):
    """Before, a CSV of another table rebuilt an empty report over the good one with exit 0, and a
    truncated results.csv.gz ended in a traceback."""
    import gzip

    copy = tmp_path / "damaged"
    copy.mkdir()
    for other in COMMITTED[1:]:
        shutil.copy(bench / other, copy / other)
    if content == "truncated":
        content = gzip.compress((bench / "results.csv").read_bytes(), mtime=0)[:-40]
    (copy / name).write_bytes(content)
    (copy / "report.md").write_text("the earlier report\n", encoding="utf-8")
    assert main(["benchmark", "--out", str(copy), "--report-only"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"charcurves: error: cannot rebuild the report: {copy / name} {says}")
    assert (copy / "report.md").read_text(encoding="utf-8") == "the earlier report\n"


@pytest.mark.parametrize("missing", ["results.csv", "run.json", "extras.json", "appendix_f.csv",
                                     "appendix_f_default.csv"])
def test_a_missing_file_exits_2_with_one_line_naming_it(bench, tmp_path, capsys, missing):
    copy = tmp_path / "partial"
    copy.mkdir()
    for name in COMMITTED:
        if name != missing:
            shutil.copy(bench / name, copy / name)
    assert main(["benchmark", "--out", str(copy), "--report-only"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("charcurves: error: cannot rebuild the report: ")
    assert f"{copy / missing} is missing (" in err
    assert not (copy / "report.md").exists()


def test_report_only_refuses_grid_options_and_a_missing_folder(tmp_path, capsys):
    assert main(["benchmark", "--out", str(tmp_path), "--report-only", "--snr", "20"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--report-only runs nothing, so --snr has no effect; drop --snr" in err
    assert main(["benchmark", "--out", str(tmp_path / "nope"), "--report-only"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is not a folder; give the --out of a benchmark run" in err


def test_results_csv_of_an_older_release_still_reads(bench, tmp_path):
    """The committed duffing-full/results.csv predates the mixed_terms column: it reads as NaN."""
    from charcurves.experiments._report_inputs import read_results_csv

    old = pd.read_csv(bench / "results.csv").drop(columns=["mixed_terms"])
    old.to_csv(tmp_path / "results.csv", index=False)
    df = read_results_csv(tmp_path / "results.csv")
    assert df["mixed_terms"].isna().all() and len(df) == 1 and df["status"].tolist() == ["ok"]


def _section_text(build):
    from charcurves.report._html import Report

    rep = Report("t")
    build(rep)
    return rep.to_markdown()


def test_appendix_c_says_when_every_setting_gives_the_same_curves():
    from charcurves.experiments import _report_sections as sections

    class Extras:  # the two fields the section reads
        def __init__(self, rows):
            self.data = {"sensitivity:stick-slip:default": {"value": rows}}

    same = [{"setting": s, "value": v, "loss": 0.0198503157, "rmse_f1": 0.0128688033 * (1 + 1e-9 * k),
             "rmse_f2": 0.00118815143, "seconds": 1.0, "is_default": k == 0, "effective_parameters": 8.0}
            for k, (s, v) in enumerate([("activation", "softplus"), ("width", 5), ("adam_lr", 0.1)])]
    text = _section_text(lambda rep: sections._sensitivity(rep, Extras(same)))
    assert "stick-slip: every setting gives the same curves" in text
    assert "switched the networks off on this record (effective parameters 8)" in text
    differ = [dict(r, rmse_f1=r["rmse_f1"] * (1 + 0.1 * k)) for k, r in enumerate(same)]
    assert "every setting gives the same curves" not in _section_text(
        lambda rep: sections._sensitivity(rep, Extras(differ)))


def test_the_report_counts_sr_runs_with_mixed_terms_per_level():
    from charcurves.experiments import _report_sections as sections

    df = pd.DataFrame({"system": "duffing", "preset": "default", "method": "sr", "status": "ok",
                       "snr_db": [20.0, 20.0, 0.0, 0.0, -5.0], "realization": [0, 1, 0, 1, 0],
                       "mixed_terms": [0.0, 0.0, 1.0, 2.0, 0.0]})
    text = _section_text(lambda rep: sections._mixed(rep, df))
    assert "| duffing | default | sr | 2 | 5 | 0 dB: 2/2 |" in text
    old = df.assign(mixed_terms=float("nan"))  # a results.csv written before the column existed
    assert "does not record the mixed terms" in _section_text(lambda rep: sections._mixed(rep, old))


def test_run_json_keeps_every_earlier_invocation_and_the_report_lists_them(bench, tmp_path):
    """A second invocation into a folder (another preset, a resumed run) keeps the first's stage times
    under "previous"; the report shows them in a table of earlier invocations."""
    from charcurves.experiments._report_inputs import write_run_file

    folder = tmp_path / "b"
    shutil.copytree(bench, folder, ignore=shutil.ignore_patterns("*.sqlite*", "models"))
    first = json.loads((folder / "run.json").read_text())
    assert "previous" not in first
    second = dict(first, preset="paper", timing={"main sweep": 1234.0})
    write_run_file(str(folder), second)
    stored = json.loads((folder / "run.json").read_text())
    assert stored["preset"] == "paper" and stored["timing"] == {"main sweep": 1234.0}
    assert [p["timing"] for p in stored["previous"]] == [first["timing"]]
    assert stored["previous"][0]["preset"] == first["preset"] and "previous" not in stored["previous"][0]
    write_run_file(str(folder), dict(first, timing={"main sweep": 5.0}))
    assert [p["preset"] for p in json.loads((folder / "run.json").read_text())["previous"]] == \
        [first["preset"], "paper"]
    build_report(str(folder))
    text = (folder / "report.md").read_text()
    assert "Earlier invocations into this folder, oldest first" in text
    assert "main sweep 1234 s" in text
