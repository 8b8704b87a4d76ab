"""The posterior of least-squares fits: covariance against a direct computation, gauge, gain, HAC on
correlated residuals, stale and ill-conditioned posteriors, result.json, summary.txt and --bands."""

import json

import numpy as np
import pytest

import charcurves as cc
from charcurves._errors import ConfigError
from charcurves.cli import main
from charcurves.fitting import hac_bandwidth, posterior_bands, scalar_lines, uncertainty_summary
from charcurves.systems import get_system

BASIS = "f1=z; f2=z, z**3"


@pytest.fixture(scope="module")
def record():
    return cc.corrupt(get_system("duffing").simulate(), 20, seed=0)


def test_gauss_covariance_is_the_least_squares_formula(record):
    """Parametric on the Duffing basis: x'' - F = -(d v + a x + b x^3 + c), so the f2 band at z is
    [z, z^3] s^2 (X^T X)^-1 [z, z^3]^T with X = [v, x, x^3, 1] and s^2 = RSS / (N - 4)."""
    model = cc.fit(record, method="parametric", basis=BASIS)
    post = model.posterior.with_kind("gauss")
    X = np.column_stack([record.v, record.x, record.x**3, np.ones(record.n_samples)])
    y = record.F - record.a
    coef, *_ = np.linalg.lstsq(X, y, rcond=None)
    s2 = np.sum((y - X @ coef) ** 2) / (record.n_samples - 4)
    cov = s2 * np.linalg.inv(X.T @ X)
    z = np.array([-1.2, 0.5, 1.3])
    value, sd = post.curve_sd("f2", z)
    basis = np.column_stack([z, z**3])
    assert np.allclose(value, basis @ coef[1:3], rtol=1e-9)
    assert np.allclose(sd, np.sqrt(np.einsum("ij,jk,ik->i", basis, cov[1:3, 1:3], basis)), rtol=1e-6)
    stats = post.scalar_stats()
    assert stats["names"] == ["offset"]
    assert stats["mean"]["offset"] == pytest.approx(coef[3], rel=1e-9)
    assert stats["sd"]["offset"] == pytest.approx(np.sqrt(cov[3, 3]), rel=1e-6)


def test_band_centre_is_the_fitted_curve_and_the_anchor_has_no_width(record):
    model = cc.fit(record, method="poly-cc")
    for name, curve in model.curves.items():
        z = np.linspace(curve.domain[0], curve.domain[1], 7)
        value, lo, hi = model.curve_band(name, z, level=0.9)
        assert np.allclose(value, curve(z), rtol=1e-9, atol=1e-12)
        assert np.all(hi > value) and np.allclose(hi - value, value - lo)
    value, lo, hi = model.curve_band("f2", np.array([0.0]))  # the gauge f2(0) = 0 is exact
    assert value[0] == 0.0 and hi[0] - lo[0] < 1e-12
    _, lo1, hi1 = model.curve_band("f1", np.array([0.0]))  # f1 carries the constant: it has a width
    assert hi1[0] - lo1[0] > 1e-3


def test_free_gain_interval_holds_the_true_gain_and_gives_the_mass(record):
    model = cc.fit(record, method="parametric", basis=BASIS, free_gain=True)
    stats = model.posterior.scalar_stats()
    g, sd = stats["mean"]["gain"], stats["sd"]["gain"]
    assert g == pytest.approx(model.gain, rel=1e-12)
    assert 1e-4 < sd < 0.02 and abs(g - 1.0) < 2.5 * sd
    line = scalar_lines(model)[0]
    assert line.startswith(f"  gain g = {g:.4g}") and "1/g = " in line
    assert f"1/g = {1 / g:.4g}" in line


def test_hac_widens_the_band_where_estimated_derivatives_correlate_the_residual():
    rec = cc.corrupt(get_system("duffing").simulate(), 40, on="state", seed=1)
    model = cc.CharacteristicCurves.from_method(method="poly-cc", objective="equation-error").fit(rec).model_
    post = model.posterior
    assert post.kind == "hac" and post.bandwidth > 10
    z = np.linspace(*model.curves["f2"].domain, 9)
    _, sd_hac = post.curve_sd("f2", z)
    _, sd_iid = post.with_kind("gauss").curve_sd("f2", z)
    assert np.median(sd_hac / np.where(sd_iid > 0, sd_iid, np.inf)) > 2.0


