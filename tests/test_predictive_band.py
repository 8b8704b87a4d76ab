"""The predictive band of a free run (charcurves.simulate.predictive_band, charcurves validate): the
posterior propagated through the simulation plus the noise of x holds the validation record."""

from __future__ import annotations

import json
from statistics import NormalDist

import numpy as np
import pytest

import charcurves as cc
from charcurves.simulate import predictive_band
from charcurves.systems import get_system

BASIS = "f1=z; f2=z, z**3"


@pytest.fixture(scope="module")
def fitted():
    system = get_system("duffing")
    record = cc.corrupt(system.simulate(), 20, seed=0)
    model = cc.fit(record, method="parametric", basis=BASIS, free_gain=True, threads=1)
    val = cc.corrupt(system.simulate(t_end=10.0, n_points=251), 40, on="state", seed=50)
    return system, model, val


def test_the_band_holds_a_validation_record_of_the_same_system(fitted):
    system, model, val = fitted
    band = predictive_band(model, val, system.x0, system.v0, substeps=2, draws=60)
    assert band["draws"] == 60 and band["diverged"] == 0 and band["level"] == 0.95
    assert 0.92 <= band["inside"] <= 1.0
    # the noise of x estimated from the record: 40 dB of the record's std
    assert band["noise_sd"] == pytest.approx(np.std(val.x) * 10 ** (-40 / 20), rel=0.15)
    half = (band["hi"] - band["lo"]) / 2
    noise_only = NormalDist().inv_cdf(0.975) * band["noise_sd"]
    assert half.min() >= noise_only * (1 - 1e-9) and half[-50:].mean() > 1.5 * noise_only  # the posterior grows in
    run = cc.simulate.simulate_sampled(model, val, system.x0, system.v0, substeps=2)
    assert np.allclose(band["centre"], run.x, atol=1e-9)  # the centre is the fitted model's free run


def test_a_model_without_a_posterior_has_no_band(fitted):
    system, model, val = fitted
    import copy

    other = copy.deepcopy(model)
    other.curves["f2"].shift += 0.1
    assert predictive_band(other, val, system.x0, system.v0, substeps=1, draws=5) is None


def test_validate_reports_the_share_inside_the_band(fitted, tmp_path):
    from charcurves.simulate import validate_cli

    _, model, val = fitted
    model.save(tmp_path / "model")
    val.to_csv(tmp_path / "val.csv")
    lines, failed = validate_cli(tmp_path / "model", tmp_path / "val.csv", substeps=2, out_dir=tmp_path / "out")
    doc = json.loads((tmp_path / "out" / "validation.json").read_text())
    pb = doc["segments"][0]["predictive_band"]
    assert failed == [] and pb["draws"] == 100 and 0.9 <= pb["inside"] <= 1.0
    assert lines[1].endswith(f", {100 * pb['inside']:.3g} % of x inside the 95 % predictive band")


def test_a_direction_the_record_leaves_open_gives_no_finite_band(fitted):
    """A posterior with an undetermined gain (infinite variance) must not yield a finite band and a
    share inside it: the band is unbounded and says which direction is open."""
    import copy

    from charcurves.model import StoredPosterior

    system, model, val = fitted
    stored = StoredPosterior.from_posterior(model.posterior, model)
    names, mean, G, inf = stored.scalars
    inf = np.array(inf, dtype=bool)
    inf[names.index("gain")] = True
    stored.scalars = (names, mean, G, inf)
    other = copy.deepcopy(model)
    other.posterior = stored
    band = predictive_band(other, val, system.x0, system.v0, substeps=1, draws=5)
    assert band["unbounded"] == ["gain"] and np.isnan(band["inside"]) and band["draws"] == 0
    assert np.all(np.isinf(band["lo"])) and np.all(np.isinf(band["hi"]))
    finite = predictive_band(model, val, system.x0, system.v0, substeps=1, draws=5)
    assert "unbounded" not in finite and np.all(np.isfinite(finite["hi"]))
