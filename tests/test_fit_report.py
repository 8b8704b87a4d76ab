"""The one-page report of a fit: ``charcurves fit --report`` and ``charcurves report`` (issue 24, item 3).

The page is checked as a user gets it: parsed (every image an inline PNG, no external asset, the
sections, the numbers of result.json and model.json) and, where chromium is installed, opened in a
real headless browser that must decode every image without fetching anything."""

import base64
import json
import os
import re
import shutil
import subprocess
from html.parser import HTMLParser

import numpy as np
import pytest

import charcurves as cc
from charcurves.cli import main

SECTIONS = ["Identified equation", "Curves", "Fit statistics",
            "Output error (free runs of the model against the measured x)", "Self-check", "Settings", "Warnings", "Versions"]


class Page(HTMLParser):
    """Tags, their attributes, h2 headings, table rows and the visible text of a page."""

    def __init__(self, text: str):
        super().__init__()
        self.tags, self.h2, self.rows, self.text = [], [], [], []
        self._in, self._row = None, None
        self.feed(text)

    def handle_starttag(self, tag, attrs):
        self.tags.append((tag, dict(attrs)))
        if tag in ("h2", "td", "th"):
            self._in = tag
            if tag == "h2":
                self.h2.append("")
            else:
                self._row.append("")
        elif tag == "tr":
            self._row = []

    def handle_endtag(self, tag):
        if tag == "tr" and self._row is not None:
            self.rows.append(self._row)
            self._row = None
        if tag in ("h2", "td", "th"):
            self._in = None

    def handle_data(self, data):
        self.text.append(data)
        if self._in == "h2":
            self.h2[-1] += data
        elif self._in in ("td", "th"):
            self._row[-1] += data

    def values(self, key: str) -> list[str]:
        return [r[1] for r in self.rows if r and r[0] == key]

    def row(self, key: str) -> str:
        (value,) = self.values(key)
        return value


def read_page(path) -> Page:
    return Page(open(path, encoding="utf-8").read())


def png_images(page: Page) -> list[bytes]:
    out = []
    for tag, attrs in page.tags:
        if tag == "img":
            src = attrs["src"]
            assert src.startswith("data:image/png;base64,"), f"an image is not inline: {src[:60]}"
            out.append(base64.b64decode(src.split(",", 1)[1], validate=True))
    return out


@pytest.fixture(scope="module")
def fitted(tmp_path_factory, duffing_20db):
    root = tmp_path_factory.mktemp("report")
    csv = root / "duffing.csv"
    duffing_20db.to_csv(str(csv))
    out = root / "fit"
    rc = main(["fit", str(csv), "--method", "parametric", "--basis", "f1=z; f2=z, z**3", "--out", str(out), "--report", "--truth", "duffing",
               "--quiet"])
    assert rc == 0
    return out, json.loads((out / "result.json").read_text())


def test_fit_report_is_one_self_contained_page_with_the_fit(fitted):
    out, result = fitted
    page = read_page(out / "report.html")
    assert page.h2 == SECTIONS
    # nothing outside the file: images inline, links only to the page's own sections, no scripts or styles sheets
    (png,) = png_images(page)
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 20_000
    assert not [t for t, _ in page.tags if t in ("script", "link", "iframe", "object")]
    assert all(a["href"].startswith("#") for t, a in page.tags if t == "a")
    text = "".join(page.text)
    # the equation with the stored coefficients to 4 significant digits (result.json keeps all of them)
    c1 = float(result["curves"]["f1"]["expression"].split("*")[0])
    assert f"f1(x') = {c1:.4g}*x'" in text and f"x'' + {c1:.4g}*x' + (" in text
    assert result["curves"]["f1"]["expression"].split("*")[0] not in text
    assert f"{result['offset']:.4g}" in text and "record ../duffing.csv" in text
    for name in ("f1", "f2"):  # the errors against the truth are the fit's
        assert page.row(name) == f"{result['curve_rmse'][name]:.4g}"
    assert page.row("data loss (mean squared equation residual)") == f"{result['loss']:.4g}"
    assert page.row("differentiator") == "given (the record's derivative columns)"
    assert page.values("objective") == ["equation-error", "equation-error (asked: auto)"]  # statistics, settings
    assert page.row("training preset") == "default" and page.row("symmetry") == "f1 none, f2 none"
    assert page.row("charcurves") == cc.__version__ and page.row("numpy") == np.__version__
    assert "None about the record." in text
    assert "no output-error refinement" in text.lower()
    summary = (out / "summary.txt").read_text()
    assert "report.html" in summary
    # the printed closed forms have 4 significant digits (issue 24, item 5); result.json keeps all of them
    lo, hi = result["curves"]["f1"]["domain"]
    assert f"  f1(x') on [{lo:.4g}, {hi:.4g}] = {c1:.4g}*x'; RMSE vs truth" in summary
    assert result["curves"]["f1"]["expression"].split("*")[0] not in summary
    assert len(result["curves"]["f1"]["expression"].split("*")[0]) > 10