def test_hac_bandwidth_follows_the_residual_correlation():
    rng = np.random.default_rng(0)
    white = rng.normal(size=3000)
    assert hac_bandwidth(white) <= 3
    ar = np.zeros(3000)
    for t in range(1, 3000):
        ar[t] = 0.9 * ar[t - 1] + white[t]
    rho = 0.9
    alpha = 4 * rho**2 / ((1 - rho) ** 2 * (1 + rho) ** 2)
    assert abs(hac_bandwidth(ar) - 1.1447 * (alpha * 3000) ** (1 / 3)) < 6


def test_bartlett_sum_equals_the_sum_over_lags():
    from charcurves.train._posterior_linear import bartlett_sum

    rng = np.random.default_rng(3)
    u = rng.normal(size=(300, 4)).cumsum(axis=0) * 0.1 + rng.normal(size=(300, 4))
    for L in (0, 1, 17, 150):
        S = u.T @ u
        for lag in range(1, L + 1):
            G = u[lag:].T @ u[:-lag]
            S += (1 - lag / (L + 1)) * (G + G.T)
        assert np.allclose(bartlett_sum(u, L), S, rtol=1e-10, atol=1e-9)


def test_a_posterior_whose_curves_changed_is_not_used(record):
    model = cc.fit(record, method="poly-cc")
    model.curves["f2"].shift += 0.5
    assert posterior_bands(model) == {} and uncertainty_summary(model) is None
    with pytest.raises(ConfigError, match="has no posterior"):
        model.curve_band("f2", [0.0])


def test_bad_band_level_and_curve_name_are_refused(record):
    model = cc.fit(record, method="poly-cc")
    with pytest.raises(ConfigError, match="band level must be between 0 and 1"):
        model.curve_band("f2", [0.0], level=1.5)
    with pytest.raises(ConfigError, match="unknown curve 'f3'; the model has f1, f2"):
        model.curve_band("f3", [0.0])


def test_an_ill_conditioned_design_warns_naming_the_columns_and_keeps_the_curve_band(record):
    # z and z + 1e-9 z^3 are nearly the same column: their coefficients are barely determined, the
    # curve they make (the same as z, z^3 up to the scale of the second coefficient) is not
    model = cc.fit(record, method="parametric", basis="f1=z; f2=z, z + 1e-9*z**3")
    warned = [w for w in model.info["warnings"] if w.startswith("uncertainty:")]
    assert len(warned) == 1
    assert "barely determines a combination of coefficient 0 of f2, coefficient 1 of f2" in warned[0]
    assert model.posterior.condition_number > 1e8
    assert uncertainty_summary(model)["warnings"] == warned
    z = np.array([0.7, 1.0, 1.4])
    _, sd = model.posterior.curve_sd("f2", z)
    _, sd_good = cc.fit(record, method="parametric", basis=BASIS).posterior.curve_sd("f2", z)
    assert np.allclose(sd, sd_good, rtol=0.02)
    assert not [w for w in cc.fit(record, method="parametric", basis=BASIS).info.get("warnings", [])
                if w.startswith("uncertainty:")]


def test_a_singular_design_warns_and_bands_what_it_determines(record):
    # z and 2 z: their split is not determined at all, the curve they make is
    model = cc.fit(record, method="parametric", basis="f1=z; f2=z, 2*z, z**3")
    assert model.posterior.unidentified.shape == (1, 5)
    warned = [w for w in model.info["warnings"] if w.startswith("uncertainty:")]
    assert len(warned) == 1
    assert "does not determine a combination of coefficient 0 of f2, coefficient 1 of f2" in warned[0]
    z = np.array([0.5, 1.0])
    _, sd = model.posterior.curve_sd("f2", z)
    _, sd_good = cc.fit(record, method="parametric", basis=BASIS).posterior.curve_sd("f2", z)
    assert np.allclose(sd, sd_good, rtol=1e-6)


