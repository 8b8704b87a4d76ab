"""validate --init-window for models with hidden states: the initial state (hidden ones included)
from the first N samples of the test record only, the RMSE counted after them."""

from __future__ import annotations

import json

import numpy as np
import pytest

from charcurves._errors import ConfigError
from charcurves.fitting import StateSpaceModel, estimate_window_state, window_free_run_error
from charcurves.systems import TwoTank
from charcurves.templates import StateSpace

TANKS = "x1' = g*F - f1(x1); x2' = f1(x1) - f2(x2)"


def _projected(name, argument, fn, lo, hi, degree=12):
    """``fn`` projected (least squares) on a power polynomial over ``[lo, hi]``."""
    import torch

    from charcurves.curves import LinearFittedCurve, Polynomial

    rep = Polynomial(degree=degree, basis="power")
    center, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    u = np.linspace(lo, hi, 400)
    phi = rep.features(torch.as_tensor((u - center) / half)).numpy()
    coef = np.linalg.lstsq(np.column_stack([np.ones(u.size), phi]), fn(u), rcond=None)[0]
    return LinearFittedCurve(name, argument, (lo, hi), rep, coef[1:], center, half, float(coef[0]))


@pytest.fixture(scope="module")
def tanks():
    """The true two-tank model (outflows projected on degree 12 over the range the states visit),
    the upper level x1 hidden, and a clean record of it."""
    system = TwoTank(noise=0.0)
    clean = system.states(n_points=600, t_end=600.0, seed=3)
    template = StateSpace(TANKS, measured={"x2": "x"})
    curves = {"f1": _projected("f1", "x1", system.f1, 0.0, 1.1 * clean["x1"].max()),
              "f2": _projected("f2", "x2", system.f2, 0.0, 1.1 * clean["x2"].max())}
    info = {"measured": {"x2": "x"}, "substeps": 2, "hold": "linear", "hidden": ["x1"], "scalars": {}}
    model = StateSpaceModel(template, template.structure(), curves, 1.0, {"x1": 0.0, "x2": 0.0}, info)
    return system, clean, model


def test_the_hidden_initial_state_comes_from_the_window(tanks):
    system, clean, model = tanks
    start = 200  # mid-record: both levels far from the empty tanks' 0
    record = system.simulate(n_points=600, t_end=600.0, seed=3).slice(slice(start, 600))
    state = estimate_window_state(model, record, 40)
    truth = {"x1": float(clean["x1"][start]), "x2": float(clean["x2"][start])}
    assert truth["x1"] > 1.0  # the hidden level is not at its fitted initial value 0
    assert state["x1"] == pytest.approx(truth["x1"], rel=2e-3)  # measured: 2.5e-4
    assert state["x2"] == pytest.approx(truth["x2"], abs=2e-3)  # measured: 5e-4
    rmse, initial = window_free_run_error(model, record, 40)
    assert initial == state
    # the whole record from that state: the projected curves' own error, far below the levels' size
    assert rmse["x2"] < 0.02 * float(np.std(clean["x2"][start + 40:400]))


def test_the_window_does_not_read_past_its_samples(tanks):
    system, _, model = tanks
    record = system.simulate(n_points=600, t_end=600.0, seed=3).slice(slice(200, 400))
    changed = record.replace(x=np.where(np.arange(record.n_samples) >= 40, record.x + 5.0, record.x))
    assert estimate_window_state(model, changed, 40) == estimate_window_state(model, record, 40)
    rmse, _ = window_free_run_error(model, changed, 40)
    assert rmse["x2"] == pytest.approx(5.0, abs=0.05)  # counted after the window, on the shifted samples


@pytest.mark.parametrize("window", [1, 185, True, 2.5])
def test_a_window_that_leaves_too_little_is_refused(tanks, window):
    system, _, model = tanks
    record = system.simulate(n_points=600, t_end=600.0, seed=3).slice(slice(200, 400))
    with pytest.raises(ConfigError, match="initialisation window must be a whole number of samples from 2 to 184"):
        window_free_run_error(model, record, window)


def test_validate_cli_with_a_window(tanks, tmp_path, capsys):
    from charcurves.cli import main

    system, clean, model = tanks
    model.save(tmp_path / "model")
    record = system.simulate(n_points=600, t_end=600.0, seed=3).slice(slice(200, 400))
    record.to_csv(tmp_path / "r.csv")
    code = main(["validate", str(tmp_path / "model"), str(tmp_path / "r.csv"), "--init-window", "40",
                 "--out", str(tmp_path / "v")])
    out = capsys.readouterr().out
    assert code == 0
    assert "initial state (hidden states included) fitted to the first 40 samples, the RMSE counted after them" in out
    doc = json.loads((tmp_path / "v" / "validation.json").read_text())
    assert doc["init_window"] == 40 and doc["rmse_rows"] == [40, 200]
    assert doc["initial_state"]["x1"] == pytest.approx(float(clean["x1"][200]), rel=2e-3)
    assert doc["rmse"]["x2"] < 0.02 * float(np.std(clean["x2"][240:400]))


@pytest.mark.parametrize("window, message", [
    ("1", "argument --init-window: must be an integer from 2 to 2000000"),
    ("190", "the initialisation window must be a whole number of samples from 2 to 184 (the record has 200")])
def test_validate_cli_refuses_a_window_that_leaves_too_little(tanks, tmp_path, capsys, window, message):
    from charcurves.cli import main

    system, _, model = tanks
    model.save(tmp_path / "model")
    system.simulate(n_points=600, t_end=600.0, seed=3).slice(slice(200, 400)).to_csv(tmp_path / "r.csv")
    assert main(["validate", str(tmp_path / "model"), str(tmp_path / "r.csv"), "--init-window", window]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert message in err[0] and "--init-window" in err[0]


def test_rows_may_start_inside_the_file(tanks, tmp_path, capsys):
    """The default start is the state fitted to the span's first 128 samples, so a span may start
    mid-record (it had to start at row 0 while the hidden state started at its fitted value)."""
    from charcurves.cli import main

    system, clean, model = tanks
    model.save(tmp_path / "model")
    system.simulate(n_points=600, t_end=600.0, seed=3).to_csv(tmp_path / "all.csv")
    args = ["validate", str(tmp_path / "model"), str(tmp_path / "all.csv"), "--rows", "200:400"]
    assert main([*args, "--out", str(tmp_path / "d")]) == 0
    assert "fitted to the first 128 samples, the RMSE over all" in capsys.readouterr().out
    doc = json.loads((tmp_path / "d" / "validation.json").read_text())
    assert doc["init_window"] is None and doc["rmse_rows"] == [0, 200]
    assert doc["initial_state"]["x1"] == pytest.approx(float(clean["x1"][200]), rel=2e-3)
    # every sample counted, the window's too: the projected curves' own error, far below the levels' size
    assert doc["rmse"]["x2"] < 0.02 * float(np.std(clean["x2"][200:400]))
    record = system.simulate(n_points=600, t_end=600.0, seed=3).slice(slice(200, 400))
    # from the hidden level's fitted initial value 0 instead (the old default) it is far off
    assert model.free_run_rmse(record, start="first-samples")["x2"] > 10 * doc["rmse"]["x2"]
    assert main([*args, "--init-window", "40", "--out", str(tmp_path / "v")]) == 0
    doc = json.loads((tmp_path / "v" / "validation.json").read_text())
    rmse, initial = window_free_run_error(model, record, 40)
    assert doc["rmse"] == rmse and doc["initial_state"] == initial
