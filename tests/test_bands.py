"""Uncertainty bands: ensembles, band arithmetic, coverage of the true curves, result.json and figure."""

import json

import numpy as np
import pytest

from charcurves._errors import ConfigError
from charcurves.cli import main
from charcurves.data import corrupt
from charcurves.fitting import CharacteristicCurves, residual_block
from charcurves.selection import (Ensemble, attach_bands, band_coverage, bootstrap_records, curve_bands,
                                  fit_ensemble)
from charcurves.systems import get_system


class _Curve:
    def __init__(self, fn, domain):
        self.fn, self.domain, self.argument = fn, domain, "x"

    def __call__(self, z):
        return self.fn(np.asarray(z, dtype=float))


class _Model:
    def __init__(self, curves):
        self.curves = curves


def test_band_is_point_plus_minus_normal_quantile_times_member_spread():
    point = _Model({"f2": _Curve(lambda z: z**3, (-1.0, 2.0))})
    offsets = np.array([-0.3, -0.1, 0.0, 0.1, 0.3])
    members = [_Model({"f2": _Curve(lambda z, o=o: z**3 + o, (-1.0, 2.0))}) for o in offsets]
    bands = curve_bands(Ensemble(point, members, None, "seeds"), level=0.95, n_grid=31)
    b = bands["f2"]
    z = np.asarray(b["z"])
    assert z[0] == -1.0 and z[-1] == 2.0 and len(z) == 31
    sd = offsets.std(ddof=1)
    assert np.allclose(b["sd"], sd)
    assert np.allclose(np.asarray(b["hi"]) - z**3, 1.959964 * sd, rtol=1e-6)
    assert np.allclose(z**3 - np.asarray(b["lo"]), 1.959964 * sd, rtol=1e-6)
    assert (b["level"], b["members"], b["kind"], b["argument"]) == (0.95, 5, "seeds", "x")
    cov = band_coverage(bands, {"f2": lambda z: np.asarray(z) ** 3 + 0.5 * sd})
    assert cov["f2"] == 1.0
    assert band_coverage(bands, {"f2": lambda z: np.asarray(z) ** 3 + 3 * sd})["f2"] == 0.0


@pytest.mark.parametrize("kwargs, message", [
    ({"level": 1.5}, "band level must be between 0 and 1"),
    ({"level": 0.0}, "band level must be between 0 and 1"),
])
def test_bad_band_level_is_refused(kwargs, message):
    point = _Model({"f1": _Curve(lambda z: z, (-1.0, 1.0))})
    with pytest.raises(ConfigError, match=message):
        curve_bands(Ensemble(point, [point] * 3, None, "seeds"), **kwargs)


def test_bootstrap_keeps_the_state_and_flips_residual_signs():
    system = get_system("duffing")
    rec = corrupt(system.simulate(), 20, seed=0)
    model = CharacteristicCurves.from_method(method="poly-cc").fit(rec).model_
    boots = bootstrap_records(rec, model, 3, random_state=1)
    resid = model.force_residual(rec)
    f_hat = rec.F + resid
    for b in boots:
        assert np.array_equal(b.x, rec.x) and np.array_equal(b.a, rec.a)
        # each sample's residual is kept in size, only its sign is drawn
        assert np.allclose(np.abs(b.F - f_hat), np.abs(resid))
    flips = np.mean(np.sign(boots[0].F - f_hat) != np.sign(rec.F - f_hat))
    assert 0.4 < flips < 0.6


def test_residual_block_is_one_for_white_noise_and_the_correlation_length_otherwise():
    rng = np.random.default_rng(0)
    white = rng.standard_normal(2000)
    assert residual_block(white) == 1
    # a moving average of 12 samples: correlation 1 - k/12 at lag k, inside 2/sqrt(n) = 0.045 from lag 12
    smooth = np.convolve(rng.standard_normal(2011), np.ones(12), mode="valid")
    assert 10 <= residual_block(smooth) <= 12
    assert residual_block(np.cumsum(white)) == 100  # a random walk: capped at n // 20 (20 blocks)
    # several equations: the longest column's length
    assert residual_block(np.column_stack([white, smooth[:2000]])) == residual_block(smooth[:2000])
    assert residual_block(white[:30]) == 1  # too short to estimate


def test_bootstrap_flips_one_sign_per_block():
    rec = corrupt(get_system("duffing").simulate(), 20, seed=0)
    model = CharacteristicCurves.from_method(method="poly-cc").fit(rec).model_
    resid = model.force_residual(rec)
    f_hat = rec.F + resid
    [b] = bootstrap_records(rec, model, 1, random_state=3, block=25)
    signs = np.sign(f_hat - b.F) * np.sign(resid)
    blocks = signs.reshape(-1, 25)  # 1000 samples: 40 blocks
    assert np.all(blocks == blocks[:, :1]) and 10 < np.sum(blocks[:, 0] > 0) < 30
    # white residual (noise on F): the default block is one sample, the copies the sign-per-sample ones
    auto = bootstrap_records(rec, model, 2, random_state=1)
    per_sample = bootstrap_records(rec, model, 2, random_state=1, block=1)
    assert all(np.array_equal(a.F, p.F) for a, p in zip(auto, per_sample))
    with pytest.raises(ConfigError, match="block must be a positive number of samples, got 0"):
        bootstrap_records(rec, model, 1, block=0)


