"""Model files (issue 8): the schema is checked on load, damage is reported as ModelFileError,
loading never runs code, writes are atomic under SIGKILL, and Ctrl-C keeps the best model so far."""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import charcurves as cc
from charcurves._errors import ModelFileError
from charcurves.curves import SymbolicFittedCurve
from charcurves.fitting import MODEL_SCHEMA, FittedModel, load_model, validate_model_document

# module fixtures (saved ~1.2 CPU s) made once: all tests here in one xdist worker (--dist loadgroup)
pytestmark = pytest.mark.xdist_group("model_files")

DOCS = Path(__file__).resolve().parents[1] / "docs" / "model-format.md"


@pytest.fixture(scope="module")
def record():
    from charcurves.data import corrupt
    from charcurves.systems import get_system

    return corrupt(get_system("duffing").simulate(n_points=400), 30, seed=0)


@pytest.fixture(scope="module")
def saved(tmp_path_factory, record):
    """A neural model and a parametric model, saved once; tests work on copies."""
    root = tmp_path_factory.mktemp("models")
    neural = cc.CharacteristicCurves.from_method(method="nn-cc+sym", threads=1).fit(record).model_
    neural.save(root / "neural")
    parametric = cc.fit(record, method="parametric", basis="f1=z; f2=z, z**3", threads=1)
    parametric.save(root / "parametric")
    return root


def _copy(saved, name, tmp_path) -> Path:
    dst = tmp_path / name
    shutil.copytree(saved / name, dst)
    return dst


def _edit(directory: Path, change) -> None:
    path = directory / "model.json"
    doc = json.loads(path.read_text())
    change(doc)
    path.write_text(json.dumps(doc))


def test_round_trip_is_exact(saved, tmp_path):
    z = np.linspace(-1.5, 1.5, 301)
    for name in ("neural", "parametric"):
        m = load_model(saved / name)
        m.save(tmp_path / name)  # saving over nothing: a fresh directory appears whole
        again = load_model(tmp_path / name)
        for curve in ("f1", "f2"):
            assert np.array_equal(m.curves[curve](z), again.curves[curve](z))
        assert (again.gain, again.offset, again.loss) == (m.gain, m.offset, m.loss)
        assert not [p for p in os.listdir(tmp_path) if p.startswith(".tmp")]


def test_documented_schema_matches_the_checker():
    text = DOCS.read_text()
    for key in MODEL_SCHEMA:
        assert f"`{key}`" in text, f"docs/model-format.md does not describe {key!r}"
    for key in ("hidden", "activation", "symmetry_mode", "linear_term", "jump", "in_scale", "out_scale", "basis",
                "expression", "arrays.safetensors", "format_version", "ModelFileError"):
        assert key in text, key


# (change to model.json, words the ModelFileError must hold)
DAMAGE = [
    (lambda d: d.pop("curves"), "model.curves is missing"),
    (lambda d: d.pop("arrays_sha256"), "model.arrays_sha256 is missing"),
    (lambda d: d.pop("template"), "model.template is missing"),
    (lambda d: d["template"].pop("family"), "model.template.family is missing"),
    (lambda d: d.update(gain="1.0"), "model.gain must be a number, not a string"),
    (lambda d: d.update(loss=True), "model.loss must be a number, not a boolean"),
    (lambda d: d.update(curves={}), "model.curves must be a list, not an object"),
    (lambda d: d.update(info=[]), "model.info must be an object, not a list"),
    (lambda d: d.update(method=None), "model.method must be a string, not null"),
    (lambda d: d["curves"][0].update(domain="wide"), "model.curves[0].domain must be a list"),
    (lambda d: d["curves"][0].update(domain=[0.0]), "model.curves[0].domain must be [low, high]"),
    (lambda d: d["curves"][1].update(shift=[1]), "model.curves[1].shift must be a number"),
    (lambda d: d["curves"][0]["network"].update(hidden=["8"]), "model.curves[0].network.hidden[0] must be an integer"),
    (lambda d: d["curves"][0]["network"].update(jump="no"), "model.curves[0].network.jump must be true or false"),
    (lambda d: d["curves"][0].pop("in_scale"), "model.curves[0].in_scale is missing"),
    (lambda d: d["curves"][0]["network"].update(activation="rm -rf"), "unknown activation 'rm -rf'"),
    (lambda d: d["curves"][0]["network"].update(hidden=[8, 8, 8]), "weights of shape"),
    (lambda d: d["curves"][1].update(name="f1"), "curve names ['f1', 'f1'] are empty or repeated"),
    (lambda d: d["curves"][0].update(kind="quantum"), "unknown curve kind 'quantum'"),
    (lambda d: d.update(arrays_sha256="abc"), "not a sha256 hex digest"),
    (lambda d: d.update(format_version=2), "model format version 2 is not supported"),
    (lambda d: d.update(format_version=2), "upgrade charcurves"),
    (lambda d: d.update(format_version="1"), "invalid format_version '1'"),
    (lambda d: d.update(format_version=0), "invalid format_version 0"),
    (lambda d: d.update(format="pickle"), "is not a charcurves model file"),
    (lambda d: d["template"].update(family="mystery"), "unknown family 'mystery'"),
]


