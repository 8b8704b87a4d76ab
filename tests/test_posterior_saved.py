"""The posterior saved with the model: a loaded model has the same bands and ± as the fitted one,
old files load without one, a damaged one is refused in one line, and the report of a model
folder shows its bands and ±."""

from __future__ import annotations

import json

import numpy as np
import pytest

import charcurves as cc
from charcurves._errors import ConfigError, ModelFileError
from charcurves.fitting import model_digest, posterior_bands, scalar_lines, uncertainty_summary
from charcurves.systems import get_system

BASIS = "f1=z; f2=z, z**3"


@pytest.fixture(scope="module")
def record():
    return cc.corrupt(get_system("duffing").simulate(n_points=600), 20, seed=0)


@pytest.fixture(scope="module")
def saved(tmp_path_factory, record):
    root = tmp_path_factory.mktemp("posterior")
    fits = {"poly": cc.fit(record, method="poly-cc", free_gain=True, threads=1),
            "parametric": cc.fit(record, method="parametric", basis=BASIS, free_gain=True, threads=1)}
    for name, model in fits.items():
        model.save(root / name)
    return root, fits


def _rewrite(path, change):
    doc = json.loads((path / "model.json").read_text())
    change(doc)
    doc["model_sha256_keys"] = sorted(k for k in doc if k not in ("model_sha256", "model_sha256_keys"))  # as save()
    doc["model_sha256"] = model_digest(doc, doc["model_sha256_keys"])
    (path / "model.json").write_text(json.dumps(doc))


@pytest.mark.parametrize("name", ["poly", "parametric"])
def test_a_loaded_model_has_the_bands_and_scalars_of_the_fit(saved, name):
    root, fits = saved
    model, back = fits[name], cc.load_model(root / name)
    for curve in ("f1", "f2"):
        lo, hi = model.curves[curve].domain
        z = np.linspace(lo, hi, 37)  # off the stored grid of 201 points
        v0, lo0, hi0 = model.curve_band(curve, z)
        v1, lo1, hi1 = back.curve_band(curve, z)
        width = np.max(hi0 - lo0)
        assert np.max(np.abs(lo1 - lo0)) < 1e-5 * width and np.max(np.abs(hi1 - hi0)) < 1e-5 * width
        assert np.allclose(v1, back.curves[curve](z), rtol=1e-6, atol=1e-6 * width)
    s0, s1 = model.posterior.scalar_stats(), back.posterior.scalar_stats()
    assert s1["names"] == s0["names"] and "gain" in s1["names"]
    for k in s0["names"]:
        assert s1["mean"][k] == pytest.approx(s0["mean"][k], rel=1e-12)
        assert s1["sd"][k] == pytest.approx(s0["sd"][k], rel=1e-9)
    assert np.allclose(s1["correlation"], s0["correlation"], atol=1e-9)
    assert scalar_lines(back) == scalar_lines(model)
    u0, u1 = uncertainty_summary(model), uncertainty_summary(back)
    assert (u1["covariance"], u1["hac_bandwidth"]) == (u0["covariance"], u0["hac_bandwidth"])
    assert u1["noise_variance"] == pytest.approx(u0["noise_variance"], rel=1e-12)


def test_outside_the_training_range_a_saved_band_is_infinite(saved):
    root, fits = saved
    back = cc.load_model(root / "poly")
    lo, hi = back.curves["f2"].domain
    _, sd = back.posterior.curve_sd("f2", np.array([lo, hi, hi + 0.1 * (hi - lo)]))
    assert np.isfinite(sd[:2]).all() and sd[2] == np.inf
    assert back.posterior.with_kind("hac") is back.posterior
    with pytest.raises(ConfigError, match="holds the 'hac' covariance only"):
        back.posterior.with_kind("gauss")


def test_a_loaded_model_whose_curve_changed_has_no_posterior(saved):
    root, _ = saved
    back = cc.load_model(root / "poly")
    back.curves["f2"].shift += 0.5
    with pytest.raises(ConfigError, match="has no posterior"):
        back.curve_band("f2", np.array([1.0]))
    assert posterior_bands(back) == {}