def test_ensemble_size_is_checked():
    rec = get_system("duffing").simulate()
    with pytest.raises(ConfigError, match="at least 3 members"):
        fit_ensemble(CharacteristicCurves.from_method(method="poly-cc"), rec, 2)
    with pytest.raises(ConfigError, match="unknown ensemble kind 'jackknife'"):
        fit_ensemble(CharacteristicCurves.from_method(method="poly-cc"), rec, 4, kind="jackknife")


def test_poly_cc_bootstrap_bands_cover_the_duffing_curves():
    system = get_system("duffing")
    rec = corrupt(system.simulate(), 20, seed=0)
    ens = fit_ensemble(CharacteristicCurves.from_method(method="poly-cc"), rec, 8)
    cov = band_coverage(curve_bands(ens, level=0.95), system.true_curves())
    # measured: 1.0 and 0.945 (seed 0); 0.98-1.0 over seeds 1, 2
    assert cov["f1"] >= 0.9 and cov["f2"] >= 0.9
    # the seeds ensemble of a least-squares fit has no spread: bands collapse on the point fit
    flat = curve_bands(fit_ensemble(CharacteristicCurves.from_method(method="poly-cc"), rec, 3, kind="seeds"))
    assert max(flat["f2"]["sd"]) < 1e-9


def test_poly_cc_bootstrap_bands_of_a_two_dof_record():
    from charcurves.systems import corrupt_forces

    system = get_system("two-dof")
    rec = corrupt_forces(system.simulate(t_end=50.0, n_points=1000), 25, seed=0)
    ens = fit_ensemble(CharacteristicCurves.from_method(family="two-dof", method="poly-cc"), rec, 8)
    assert ens.kind == "bootstrap"
    bands = curve_bands(ens, level=0.95)
    assert all(min(bands[k]["sd"]) > 0 for k in ("f1", "f2", "f3", "f4"))
    cov = band_coverage(bands, system.true_curves())
    # measured (seeds 0, 1, 2): 0.89-1.0, 0.72-0.98, 0.80-1.0; nominal 0.95 with 8 members
    assert all(cov[k] >= 0.6 for k in cov), cov
    assert np.mean(list(cov.values())) >= 0.8, cov


def test_cli_fit_bands_writes_result_json_and_draws_them(tmp_path, capsys):
    import matplotlib

    matplotlib.use("Agg")
    system = get_system("duffing")
    path = tmp_path / "d.csv"
    corrupt(system.simulate(), 20, seed=0).to_csv(path)
    out = tmp_path / "fit"
    assert main(["fit", str(path), "--method", "poly-cc", "--bands", "4", "--bands-level", "0.9",
                 "--out", str(out), "--quiet"]) == 0
    doc = json.loads((out / "result.json").read_text())
    for name in ("f1", "f2"):
        b = doc["bands"][name]
        assert b["level"] == 0.9 and b["members"] == 4 and b["kind"] == "bootstrap"
        lo, hi, center = (np.asarray(b[k]) for k in ("lo", "hi", "center"))
        assert len(b["z"]) == 200 and np.all(lo <= center) and np.all(center <= hi)
        assert np.all(hi - lo > 0)
        # the band's centre is the saved curve
        grid = np.asarray(doc["curves"][name]["grid"])
        assert np.interp(b["z"][100], grid, doc["curves"][name]["values"]) == pytest.approx(center[100], abs=1e-3)
    assert (out / "curves.png").stat().st_size > 0


def test_plot_curves_draws_the_model_bands():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    from charcurves.report import plot_curves

    rec = corrupt(get_system("duffing").simulate(), 20, seed=0)
    ens = fit_ensemble(CharacteristicCurves.from_method(method="poly-cc"), rec, 4)
    attach_bands(ens.point, curve_bands(ens, level=0.9))
    fig = plot_curves(ens.point)
    for ax in fig.axes:
        fills = [c for c in ax.collections if isinstance(c, PolyCollection)]
        assert len(fills) == 1 and fills[0].get_label() == "90% band (4 bootstrap)"
    plt.close(fig)


@pytest.mark.parametrize("args, message", [
    (["--bands", "2"], "argument --bands: must be 'posterior' (the fit's own bands) or an integer from 3 to 1000 (each member"),
    (["--bands", "4", "--bands-level", "95"], "argument --bands-level: must be a number from 1e-06 to 0.999999"),
])
def test_cli_bad_bands_options_exit_2_before_fitting(tmp_path, capsys, args, message):
    path = tmp_path / "d.csv"
    get_system("duffing").simulate(n_points=200).to_csv(path)
    assert main(["fit", str(path), "--out", str(tmp_path / "o"), "--method", "poly-cc", *args]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_nn_cc_bootstrap_bands_cover_the_duffing_curves_on_average():
    # The bootstrap captures the noise, not a network's bias (docs/selection.md): on one record a curve whose
    # systematic error exceeds the members' spread is under-covered. Measured (noise seeds 0-3, f1 / f2):
    # 0.72 / 1.00, 0.975 / 1.00, 1.00 / 0.65, 1.00 / 1.00, means 0.92 / 0.91; a one-sigma band (level 0.6827)
    # of the same records' ensembles fitted together (fit_ensembles) covers 0.70 / 0.37 on average (0.93 / 1.00
    # at 0.95), so the bound below fails a band of the wrong width.
    system = get_system("duffing")
    clean, truth = system.simulate(), system.true_curves()
    covers = [band_coverage(curve_bands(fit_ensemble(CharacteristicCurves.from_method(method="nn-cc"),
                                                     corrupt(clean, 20, seed=seed), 8), level=0.95), truth)
              for seed in range(4)]
    assert np.mean([c["f1"] for c in covers]) >= 0.85 and np.mean([c["f2"] for c in covers]) >= 0.85