@pytest.mark.parametrize("change,words", DAMAGE, ids=[w for _, w in DAMAGE])
def test_damaged_documents_give_a_clear_model_file_error(saved, tmp_path, change, words):
    d = _copy(saved, "neural", tmp_path)
    _edit(d, change)
    with pytest.raises(ModelFileError) as info:
        load_model(d)
    message = str(info.value)
    assert words in message and "\n" not in message, message
    assert re.search(r"re-save|re-fit|upgrade|give the directory", message), message


def test_a_newer_writer_may_add_keys(saved, tmp_path):
    d = _copy(saved, "parametric", tmp_path)
    _edit(d, lambda doc: doc.update(comment="added by a later release", extra={"x": 1}))
    assert load_model(d).method == "parametric"


@pytest.mark.parametrize("cut", [0, 1, 10, 100, -200, -2])
def test_truncated_json_is_reported(saved, tmp_path, cut):
    d = _copy(saved, "neural", tmp_path)
    raw = (d / "model.json").read_bytes()
    (d / "model.json").write_bytes(raw[:cut] if cut >= 0 else raw[:cut])
    with pytest.raises(ModelFileError, match="not valid JSON .* corrupted"):
        load_model(d)


def test_corrupted_truncated_or_missing_arrays(saved, tmp_path):
    d = _copy(saved, "neural", tmp_path)
    blob = bytearray((d / "arrays.safetensors").read_bytes())
    blob[len(blob) // 2] ^= 0x01  # one flipped bit
    (d / "arrays.safetensors").write_bytes(bytes(blob))
    with pytest.raises(ModelFileError, match="does not match the checksum"):
        load_model(d)
    (d / "arrays.safetensors").write_bytes(bytes(blob[:50]))
    with pytest.raises(ModelFileError, match="checksum"):
        load_model(d)
    # a damaged array file whose checksum was updated too (hand-edited): the reader still refuses it
    import hashlib

    junk = b"\x08\x00\x00\x00\x00\x00\x00\x00{garbage"
    (d / "arrays.safetensors").write_bytes(junk)
    _edit(d, lambda doc: doc.update(arrays_sha256=hashlib.sha256(junk).hexdigest()))
    with pytest.raises(ModelFileError, match="not a readable safetensors file"):
        load_model(d)
    (d / "arrays.safetensors").unlink()
    with pytest.raises(ModelFileError, match="arrays.safetensors' is missing"):
        load_model(d)


def test_bad_locations(tmp_path, saved):
    with pytest.raises(ModelFileError, match="does not exist"):
        load_model(tmp_path / "nowhere")
    (tmp_path / "file").write_text("x")
    with pytest.raises(ModelFileError, match="is not a directory"):
        load_model(tmp_path / "file")
    (tmp_path / "empty").mkdir()
    with pytest.raises(ModelFileError, match="model.json' is missing"):
        load_model(tmp_path / "empty")
    model = load_model(saved / "parametric")
    with pytest.raises(ModelFileError, match="is a file, not a model directory"):
        model.save(tmp_path / "file")


MALICIOUS = [
    "__import__('os').system('touch {marker}')",
    "exec(\"open('{marker}', 'w')\")",
    "eval('1')",
    "open('{marker}', 'w')",
    "z.__class__.__bases__[0].__subclasses__()",
    "lambda: 0",
    "[c for c in ()]",
    "z; import os",
    "getattr(z, 'evalf')",
    "Symbol('x') + z",
    "9**9**9*z",
    "z**(10**100)",
    "((z**99)**99)**99",
    "1" * 400 + "*z",
]


@pytest.mark.parametrize("kind", ["symbolic", "basis"])
@pytest.mark.parametrize("text", MALICIOUS)
def test_loading_never_runs_code_or_hangs(saved, tmp_path, kind, text):
    marker = tmp_path / "PWNED"
    text = text.replace("{marker}", str(marker))
    d = _copy(saved, "parametric", tmp_path)
    if kind == "symbolic":
        def change(doc):
            c = doc["curves"][0]
            for key in ("basis",):
                c.pop(key)
            c.update(kind="symbolic", expression=text, meta={})
    else:
        def change(doc):
            doc["curves"][0]["basis"] = [text]
    _edit(d, change)
    t0 = time.perf_counter()
    with pytest.raises(ModelFileError) as info:
        load_model(d)
    assert time.perf_counter() - t0 < 5
    assert not marker.exists()
    assert "\n" not in str(info.value)


def test_symbolic_models_round_trip(tmp_path, record):
    base = cc.fit(record, method="parametric", basis="f1=z; f2=z, z**3", threads=1)
    curves = {n: SymbolicFittedCurve(n, c.argument, c.domain, str(c.expression())) for n, c in base.curves.items()}
    model = FittedModel(base.template, "sr-cc", curves, base.gain, base.offset, base.loss, {"x_seconds": 1.5})
    model.save(tmp_path / "s")
    back = load_model(tmp_path / "s")
    z = np.linspace(-1, 1, 11)
    assert np.allclose(back.curves["f2"](z), base.curves["f2"](z), rtol=1e-12, atol=1e-12)
    validate_model_document(json.loads((tmp_path / "s" / "model.json").read_text()))


COSTLY = ["9**9**9*z", "z**(10**100)", "((z**99)**99)**99", "1" * 400 + "*z", "2**2**2**2**2*z"]


@pytest.mark.parametrize("text", COSTLY)
def test_every_parser_of_closed_forms_refuses_costly_text_quickly(text):
    """The cost guard sits in the shared token checker, so no path that hands text to sympy
    can hang: the basis parser, symbolic curves built from text, fitted bases, and the parser of
    symbolic-regression engines' output."""
    import sympy as sp

    from charcurves._errors import ConfigError
    from charcurves.curves import parse_basis_function
    from charcurves.curves import BasisFittedCurve
    from charcurves.symbolic import parse_infix

    calls = [
        lambda: parse_basis_function(text),
        lambda: SymbolicFittedCurve("f1", "x'", (-1.0, 1.0), text),
        lambda: BasisFittedCurve("f1", "x'", (-1.0, 1.0), ["z", text], [1.0, 2.0]),
        lambda: parse_infix(text.replace("z", "X1"), [sp.Symbol("z")]),
    ]
    for call in calls:
        t0 = time.perf_counter()
        with pytest.raises(ConfigError) as info:
            call()
        assert time.perf_counter() - t0 < 2
        message = str(info.value)
        assert "\n" not in message and "plain closed form" in message
        assert any(w in message for w in ("exponent", "digits", "nests powers")), message


def test_the_cost_guard_leaves_ordinary_closed_forms_alone():
    from charcurves.curves import parse_basis_function

    z = np.linspace(-1, 1, 7)
    curve = SymbolicFittedCurve("f1", "x'", (-1.0, 1.0), "0.3*z**3 - 1.5*tanh(50*z) + 2**3*z + (z**2)**0.5")
    assert np.allclose(curve(z), 0.3 * z**3 - 1.5 * np.tanh(50 * z) + 8 * z + np.abs(z), rtol=1e-12, atol=1e-12)
    assert str(parse_basis_function("(z**2)**3*exp(-z**2)")) == "z**6*exp(-z**2)"


# ---------------------------------------------------------------------- SIGKILL while saving
def _save_forever(model, root: Path) -> None:
    i = 0
    while True:
        model.info["round"] = i
        model.save(root / "over")  # overwritten again and again
        model.save(root / f"fresh{i}")  # new directories
        i += 1


def test_sigkill_while_saving_never_leaves_a_half_written_model(saved, tmp_path):
    model = load_model(saved / "neural")
    rng = np.random.default_rng(8)
    seen_fresh = 0
    for round_ in range(8):
        root = tmp_path / f"r{round_}"
        root.mkdir()
        pid = os.fork()  # a warm copy of this process, killed at a random moment while it saves
        if pid == 0:
            try:
                _save_forever(model, root)
            finally:
                os._exit(0)
        time.sleep(float(rng.uniform(0.02, 0.4)))
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
        for entry in sorted(os.listdir(root)):
            path = root / entry
            if entry.startswith(".tmp"):
                continue  # unfinished temporaries of the kill: never a model
            raw = (path / "model.json").read_bytes()
            json.loads(raw)  # never half-written: always complete JSON
            if entry.startswith("fresh"):
                seen_fresh += 1
                assert load_model(path).method == "nn-cc+sym"  # a new model appears whole or not at all
            else:
                try:
                    load_model(path)
                except ModelFileError as exc:  # killed between its two files: detected, never garbage
                    assert "checksum" in str(exc)
    assert seen_fresh > 0


# ---------------------------------------------------------------------- Ctrl-C during a long fit
def _sigint_at_default():
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_ctrl_c_keeps_the_best_model_so_far(tmp_path, record):
    csv = tmp_path / "d.csv"
    record.to_csv(csv)
    out = tmp_path / "fit"
    env = dict(os.environ, OMP_NUM_THREADS="1")
    # the paper preset runs 20 000 Adam epochs (minutes): stop it once it reports progress
    # Ctrl-C reaches a command in the terminal's foreground, whose SIGINT is at its default. A test run
    # started as a script's background job (`pytest &`) inherits SIGINT *ignored* (POSIX), and then
    # Python never raises KeyboardInterrupt: give the child the foreground's default whatever ours is
    p = subprocess.Popen([sys.executable, "-m", "charcurves", "fit", str(csv), "--preset", "paper", "--out", str(out),
                          "--no-figure"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                         preexec_fn=_sigint_at_default)
    for _ in range(50):  # progress goes to stderr every 2 s; wait until training is under way
        line = p.stderr.readline()
        progress = re.match(r"\s+\[adam\] (\d+)/20000\s+loss", line)
        if not line or (progress and int(progress.group(1)) >= 100):
            break
    assert progress and int(progress.group(1)) >= 100, line
    p.send_signal(signal.SIGINT)
    stdout, stderr = p.communicate(timeout=120)
    assert p.returncode == 130, stderr
    lines = [ln for ln in stderr.splitlines() if not ln.startswith("  [")]  # progress lines aside
    assert len(lines) == 1 and lines[0].startswith("charcurves: interrupted; kept the best model so far"), stderr
    assert "Traceback" not in stderr
    assert "interrupted: these are the best curves reached before Ctrl-C" in stdout
    result = json.loads((out / "result.json").read_text())
    assert result["interrupted"] is True and result["info"]["stopped_by"] == "interrupted"
    assert 0 < result["info"]["adam_steps"] < 20000
    model = load_model(out / "model")
    assert model.info["interrupted"] is True
    v = np.linspace(-0.5, 0.5, 5)
    predicted = model.acceleration(0.0, v, v, np.zeros_like(v))
    assert np.isfinite(predicted).all()
    # the curves written are those of result.json
    f2 = result["curves"]["f2"]
    assert np.allclose(model.curves["f2"](np.asarray(f2["grid"])), f2["values"], rtol=1e-12, atol=1e-12)
    assert json.loads((out / "timing.json").read_text())["fit_seconds"] > 0


# ---------------------------------------------------------------------- Ctrl-C after or between chunks
@pytest.mark.parametrize("family", ["separable", "position-damping"])
def test_ctrl_c_in_a_chunked_fit_leaves_the_later_chunks_untrained(family):
    """Ten records train as two chunks (8 + 2 records of 6 starts). Ctrl-C during the first
    chunk: it keeps its best weights so far, the second chunk never trains, and every model of
    the call says so (interrupted, with its own chunk's stopped_by). Both neural fitters (the
    separable one and that of general templates) behave alike."""
    from charcurves.data import corrupt
    from charcurves.systems import get_system

    clean = get_system("duffing").simulate(n_points=200)
    records = [corrupt(clean, 30, seed=i) for i in range(10)]
    calls = []

    def progress(phase, step, total, loss):  # stands in for the user's Ctrl-C at Adam step 100
        calls.append((phase, step))
        if (phase, step) == ("adam", 100):
            raise KeyboardInterrupt

    t0 = time.perf_counter()
    est = cc.CharacteristicCurves.from_method(method="nn-cc", family=family, threads=1, progress=progress)
    models = est.fit_many(records, seeds=range(10))
    assert calls == [("adam", 0), ("adam", 100)], "no training may run after the interrupt"
    assert time.perf_counter() - t0 < 60
    assert all(m.info["interrupted"] is True for m in models)
    first, later = models[:8], models[8:]
    assert {m.info["stopped_by"] for m in first} == {"interrupted"}
    assert all(m.info["adam_steps"] == 100 and m.info["lm_iterations"] == 0 for m in first)
    assert {m.info["stopped_by"] for m in later} == {"not trained: interrupted"}
    assert all(m.info["adam_steps"] == 0 and m.info["lm_iterations"] == 0 for m in later)
    v = np.linspace(-1, 1, 9)
    assert all(np.isfinite(m.curves["f1"](v)).all() and np.isfinite(m.loss) for m in models)


def test_ctrl_c_during_post_sr_writes_the_finished_fit(tmp_path, record, monkeypatch, capsys):
    """Operon's search does not watch for Ctrl-C; the interrupt arrives when it returns. The
    finished fit before post-SR is written, and what was skipped is said."""
    import charcurves.fitting._post_sr as distill_module
    from charcurves.cli import main

    def interrupted_search(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(distill_module, "distill_model", interrupted_search)
    csv = tmp_path / "d.csv"
    record.to_csv(csv)
    out = tmp_path / "fit"
    code = main(["fit", str(csv), "--method", "sindy-cc+sym+post-sr", "--out", str(out), "--no-figure", "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 130
    assert err == [f"charcurves: interrupted; the fit had finished and was written to {out}, without post-SR "
                   "(result.json marked interrupted); rerun to compute them"]
    result = json.loads((out / "result.json").read_text())
    assert result["interrupted"] is True and result["info"]["post_sr"] == "skipped: interrupted"
    assert result["method"] == "sindy-cc+sym+post-sr"
    # the curves written are the SINDy-CC+sym fit itself: odd polynomials close to the truth
    reference = cc.CharacteristicCurves.from_method(method="sindy-cc+sym", threads=1).fit(record).model_
    model = load_model(out / "model")
    z = np.linspace(-1, 1, 21)
    for name in ("f1", "f2"):
        assert np.allclose(model.curves[name](z), reference.curves[name](z), rtol=1e-12, atol=1e-12)
    assert "Ctrl-C skipped post-SR" in (out / "summary.txt").read_text()


def test_ctrl_c_during_output_error_refinement_writes_the_finished_fit(tmp_path, record, monkeypatch, capsys):
    import charcurves.objectives._objectives as objectives
    from charcurves.cli import main

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(objectives, "output_error_fit", interrupted)  # where OutputError.refine looks it up
    csv = tmp_path / "d.csv"
    record.to_csv(csv)
    out = tmp_path / "fit"
    code = main(["fit", str(csv), "--method", "parametric", "--basis", "f1=z; f2=z, z**3", "--refine", "output-error",
                 "--out", str(out), "--no-figure", "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 130
    assert err == [f"charcurves: interrupted; the fit had finished and was written to {out}, without the "
                   "output-error refinement (result.json marked interrupted); rerun to compute them"]
    result = json.loads((out / "result.json").read_text())
    assert result["interrupted"] is True and result["info"]["refine"] == "skipped: interrupted"
    reference = cc.CharacteristicCurves.from_method(method="parametric", basis="f1=z; f2=z, z**3", threads=1).fit(record).model_
    assert result["curves"] == reference.result_dict()["curves"]


def test_ctrl_c_during_band_refits_writes_the_main_fit(tmp_path, record, monkeypatch, capsys):
    import charcurves.fitting._ensemble as bands_module
    from charcurves.cli import main

    class Interrupted:
        def resolve(self, *args, **kwargs):
            raise KeyboardInterrupt

    monkeypatch.setattr(bands_module, "_member_estimator", lambda estimator, point: Interrupted())
    csv = tmp_path / "d.csv"
    record.to_csv(csv)
    out = tmp_path / "fit"
    code = main(["fit", str(csv), "--method", "poly-cc", "--bands", "4", "--out", str(out), "--no-figure", "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 130
    assert err == [f"charcurves: interrupted; the fit had finished and was written to {out}, without the "
                   "uncertainty bands (result.json marked interrupted); rerun to compute them"]
    result = json.loads((out / "result.json").read_text())
    assert result["interrupted"] is True and result["info"]["bands"] == "skipped: interrupted"
    assert "bands" not in result
    reference = cc.CharacteristicCurves.from_method(method="poly-cc", threads=1).fit(record).model_.result_dict()
    assert result["curves"] == reference["curves"]  # the finished main fit, bit for bit


def test_band_refits_stopped_by_ctrl_c_make_no_ensemble(record, monkeypatch):
    """Neural refits answer Ctrl-C by returning their best weights so far: fit_ensembles must not
    turn those into bands; the interrupt goes on to the caller."""
    import charcurves.train._train as gradient
    from charcurves.selection import fit_ensembles

    real_train = gradient.train
    passes = []

    def counting(*args, **kwargs):
        passes.append(len(passes))
        return real_train(*args, **kwargs)

    # the point fit's own passes (two where an automatic term is checked against the fit without it)
    monkeypatch.setattr(gradient, "train", counting)
    cc.CharacteristicCurves.from_method(method="nn-cc", threads=1).fit(record)
    point_passes, passes[:] = len(passes), []

    def train_then_ctrl_c(*args, **kwargs):
        passes.append(len(passes))
        if len(passes) == point_passes + 1:  # the members' pass: Ctrl-C at Adam step 100
            def stop(phase, step, total, loss):
                if (phase, step) == ("adam", 100):
                    raise KeyboardInterrupt
            kwargs["progress"] = stop
        return real_train(*args, **kwargs)

    monkeypatch.setattr(gradient, "train", train_then_ctrl_c)
    with pytest.raises(KeyboardInterrupt):
        fit_ensembles(cc.CharacteristicCurves.from_method(method="nn-cc", threads=1), [record], 3, kind="seeds")
    assert passes == list(range(point_passes + 1))


def test_docs_index_links_every_page_and_every_link_resolves():
    docs = DOCS.parent
    index = (docs / "index.md").read_text()
    links = re.findall(r"\]\(([^)#]+)\)", index)
    pages = sorted(p.name for p in docs.glob("*.md") if p.name != "index.md")
    assert sorted(link for link in links if "/" not in link) == pages
    assert all((docs / link).resolve().is_file() for link in links)
    # one line per page
    assert len([ln for ln in index.splitlines() if ln.startswith("- [")]) == len(pages)


# ---------------------------------------------------------------------- model.json checksum, ranges (issue 50)
def _resign(directory: Path) -> None:
    """Recompute model.json's own checksum, as a writer would: for edits that must fail on their values."""
    from charcurves.fitting import model_digest

    _edit(directory, lambda doc: doc.update(model_sha256=model_digest(doc, doc["model_sha256_keys"])))


@pytest.mark.parametrize("name,change,detail", [
    ("parametric", lambda d: d.update(gain=d["gain"] * 1.5), None),
    ("neural", lambda d: d["curves"][0].update(out_scale=d["curves"][0]["out_scale"] * 2), None),
    ("neural", lambda d: d["info"].update(seed=12345), None),
    ("neural", lambda d: d.pop("created"), "'created', covered by model_sha256, was removed"),
], ids=["gain", "out_scale", "info", "removed key"])
def test_an_edited_model_json_is_detected_at_load(saved, tmp_path, name, change, detail):
    """Before: the checksum covered arrays.safetensors only, and an edited gain loaded unnoticed."""
    d = _copy(saved, name, tmp_path)
    doc = json.loads((d / "model.json").read_text())
    assert doc["model_sha256_keys"] == sorted(k for k in doc if k not in ("model_sha256", "model_sha256_keys"))
    _edit(d, change)
    with pytest.raises(ModelFileError) as info:
        load_model(d)
    detail = detail or "its values no longer match model_sha256, e.g. an edited gain"
    assert str(info.value) == (f"{str(d / 'model.json')!r} was modified after it was saved ({detail}); refusing to "
                               "load it, re-fit the model or restore the file as saved")


def test_models_saved_without_the_model_json_checksum_still_load(saved, tmp_path):
    d = _copy(saved, "neural", tmp_path)
    _edit(d, lambda doc: [doc.pop("model_sha256"), doc.pop("model_sha256_keys")])  # as written before issue 50
    z = np.linspace(-1, 1, 21)
    assert np.array_equal(load_model(d).curves["f1"](z), load_model(saved / "neural").curves["f1"](z))


@pytest.mark.parametrize("where,value,words", [
    (("curves", 0, "out_scale"), 1e308, "model.curves[0].out_scale is 1e+308, out of range (it must be between "
                                        "1e-100 and 1e+100 in magnitude)"),
    (("curves", 0, "in_scale"), 1e-200, "model.curves[0].in_scale is 1e-200, out of range"),
    (("gain",), -1e101, "model.gain is -1e+101, out of range"),
    (("offset",), 1e200, "model.offset is 1e+200, out of range (it must be finite and at most 1e+100 in magnitude)"),
    (("curves", 1, "domain", 1), 1e300, "model.curves[1].domain[1] is 1e+300, out of range"),
], ids=["out_scale", "in_scale", "gain", "offset", "domain"])
def test_out_of_range_values_are_refused_at_load(saved, tmp_path, where, value, words):
    d = _copy(saved, "neural", tmp_path)

    def change(doc):
        node = doc
        for key in where[:-1]:
            node = node[key]
        node[where[-1]] = value

    _edit(d, change)
    _resign(d)  # a consistent checksum: the value itself is refused
    with pytest.raises(ModelFileError) as info:
        load_model(d)
    assert words in str(info.value) and "re-fit the model" in str(info.value), str(info.value)


def test_non_finite_weights_are_refused_at_load(saved, tmp_path):
    import hashlib

    from safetensors.numpy import load as st_load
    from safetensors.numpy import save as st_save

    d = _copy(saved, "neural", tmp_path)
    arrays = st_load((d / "arrays.safetensors").read_bytes())
    name = sorted(arrays)[0]
    arrays[name] = arrays[name].copy()
    arrays[name].flat[0] = np.inf
    blob = st_save(arrays)
    (d / "arrays.safetensors").write_bytes(blob)
    _edit(d, lambda doc: doc.update(arrays_sha256=hashlib.sha256(blob).hexdigest()))
    _resign(d)
    with pytest.raises(ModelFileError, match=f"the array {name!r} holds non-finite values or values beyond 1e"):
        load_model(d)


def test_report_refuses_a_model_with_an_output_scale_of_1e308(saved, tmp_path, capsys):
    """Before: report ended in an OverflowError traceback."""
    from charcurves.cli import main

    d = _copy(saved, "neural", tmp_path)
    _edit(d, lambda doc: doc["curves"][0].update(out_scale=1e308))
    _resign(d)
    capsys.readouterr()
    assert main(["report", str(d), "--out", str(tmp_path / "r.html")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "model.curves[0].out_scale is 1e+308, out of range" in err
    assert not (tmp_path / "r.html").exists()


def test_a_model_folder_link_is_saved_through(saved, tmp_path):
    model = load_model(saved / "parametric")
    (tmp_path / "real").mkdir()
    os.symlink("real", tmp_path / "link")
    model.save(tmp_path / "link")
    assert os.readlink(tmp_path / "link") == "real" and sorted(os.listdir(tmp_path / "real")) == [
        "arrays.safetensors", "model.json"]
    os.symlink("fresh", tmp_path / "dangling")
    model.save(tmp_path / "dangling")
    assert load_model(tmp_path / "fresh").gain == model.gain