def test_result_json_and_summary_carry_the_posterior(tmp_path, record):
    csv = tmp_path / "rec.csv"
    record.to_csv(csv)
    out = tmp_path / "fit"
    assert main(["fit", str(csv), "--method", "parametric", "--basis", BASIS, "--free-gain", "--out", str(out),
                 "--no-figure", "--quiet", "--bands"]) == 0
    result = json.loads((out / "result.json").read_text())
    unc = result["uncertainty"]
    assert unc["covariance"] == "hac" and sorted(unc["scalars"]) == ["gain", "offset"]
    assert unc["scalars"]["gain"]["mean"] == pytest.approx(result["gain"], rel=1e-12)
    assert unc["correlation"]["names"] == ["gain", "offset"]
    assert unc["correlation"]["matrix"][0][0] == pytest.approx(1.0)
    band = result["bands"]["f2"]
    assert band["kind"] == "posterior (hac)" and len(band["z"]) == 200
    assert np.all(np.asarray(band["hi"]) > np.asarray(band["lo"]))
    summary = (out / "summary.txt").read_text()
    sd = unc["scalars"]["gain"]["sd"]
    assert f"gain g = {unc['scalars']['gain']['mean']:.4g}" in summary and f"± {sd:.2g}" in summary


def test_bands_without_a_posterior_warn_and_name_the_bootstrap(record):
    from charcurves.cli._bands import attach_posterior_bands

    model = cc.fit(record, method="poly-cc")
    model.curves["f1"].shift += 0.1  # as after an output-error refinement: the posterior is not this model's
    attach_posterior_bands(model, 0.95, quiet=True)
    assert getattr(model, "bands", None) is None
    result = model.result_dict()
    assert "bands" not in result and "uncertainty" not in result
    assert [w for w in model.info["warnings"] if "has no posterior" in w] == [
        "bands: this poly-cc fit has no posterior (today poly-cc, parametric, sindy-cc, nn-cc and "
        "nn-cc+sym fits have one, by equation or output error, and post-SR closed forms); use --bands N for "
        "N bootstrap refits"]


def test_a_sparse_fit_has_the_posterior_of_its_active_terms(record):
    """sindy (STLSQ, free gain): the band is the least-squares one on the chosen columns."""
    model = cc.fit(record, method="sindy")
    active = model.info["active_terms"]
    post = model.posterior.with_kind("gauss")
    cols = {"x": record.x, "v": record.v}
    X = np.column_stack([cols[t.split("^")[0]] ** (int(t.split("^")[1]) if "^" in t else 1) for t in active]
                        + [-record.F])
    y = -record.a
    coef, *_ = np.linalg.lstsq(X, y, rcond=None)
    s2 = np.sum((y - X @ coef) ** 2) / (len(y) - X.shape[1])
    cov = s2 * np.linalg.inv(X.T @ X)
    stats = post.scalar_stats()
    assert stats["mean"]["gain"] == pytest.approx(model.gain, rel=1e-12)
    assert stats["sd"]["gain"] == pytest.approx(np.sqrt(cov[-1, -1]), rel=1e-6)


def test_the_coverage_table_of_the_docs_is_the_one_the_committed_results_give():
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_coverage.py"
    spec = importlib.util.spec_from_file_location("bench_coverage", path)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    assert bench.render(check=True), "run `python benchmarks/bench_coverage.py --render` and commit the page"


@pytest.mark.parametrize("value", ["2", "poster", "8.5"])
def test_a_bad_bands_value_is_one_line_naming_both_forms(tmp_path, record, capsys, value):
    csv = tmp_path / "rec.csv"
    record.to_csv(csv)
    assert main(["fit", str(csv), "--out", str(tmp_path / "o"), "--bands", value]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "argument --bands: must be 'posterior' (the fit's own bands) or an integer from 3 to 1000" in err
    assert not (tmp_path / "o").exists()


def test_the_figure_labels_a_posterior_band(record):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    from charcurves.fitting import plot_curves
    from charcurves.selection import attach_bands

    model = cc.fit(record, method="poly-cc")
    attach_bands(model, posterior_bands(model, level=0.9))
    fig = plot_curves(model)
    for ax in fig.axes:
        fills = [c for c in ax.collections if isinstance(c, PolyCollection)]
        assert [f.get_label() for f in fills] == ["90% band (posterior (hac))"]
    plt.close(fig)

