"""The gallery (docs/gallery.md): every example script runs on a short record and its numbers hold.

Each script of examples/ runs once, in this process (its main() with the command line of a short
run: a 500-sample record; one thread and the Agg backend, as tests/conftest.py sets them), so that
the scripts do not pay a fresh interpreter's imports of torch, sympy and matplotlib each (~5 CPU s
a script). The bounds are about 2-3x the RMSE measured on these settings (noted beside each), so
that a wrong model (a missing term, a lost jump, no output-error refit) fails them.

examples/silverbox.py needs the real measurements and has its own test (test_examples_silverbox.py);
examples/custom_curve.py is run by test_composition.py. Both must still have a gallery entry.
"""

from __future__ import annotations

import contextlib
import importlib.util
import io
import os
import re
from pathlib import Path

import pytest

# the scripts' runs (the module fixture below, ~25 CPU s) are made once: every test of this module in one
# xdist worker (--dist loadgroup), not once in each worker that draws one of them
pytestmark = pytest.mark.xdist_group("gallery")

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
GALLERY = ROOT / "docs" / "gallery.md"
FIGURES = ROOT / "docs" / "gallery"

#: script -> (arguments for a short run, the PNG it writes)
RUNS = {
    "two_dof": (["--samples", "500"], "two_dof.png"),
    "measured_record": (["--samples", "500"], "measured_record.png"),
    "duffing": (["--samples", "500"], "duffing.png"),
    "user_equation": (["--samples", "500"], "user_equation.png"),
    "stick_slip": (["--samples", "500"], "stick_slip.png"),
}
#: scripts tested elsewhere (see the module docstring), with the figure their gallery entry shows
ELSEWHERE = {"silverbox": "silverbox_free_run.png", "custom_curve": None}