def test_report_command_rebuilds_the_same_page_from_the_saved_fit(fitted, tmp_path, capsys):
    out, _ = fitted
    target = tmp_path / "again.html"
    assert main(["report", str(out), "--truth", "duffing", "--out", str(target)]) == 0
    assert target.read_bytes() == (out / "report.html").read_bytes()  # reloaded model, same page
    assert capsys.readouterr().out.strip() == f"wrote {target}"
    copy = tmp_path / "fit"  # the model/ folder works too; the default --out is report.html beside it
    shutil.copytree(out, copy)
    os.remove(copy / "report.html")
    assert main(["report", str(copy / "model"), "--truth", "duffing"]) == 0
    assert (copy / "report.html").read_bytes() == target.read_bytes()
    assert main(["report", str(copy)]) == 0  # without --truth: no truth drawn, the fit's own errors kept
    page = read_page(copy / "report.html")
    text = "".join(page.text)
    assert "true curves dashed" not in text and "as the fit computed them" in text
    assert page.row("f1") == f"{json.loads((out / 'result.json').read_text())['curve_rmse']['f1']:.4g}"


@pytest.mark.parametrize("case", ["missing", "file", "empty", "out-is-dir", "not-json"])
def test_report_bad_input_is_one_line_and_exit_2(case, fitted, tmp_path, capsys):
    out, _ = fitted
    args = {"missing": [str(tmp_path / "nope")], "file": [str(out / "result.json")], "empty": [str(tmp_path)],
            "out-is-dir": [str(out), "--out", str(tmp_path)]}.get(case)
    if case == "not-json":
        shutil.copytree(out / "model", tmp_path / "m")
        (tmp_path / "m" / "model.json").write_text("{broken")
        args = [str(tmp_path / "m")]
    assert main(["report", *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("charcurves: error: ")
    fix = {"missing": "does not exist; give the folder", "file": "is not a directory", "empty": "not a fit folder",
           "out-is-dir": "is a directory; give the HTML file", "not-json": "re-save or re-fit"}[case]
    assert fix in err[0]
    assert not list(tmp_path.rglob("report.html"))


def test_report_shows_the_output_error_free_runs_of_a_record_without_derivatives(tmp_path, duffing):
    system, _ = duffing
    traj = cc.corrupt(system.simulate(t_end=24.0, n_points=600), 30.0, on="state", seed=0)
    lines = ["t,x,F"] + [f"{float(t)!r},{float(x)!r},{float(f)!r}" for t, x, f in zip(traj.t, traj.x, traj.F)]
    (tmp_path / "x.csv").write_text("\n".join(lines) + "\n")
    assert main(["fit", str(tmp_path / "x.csv"), "--method", "parametric", "--basis", "f1=z; f2=z, z**3", "--out", str(tmp_path / "o"),
                 "--report", "--quiet"]) == 0
    oe = cc.load_model(tmp_path / "o" / "model").info["output_error"]
    assert oe["free_run_rmse_after"] < oe["free_run_rmse_before"]
    page = read_page(tmp_path / "o" / "report.html")
    assert page.row("RMSE of one free run of the whole record (before → after)") == \
        f"{oe['free_run_rmse_before']:.4g} → {oe['free_run_rmse_after']:.4g}"
    assert page.row("RMSE of the segments' free runs (before → after)") == \
        f"{oe['segmented_rmse_before']:.4g} → {oe['segmented_rmse_after']:.4g}"
    assert page.row("status") == oe["status"]
    assert page.values("objective") == ["output-error", "output-error (asked: auto)"]
    assert page.row("differentiator").startswith("Spectral")


def test_report_draws_the_bands_stored_in_result_json(tmp_path, duffing_20db):
    from charcurves.report import load_fit

    duffing_20db.to_csv(str(tmp_path / "d.csv"))
    assert main(["fit", str(tmp_path / "d.csv"), "--method", "parametric", "--basis", "f1=z; f2=z, z**3", "--bands", "3", "--out",
                 str(tmp_path / "o"), "--report", "--quiet"]) == 0
    model, result = load_fit(tmp_path / "o")
    assert set(model.bands) == {"f1", "f2"}
    assert np.array_equal(model.bands["f2"]["hi"], result["bands"]["f2"]["hi"])
    text = "".join(read_page(tmp_path / "o" / "report.html").text)
    assert "uncertainty bands filled" in text


@pytest.mark.skipif(shutil.which("chromium") is None and shutil.which("chromium-browser") is None,
                    reason="no chromium for the headless-browser check")
def test_report_renders_in_a_headless_browser_without_fetching_anything(fitted, tmp_path):
    out, _ = fitted
    probe = ("<script>window.addEventListener('load',function(){var im=[].slice.call(document.images);"
             "document.body.setAttribute('data-decoded',im.filter(function(i){return i.complete&&i.naturalWidth>0})"
             ".length+'/'+im.length);document.body.setAttribute('data-fetched',"
             "performance.getEntriesByType('resource').filter(function(r){return r.name.indexOf('data:')!==0})"
             ".length);document.body.setAttribute('data-width',im.length?im[0].naturalWidth:0);});</script>")
    page = (out / "report.html").read_text(encoding="utf-8").replace("</body>", probe + "</body>")
    (tmp_path / "probe.html").write_text(page, encoding="utf-8")
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    dom = subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu", "--dump-dom",
                          (tmp_path / "probe.html").as_uri()], capture_output=True, text=True, timeout=120).stdout
    body = re.search(r"<body([^>]*)>", dom).group(1)
    assert 'data-decoded="1/1"' in body and 'data-fetched="0"' in body
    assert 'data-width="920"' in body  # 2 panels of 4.6 inches at 100 dpi, decoded by the browser