def test_a_file_written_before_the_posterior_was_saved_loads_without_one(saved, tmp_path):
    import shutil

    root, fits = saved
    d = tmp_path / "old"
    shutil.copytree(root / "parametric", d)
    _rewrite(d, lambda doc: doc.pop("posterior"))
    back = cc.load_model(d)
    assert back.posterior is None and uncertainty_summary(back) is None
    z = np.linspace(-1, 1, 9)
    assert np.array_equal(back.curves["f2"](z), fits["parametric"].curves["f2"](z))


@pytest.mark.parametrize("change,words", [
    (lambda doc: doc["posterior"].update(rank=99), "the arrays of curve 'f1' do not fit together"),
    (lambda doc: doc["posterior"].pop("kind"), "'kind' is missing"),
    (lambda doc: doc["posterior"].update(form="samples"), "is not a gaussian-grid posterior"),
    (lambda doc: doc["posterior"].update(scalar_mean=[1.0]), "the scalars' arrays do not fit together"),
], ids=["rank", "kind", "form", "scalars"])
def test_a_damaged_saved_posterior_is_one_model_file_error(saved, tmp_path, change, words):
    import shutil

    root, _ = saved
    d = tmp_path / "bad"
    shutil.copytree(root / "parametric", d)
    _rewrite(d, change)
    with pytest.raises(ModelFileError) as info:
        cc.load_model(d)
    message = str(info.value)
    assert words in message and "the saved posterior is damaged" in message and "re-fit the model" in message
    assert "\n" not in message


def test_the_report_of_a_model_folder_shows_bands_and_scalars(saved, tmp_path):
    from charcurves.report import write_fit_report

    root, fits = saved
    page = (tmp_path / "r.html")
    write_fit_report(root / "parametric", page)
    text = page.read_text(encoding="utf-8")
    assert "uncertainty bands filled" in text
    assert scalar_lines(fits["parametric"])[0].strip().replace("'", "&#x27;") in text
    assert str(fits["parametric"].to_sympy(uncertainty=True)).split(" + ")[1] in text  # a constant with its ±


def test_a_network_posterior_is_saved_and_reloaded(tmp_path):
    """nn-cc's Laplace posterior (members' factors and spread, one shared u) goes through the file:
    the reloaded band equals the fitted one inside the training range, the gauge point keeps its zero
    width, and the file says which posterior it was."""
    rec = cc.corrupt(get_system("duffing").simulate(t_end=20.0, n_points=400), 20, seed=0)
    model = cc.fit(rec, method="nn-cc", random_state=0, threads=1)
    model.save(tmp_path / "m")
    loaded = cc.load_model(tmp_path / "m")
    lo_d, hi_d = model.curves["f1"].domain
    z = np.linspace(lo_d, hi_d, 9)[1:-1]
    _, lo, hi = model.curve_band("f1", z)
    _, lo2, hi2 = loaded.curve_band("f1", z)
    width = float(np.max(hi - lo))
    assert width > 0
    assert np.max(np.abs(lo2 - lo)) < 1e-5 * width and np.max(np.abs(hi2 - hi)) < 1e-5 * width
    _, lo0, hi0 = loaded.curve_band("f2", np.array([0.0]))
    assert abs(hi0[0] - lo0[0]) < 1e-9  # f2(0) = 0 is the gauge
    assert uncertainty_summary(loaded)["method"] == "laplace (gauss-newton, evidence decays)"
    grid = {"f1": z}
    assert loaded.posterior.simultaneous_factor(grid) == pytest.approx(model.posterior.simultaneous_factor(grid), rel=0.02)
    outside = np.array([lo_d - 0.3, hi_d + 0.3])  # past the stored range: infinite band around the curve itself
    centre, lo_out, hi_out = loaded.curve_band("f1", outside)
    assert np.array_equal(centre, loaded.curves["f1"](outside)) and np.all(np.isinf(lo_out)) and np.all(np.isinf(hi_out))