def _run(name: str, out: Path) -> str:
    """What examples/<name>.py prints when run as ``python <name>.py --out <out> <its short-run arguments>``."""
    import matplotlib.pyplot as plt

    args, _ = RUNS[name]
    spec = importlib.util.spec_from_file_location(f"gallery_{name}", EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    stdout = io.StringIO()
    try:
        with contextlib.redirect_stdout(stdout):
            spec.loader.exec_module(module)
            module.main(["--out", str(out), *args])
    finally:
        plt.close("all")
    return stdout.getvalue()


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """name -> (stdout, output folder)."""
    outs = {name: tmp_path_factory.mktemp(name) for name in RUNS}
    return {name: (_run(name, outs[name]), outs[name]) for name in RUNS}


def _rmse(text: str) -> dict[str, float]:
    """``RMSE f1 0.0012`` pairs in ``text`` -> {"f1": 0.0012, ...}."""
    return {k: float(v) for k, v in re.findall(r"RMSE (f\d) ([0-9.eE+-]+)", text)}


@pytest.mark.parametrize("name", sorted(RUNS))
def test_writes_its_figure(runs, name):
    stdout, out = runs[name]
    png = out / RUNS[name][1]
    assert png.is_file() and png.stat().st_size > 5_000, stdout
    assert f"wrote {png}" in stdout


def test_duffing(runs):
    stdout, _ = runs["duffing"]
    err = _rmse(stdout)
    # measured (500 samples, seed 0): f1 1.4e-3, f2 2.7e-3
    assert err["f1"] < 4e-3 and err["f2"] < 7e-3, stdout
    closed = re.search(r"closed forms: \{'f1': (.*), 'f2': (.*)\}", stdout)
    assert closed, stdout
    assert "z**3" in closed.group(2) and "z**3" not in closed.group(1)


def test_stick_slip_learns_the_jump(runs):
    stdout, _ = runs["stick_slip"]
    err = _rmse(stdout)
    # measured: f1 8.2e-3, f2 8.2e-3; jump 0.815 (true 0.801)
    assert err["f1"] < 0.02 and err["f2"] < 0.02, stdout
    height = float(re.search(r"height ([0-9.eE+-]+)", stdout).group(1))
    assert abs(height / 0.801 - 1) < 0.05, stdout


def test_user_equation(runs):
    stdout, _ = runs["user_equation"]
    err = _rmse(stdout)
    # measured: f1 8.5e-3, f2 2.2e-3
    assert "equation: x'' + f1(x)*x' + f2(x) = F" in stdout
    assert err["f1"] < 0.02 and err["f2"] < 6e-3, stdout


def test_two_dof(runs):
    stdout, _ = runs["two_dof"]
    err = _rmse(stdout)
    # measured: f1 3.9e-3, f2 4.8e-3, f3 2.8e-3, f4 5.2e-3
    assert set(err) == {"f1", "f2", "f3", "f4"}, stdout
    assert max(err.values()) < 0.012, stdout


def test_measured_record_output_error_beats_equation_error(runs):
    stdout, _ = runs["measured_record"]
    lines = {line.split(":")[0]: line for line in stdout.splitlines() if "RMSE" in line}
    ee, oe = _rmse(lines["equation-error"]), _rmse(lines["auto"])
    assert "ran output-error" in lines["auto"], stdout
    # measured (40 dB on x, 500 samples): equation error f1 1.4e-3, f2 5.4e-4;
    # default (then output error) f1 5.6e-5, f2 3.1e-4
    assert max(oe.values()) < 8e-4, stdout
    assert max(oe.values()) < max(ee.values()) / 2, stdout


# ------------------------------------------------------------------ the docs page


def _scripts() -> list[str]:
    return sorted(p.stem for p in EXAMPLES.glob("*.py"))


def test_every_script_is_run_here_or_elsewhere():
    assert set(_scripts()) == set(RUNS) | set(ELSEWHERE)


@pytest.mark.parametrize("name", sorted(RUNS))
def test_run_as_a_script_it_calls_the_main_tested_here(name):
    """The fixture calls main(argv); ``python examples/<name>.py ...`` must run that same main on its arguments."""
    source = (EXAMPLES / f"{name}.py").read_text()
    assert re.search(r'\nif __name__ == "__main__":\n    (sys\.exit\()?main\(\)\)?\n', source), name
    assert re.search(r"\ndef main\(argv=None\)", source) and "parse_args(argv)" in source, name


@pytest.mark.parametrize("name", _scripts())
def test_every_script_has_a_gallery_entry(name):
    """docs/gallery.md includes the script's source (the include-markdown plugin's include) and shows its committed figure."""
    page = GALLERY.read_text()
    assert f'<!--% include "../examples/{name}.py" %-->' in page
    figure = RUNS[name][1] if name in RUNS else ELSEWHERE[name]
    if figure is not None:
        assert f"](gallery/{figure})" in page
        png = FIGURES / figure
        assert png.is_file(), f"run examples/{name}.py --out docs/gallery to make {png}"
        assert png.stat().st_size < 150_000


def test_gallery_is_in_the_nav_and_the_index():
    assert "gallery.md" in (ROOT / "mkdocs.yml").read_text()
    assert "](gallery.md)" in (ROOT / "docs" / "index.md").read_text()


# ------------------------------------------------------------------ the tutorial notebook


def test_tutorial_notebook_runs(monkeypatch, tmp_path):
    """examples/tutorial.ipynb executes top to bottom (its cells assert the curve errors and the
    save/load round trip); the committed file keeps no outputs."""
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    pytest.importorskip("ipykernel")
    path = EXAMPLES / "tutorial.ipynb"
    nb = nbformat.read(path, as_version=4)
    assert all(not c.get("outputs") for c in nb.cells if c.cell_type == "code")
    # the kernel inherits the environment: this checkout's sources, one thread, and matplotlib's
    # inline backend (the kernel's default, which needs no display) so that figures become outputs
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(filter(None, [str(ROOT / "src"), os.environ.get("PYTHONPATH")])))
    monkeypatch.setenv("OMP_NUM_THREADS", "1")
    monkeypatch.delenv("MPLBACKEND", raising=False)
    nbclient.NotebookClient(nb, timeout=180, kernel_name="python3",
                            resources={"metadata": {"path": str(tmp_path)}}).execute()
    outputs = {i: c.outputs for i, c in enumerate(nb.cells) if c.cell_type == "code"}
    html = [o for outs in outputs.values() for o in outs if "text/html" in o.get("data", {})]
    assert html and "f1" in html[0]["data"]["text/html"]   # the model's _repr_html_
    assert any("image/png" in o.get("data", {}) for outs in outputs.values() for o in outs)  # model.plot
    assert "z**3" in str(outputs)
