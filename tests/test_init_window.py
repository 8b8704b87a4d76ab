"""validate --init-window: the initial state from the first N samples only, the RMSE after them."""

from __future__ import annotations

import json

import numpy as np
import pytest

import charcurves as cc
from charcurves._errors import ConfigError
from charcurves.simulate import free_run_error
from charcurves.systems import get_system

PARAM = dict(method="parametric", basis="f1=z; f2=z, z**3")


@pytest.fixture(scope="module")
def clean():
    system = get_system("duffing")
    record = system.simulate(t_end=20.0, n_points=501)
    return system, record, cc.fit(record, **PARAM)


def test_the_state_comes_from_the_window_and_the_rmse_from_the_rest(clean):
    system, record, model = clean
    shifted = record.replace(x=np.asarray(record.x) + np.where(np.arange(record.n_samples) >= 50, 5.0, 0.0))
    rmse, res = free_run_error(model, shifted, substeps=1, init_window=50)
    # the window is clean: the free run follows the true motion, 5.0 away from the shifted samples
    assert abs(res.x[0] - system.x0) < 1e-3
    assert rmse == pytest.approx(float(np.sqrt(np.mean((res.x[50:] - np.asarray(shifted.x)[50:]) ** 2))), rel=1e-12)
    assert rmse == pytest.approx(5.0, abs=0.01)
    # without a window the first 128 samples (78 of them shifted) pull the initial state away
    _, plain = free_run_error(model, shifted, substeps=1)
    assert abs(plain.x[0] - system.x0) > 0.5


@pytest.mark.parametrize("window", [1, 490, True, 2.5])
def test_a_window_that_leaves_too_little_is_refused(clean, window):
    _, record, model = clean
    with pytest.raises(ConfigError, match="initialisation window must be a whole number of samples from 2 to 485"):
        free_run_error(model, record, substeps=1, init_window=window)


def test_validate_cli_says_the_window_in_its_lines_and_json(clean, tmp_path, capsys):
    from charcurves.cli import main

    _, record, model = clean
    record.replace(v=None, a=None).to_csv(tmp_path / "r.csv")
    model.save(tmp_path / "model")
    code = main(["validate", str(tmp_path / "model"), str(tmp_path / "r.csv"), "--init-window", "100",
                 "--substeps", "1", "--out", str(tmp_path / "v")])
    out = capsys.readouterr().out
    assert code == 0
    assert "initial state fitted to the first 100 samples of each span, the RMSE counted after them" in out
    doc = json.loads((tmp_path / "v" / "validation.json").read_text())
    assert doc["init_window"] == 100 and doc["segments"][0]["rmse_rows"] == [100, 501]
    assert doc["segments"][0]["rmse"] < 2e-3  # clean record, exact model: RK4 at 1 step a sample, linear hold
