"""Fitting: Parametric, NN-CC, NN-CC+sym, free gain, gauge, batching, presets, persistence."""

import json

import numpy as np
import pytest

import charcurves as cc
from charcurves import ConfigError, DataError, ModelFileError
from charcurves.data import corrupt
from charcurves.fitting import PRESETS, CharacteristicCurves, load_model
from charcurves.metrics import curve_errors, curve_rmse
from charcurves.systems import get_system


def test_parametric_recovers_duffing_coefficients_exactly_on_clean_data(duffing):
    system, clean = duffing
    model = cc.fit(clean, method="parametric", basis="f1=z; f2=z, z**3")
    assert model.curves["f1"].coefficients == pytest.approx([0.3], abs=1e-9)
    assert model.curves["f2"].coefficients == pytest.approx([-1.0, 1.0], abs=1e-9)
    errs = curve_errors(model, system.true_curves())
    assert errs["f1"] < 1e-9 and errs["f2"] < 1e-9
    expr = model.curves["f2"].expression()
    import sympy as sp

    z = sp.Symbol("z")
    assert float(expr.coeff(z, 3)) == pytest.approx(1.0, abs=1e-9)
    eq = model.to_sympy()
    assert "Derivative" in str(eq.lhs)
    assert "x" in model.to_latex()


def test_parametric_at_20db_is_at_the_statistical_limit(duffing):
    system, clean = duffing
    errs = np.array([list(curve_errors(cc.fit(corrupt(clean, 20, seed=s), method="parametric", basis="f1=z; f2=z, z**3"),
                                       system.true_curves()).values()) for s in range(5)])
    mean = errs.mean(axis=0)
    # the paper's Table 2 implies ~1.1e-3 / 1.6e-3; the issue asks <= 2e-3
    assert mean[0] <= 2e-3 and mean[1] <= 2e-3, mean


def test_nn_cc_sym_single_seed_accuracy_and_gauge(duffing, duffing_20db):
    system, _ = duffing
    model = cc.fit(duffing_20db, method="nn-cc+sym", random_state=0, threads=1)
    errs = curve_errors(model, system.true_curves())
    # seed 0 is the hardest of the five noise seeds for f2 (see the slow test for the mean)
    assert errs["f1"] < 4e-3 and errs["f2"] < 7e-3, errs
    # exact odd curves: pinned at 0, the constant lives in the equation's offset
    for c in model.curves.values():
        assert float(c(np.array([0.0]))[0]) == 0.0
        z = c.grid(50)
        assert np.allclose(c(z), -c(-z), atol=1e-12)
    assert abs(model.offset) < 0.01
    # the data loss is at the noise floor (sigma_n^2 = 0.01 * var(F) = 1.25e-3), within 20 %
    noise_floor = 0.01 * float(np.var(duffing_20db.F))
    assert abs(model.loss / noise_floor - 1.0) < 0.2


def test_nn_cc_without_symmetry_applies_the_f2_gauge(duffing, duffing_20db):
    system, _ = duffing
    model = cc.fit(duffing_20db, method="nn-cc", random_state=0, threads=1)
    assert float(model.curves["f2"](np.array([0.0]))[0]) == pytest.approx(0.0, abs=1e-12)
    assert model.offset == 0.0
    errs = curve_errors(model, system.true_curves())
    assert errs["f1"] < 1e-2 and errs["f2"] < 1e-2, errs
    # the f1(0) = 0 gauge moves the constant to f2 and leaves the sum unchanged
    other = cc.fit(duffing_20db, method="nn-cc", random_state=0, threads=1, gauge="f1")
    assert float(other.curves["f1"](np.array([0.0]))[0]) == pytest.approx(0.0, abs=1e-12)
    v, x = np.linspace(-0.5, 0.5, 7), np.linspace(-1, 1, 7)
    s1 = model.curves["f1"](v) + model.curves["f2"](x)
    s2 = other.curves["f1"](v) + other.curves["f2"](x)
    assert np.allclose(s1, s2, atol=1e-12)


def test_free_gain_recovers_a_scaled_forcing(duffing):
    system, clean = duffing
    noisy = corrupt(clean, 20, seed=1)
    scaled = noisy.replace(F=noisy.F / 2.5)
    model = cc.fit(scaled, method="nn-cc+sym", free_gain=True, random_state=1, threads=1)
    assert model.gain == pytest.approx(2.5, rel=0.02)
    known = cc.fit(noisy, method="nn-cc+sym", random_state=1, threads=1)
    e_free = curve_errors(model, system.true_curves())
    e_known = curve_errors(known, system.true_curves())
    for k in ("f1", "f2"):
        assert e_free[k] < 1.5 * e_known[k] + 1e-3, (e_free, e_known)
    par = cc.fit(scaled, method="parametric", basis="f1=z; f2=z, z**3", free_gain=True)
    assert par.gain == pytest.approx(2.5, rel=0.01)


def test_offsets_of_real_records_are_kept_when_curves_are_odd(duffing):
    system, clean = duffing
    biased = corrupt(clean, 30, seed=2)
    biased = biased.replace(F=biased.F + 0.2)  # a force-sensor bias
    model = cc.fit(biased, method="nn-cc+sym", random_state=0, threads=1)
    # x'' + f1 + f2 + b = F_measured with F_measured = F + 0.2, so b = +0.2
    assert model.offset == pytest.approx(0.2, abs=0.01)
    errs = curve_errors(model, system.true_curves())
    assert errs["f1"] < 5e-3 and errs["f2"] < 5e-3, errs


def test_batched_fits_equal_separate_fits(duffing):
    _, clean = duffing
    trajs = [corrupt(clean, 20, seed=s) for s in (3, 4)]
    preset = PRESETS["default"].replace(n_starts=2, adam_steps=50, lm_max_iter=20)
    est = CharacteristicCurves.from_method(method="nn-cc+sym", preset=preset, threads=1)
    batch = est.fit_many(trajs, seeds=[11, 12])
    single = [est.fit_many([tr], seeds=[s])[0] for tr, s in zip(trajs, (11, 12))]
    z = np.linspace(-0.9, 0.9, 33)
    for b, s in zip(batch, single):
        for name in ("f1", "f2"):
            # batched matmuls of other shapes round differently; LM carries that to ~1e-8
            assert np.allclose(b.curves[name](z), s.curves[name](z), rtol=1e-6, atol=1e-8)


def test_fit_is_deterministic_for_a_seed(duffing_20db):
    preset = PRESETS["default"].replace(n_starts=2, adam_steps=50, lm_max_iter=10)
    a = cc.fit(duffing_20db, method="nn-cc", preset=preset, random_state=5, threads=1)
    b = cc.fit(duffing_20db, method="nn-cc", preset=preset, random_state=5, threads=1)
    c = cc.fit(duffing_20db, method="nn-cc", preset=preset, random_state=6, threads=1)
    z = np.linspace(-1, 1, 21)
    assert np.array_equal(a.curves["f2"](z), b.curves["f2"](z))
    assert not np.array_equal(a.curves["f2"](z), c.curves["f2"](z))


def test_paper_preset_is_the_papers_protocol():
    p = PRESETS["paper"]
    assert p.hidden == (100, 100, 100) and p.activation == "relu"
    assert p.adam_lr == 1e-4 and p.adam_steps == 20000 and p.lm_max_iter == 0
    assert p.symmetry_mode == "penalty" and p.lambda_sym == 10 and p.n_sym == 1000
    assert not p.scale_inputs and not p.linear_term and p.n_starts == 1 and p.combine == "best"
    assert p.stop_loss == 1e-7


def test_paper_preset_short_run_uses_the_penalty(duffing_20db):
    preset = PRESETS["paper"].replace(adam_steps=100)  # the layout and the gauge, not the accuracy, are checked
    model = cc.fit(duffing_20db, method="nn-cc+sym", preset=preset, random_state=0, threads=1)
    f1 = model.curves["f1"]
    assert f1.spec.symmetry_mode == "penalty" and not f1.pinned_at_zero
    assert model.info["adam_steps"] == 100
    # post-hoc gauge: f2(0) = 0 exactly, and no separate constant
    assert float(model.curves["f2"](np.array([0.0]))[0]) == pytest.approx(0.0, abs=1e-6)
    assert model.offset == 0.0
    assert np.isfinite(model.loss)
    # 100-100-100 networks are past the dense Laplace approximation's size: no posterior, and it says why
    assert model.info["posterior"].startswith("skipped: ") and "use --bands N" in model.info["posterior"]
    assert model.posterior is None


def test_stick_slip_jump_curve_with_sticking_samples_excluded():
    from charcurves.systems import get_system

    system = get_system("stick-slip")
    clean = system.simulate()
    noisy = corrupt(clean, 20, seed=0)
    model = cc.fit(noisy, method="nn-cc+sym", random_state=0, threads=1)  # jump="auto"
    assert model.info["n_sticking_samples"] > 100
    assert model.curves["f1"].spec.jump and not model.curves["f2"].spec.jump
    comps = model.curves["f1"].components()
    assert comps["jump_height"] == pytest.approx(0.801, rel=0.05)
    errs = curve_errors(model, system.true_curves())
    assert errs["f1"] < 3e-2 and errs["f2"] < 1e-2, errs


def test_jump_width_is_profiled_to_the_step_the_slipping_samples_call_for():
    # seed 3 once kept a gradient-trained width of 1.8e-4 (an error of 0.46 at the grid point
    # next to 0, f1 RMSE 1.8e-2) although slipping samples at |x'| ~ 1e-4 call for a step
    from charcurves.systems import get_system

    system = get_system("stick-slip")
    noisy = corrupt(system.simulate(), 20, seed=3)
    model = cc.fit(noisy, method="nn-cc+sym", random_state=3, threads=1)
    assert model.curves["f1"].components()["jump_width"] < 1e-5
    z = np.array([-1e-4, 1e-4])
    assert np.abs(model.curves["f1"](z) - system.true_curves()["f1"](z)).max() < 0.05
    assert curve_errors(model, system.true_curves())["f1"] < 1.3e-2


def test_jump_layout_is_decided_per_record_in_a_batch(duffing):
    # the benchmark's Duffing record (29 dB, realisation 3) passes the dry-friction test by chance
    # (the only one of the 610 of the full grid); a record in the same batch must not get a jump
    # because of it, and no fit may end with NaN curves (a GPU batch of all 610 once did)
    from charcurves.experiments import Sweep

    system, clean = duffing
    job = [j for j in Sweep(systems=("duffing",), methods=("nn-cc+sym",), snr_db=(29.0,), realizations=(3,)).jobs()][0]
    recs = [corrupt(clean, 30, seed=1), corrupt(clean, job.snr_db, seed=job.noise_seed)]
    models = CharacteristicCurves.from_method(method="nn-cc+sym", threads=1).fit_many(recs, seeds=[1, 2])
    assert not models[0].curves["f1"].spec.jump and models[1].curves["f1"].spec.jump
    for m in models:
        assert np.isfinite(m.curves["f1"](np.linspace(-1, 1, 11))).all()


def test_decay_groups_shared_per_curve_and_per_layer(duffing, duffing_20db):
    from charcurves.fitting import get_preset

    # the cubic unchecked (check_auto_terms=False): the groups of a model with polynomial terms
    fits = {g: cc.fit(duffing_20db, method="nn-cc+sym", random_state=0, threads=1,
                      preset=get_preset("default").replace(decay_groups=g, check_auto_terms=False))
            for g in ("shared", "per-curve", "per-layer")}
    assert fits["shared"].info["weight_decay_groups"] == ["all networks"]
    assert fits["per-curve"].info["weight_decay_groups"] == ["f1", "f2", "f2 polynomial terms"]
    per = fits["per-curve"].info["weight_decay"]
    # Duffing's curves are linear (damping) and linear + cubic (spring): the linear and polynomial
    # terms carry them and the evidence damps both networks far harder than the cubic term
    assert min(per[0], per[1]) > 1e6 * per[2]
    layer = fits["per-layer"]
    # the cubic term of the default's polynomial part goes to the curve the data find nonlinear only
    assert layer.info["settings"]["polynomial_terms"] == {"f2": [3]}
    assert layer.info["weight_decay_groups"] == [
        f"{c} layer {n} {kind}" for c in ("f1", "f2") for n in (1, 2) for kind in ("weights", "biases")
    ] + ["f2 polynomial terms"]
    d = dict(zip(layer.info["weight_decay_groups"], layer.info["weight_decay"]))
    assert d["f1 layer 2 weights"] > 1e6 * d["f2 polynomial terms"] < 1e-6 * d["f2 layer 2 weights"]
    assert get_preset("default").decay_groups == "per-layer"
    for g, m in fits.items():  # every grouping recovers the curves (20 dB, seed 0)
        errs = curve_errors(m, duffing[0].true_curves())
        assert errs["f1"] < 3e-3 and errs["f2"] < 7e-3, (g, errs)


def test_auto_jump_stays_off_without_sticking_and_in_the_paper_preset(duffing_20db):
    from charcurves.systems import get_system

    model = cc.fit(duffing_20db, method="nn-cc", preset=PRESETS["default"].replace(n_starts=1, lm_max_iter=5),
                   threads=1)
    assert not model.curves["f1"].spec.jump
    stick = corrupt(get_system("stick-slip").simulate(), 20, seed=0)
    paper = cc.fit(stick, method="nn-cc", preset=PRESETS["paper"].replace(adam_steps=5), threads=1)
    assert not paper.curves["f1"].spec.jump
    off = cc.fit(stick, method="nn-cc", jump="none", preset=PRESETS["default"].replace(n_starts=1, lm_max_iter=5),
                 threads=1)
    assert not off.curves["f1"].spec.jump


@pytest.mark.parametrize("variant", ["smooth", "scripts"])
def test_auto_jump_detects_dry_friction_without_sticking(variant):
    from charcurves.fitting import JUMP_F_THRESHOLD, dry_friction_test
    from charcurves.systems import get_system
    from charcurves.templates import get_template

    system = get_system("stick-slip", variant)
    clean = system.simulate()
    assert not system.sticking_mask(clean).any()
    for snr in (40, 0):
        F, mu = dry_friction_test(corrupt(clean, snr, seed=1), get_template("separable"))
        assert F > JUMP_F_THRESHOLD and mu > 0.3
    model = cc.fit(corrupt(clean, 20, seed=0), method="nn-cc+sym", random_state=0, threads=1)
    assert model.curves["f1"].spec.jump
    errs = curve_errors(model, system.true_curves())
    assert errs["f1"] < 1.5e-2 and errs["f2"] < 6e-3, errs


def test_no_jump_is_detected_on_smooth_curves(duffing):
    from charcurves.fitting import JUMP_F_THRESHOLD, dry_friction_test
    from charcurves.templates import get_template

    _, clean = duffing
    for seed in range(5):
        F, _ = dry_friction_test(corrupt(clean, 0, seed=seed), get_template("separable"))
        assert F < JUMP_F_THRESHOLD


def test_save_load_round_trip_gives_identical_predictions(tmp_path, duffing_20db):
    preset = PRESETS["default"].replace(n_starts=2, adam_steps=30, lm_max_iter=5)
    model = cc.fit(duffing_20db, method="nn-cc+sym", jump="f1", preset=preset, threads=1)
    model.save(tmp_path / "m")
    back = load_model(tmp_path / "m")
    z = np.linspace(-1.2, 1.2, 41)
    for name in ("f1", "f2"):
        assert np.array_equal(model.curves[name](z), back.curves[name](z))
    assert back.gain == model.gain and back.offset == model.offset and back.method == model.method
    doc = json.loads((tmp_path / "m" / "model.json").read_text())
    assert doc["format_version"] == 1 and doc["curves"][0]["network"]["jump"] is True
    par = cc.fit(duffing_20db, method="parametric", basis="f1=z; f2=z, z**3")
    par.save(tmp_path / "p")
    back = load_model(tmp_path / "p")
    assert np.array_equal(par.curves["f2"](z), back.curves["f2"](z))
    assert str(back.curves["f2"].expression()) == str(par.curves["f2"].expression())


def test_damaged_model_files_are_refused(tmp_path, duffing_20db):
    model = cc.fit(duffing_20db, method="parametric", basis="f1=z; f2=z, z**3")
    model.save(tmp_path / "m")
    blob = (tmp_path / "m" / "arrays.safetensors").read_bytes()
    (tmp_path / "m" / "arrays.safetensors").write_bytes(blob[:-3] + b"xyz")
    with pytest.raises(ModelFileError, match="checksum"):
        load_model(tmp_path / "m")
    model.save(tmp_path / "m")
    doc = json.loads((tmp_path / "m" / "model.json").read_text())
    doc["format_version"] = 99
    (tmp_path / "m" / "model.json").write_text(json.dumps(doc))
    with pytest.raises(ModelFileError, match="version 99 is not supported"):
        load_model(tmp_path / "m")
    (tmp_path / "m" / "model.json").write_text("{not json")
    with pytest.raises(ModelFileError, match="not valid JSON"):
        load_model(tmp_path / "m")
    with pytest.raises(ModelFileError, match="missing"):
        load_model(tmp_path / "nothing-here")


def test_configuration_errors_name_the_fix(duffing_20db):
    with pytest.raises(ConfigError, match="unknown method 'nn-xx'.*nn-cc"):
        cc.fit(duffing_20db, method="nn-xx")
    with pytest.raises(ConfigError, match="use nn-cc\\+sym"):
        cc.fit(duffing_20db, method="nn-cc", symmetry="f1=odd")
    with pytest.raises(ConfigError, match="unknown symmetry 'oddish'"):
        cc.fit(duffing_20db, method="nn-cc+sym", symmetry="f1=oddish")
    with pytest.raises(ConfigError, match="unknown curve 'f3'"):
        cc.fit(duffing_20db, method="nn-cc+sym", symmetry="f3=odd")
    with pytest.raises(ConfigError, match="unknown preset 'fast'"):
        cc.fit(duffing_20db, method="nn-cc", preset="fast")
    with pytest.raises(ConfigError, match="unknown family 'tri-dof'"):
        cc.fit(duffing_20db, family="tri-dof")
    with pytest.raises(ConfigError, match="--jump names unknown curve"):
        cc.fit(duffing_20db, method="nn-cc+sym", jump="f9")
    with pytest.raises(ConfigError, match="cannot parse basis function"):
        cc.fit(duffing_20db, method="parametric", basis="f1=z**; f2=z")
    with pytest.raises(ConfigError, match="'y' is not allowed"):
        cc.fit(duffing_20db, method="parametric", basis="f1=y; f2=z")
    with pytest.raises(ConfigError, match="not a plain expression"):
        cc.fit(duffing_20db, method="parametric", basis="f1=__import__('os'); f2=z")


def test_data_errors_name_the_fix(duffing_20db):
    one_sided = duffing_20db.replace(x=np.abs(duffing_20db.x) + 0.1)
    with pytest.raises(DataError, match="both sides of 0"):
        cc.fit(one_sided, method="nn-cc+sym")
    still = duffing_20db.replace(x=np.zeros(duffing_20db.n_samples) + 0.3)
    with pytest.raises(DataError, match="constant over the record"):
        cc.fit(still, method="nn-cc")
    short = duffing_20db.slice(slice(0, 10))
    with pytest.raises(DataError, match="at least 30 samples"):
        cc.fit(short, method="nn-cc")
    bare = duffing_20db.replace(v=None, a=None)
    with pytest.raises(DataError, match="--derivatives given needs v and a"):
        cc.fit(bare, method="nn-cc", differentiator="given")


def test_estimated_derivatives_path_runs(duffing):
    system, clean = duffing
    noisy_x = corrupt(clean, 40, on="state", seed=0)
    model = cc.fit(noisy_x, method="parametric", basis="f1=z; f2=z, z**3", differentiator="savgol")
    errs = curve_errors(model, system.true_curves())
    assert errs["f1"] < 0.05 and errs["f2"] < 0.08, errs


def test_curve_rmse_alignment():
    from charcurves.curves import BasisFittedCurve

    c = BasisFittedCurve("f2", "x", (-1, 1), ["z", "z**3"], [1.0, 0.5], shift=0.3)
    truth = lambda z: z + 0.5 * z**3  # noqa: E731
    assert curve_rmse(c, truth) == pytest.approx(0.3)
    assert curve_rmse(c, truth, align="zero") == pytest.approx(0.0, abs=1e-15)
    assert curve_rmse(c, truth, align="mean") == pytest.approx(0.0, abs=1e-15)
    with pytest.raises(ConfigError):
        curve_rmse(c, truth, align="best")


def test_estimator_follows_the_sklearn_contract():
    est = CharacteristicCurves.from_method(method="nn-cc", random_state=3)
    params = est.get_params()
    assert params["method__name"] == "nn-cc" and params["random_state"] == 3
    est.set_params(method__name="parametric", method__basis="f1=z; f2=z, z**3")
    assert est.method_name() == "parametric" and est.method.basis == "f1=z; f2=z, z**3"
    with pytest.raises(ConfigError, match="CharacteristicCurves has no parameter .colour.; valid: template, method, differentiator"):
        est.set_params(colour="red")
    from charcurves import NotFittedError

    with pytest.raises(NotFittedError, match="call fit"):
        est.gain_


@pytest.mark.slow
@pytest.mark.parametrize("method,limits", [("nn-cc", (1e-2, 1e-2)), ("nn-cc+sym", (4e-3, 4e-3)),
                                           ("parametric", (2e-3, 2e-3))])
def test_duffing_20db_five_seed_means(duffing, method, limits):
    system, clean = duffing
    errs = []
    for seed in range(5):
        basis = {"basis": "f1=z; f2=z, z**3"} if method == "parametric" else {}
        model = cc.fit(corrupt(clean, 20, seed=seed), method=method, random_state=seed, threads=1, **basis)
        errs.append([curve_errors(model, system.true_curves())[k] for k in ("f1", "f2")])
    mean = np.mean(errs, axis=0)
    assert mean[0] <= limits[0] and mean[1] <= limits[1], mean


def test_explicit_no_symmetry_with_a_sym_method_is_refused(duffing_20db):
    with pytest.raises(ConfigError, match="imposes a parity prior .* use 'nn-cc' for no prior"):
        cc.fit(duffing_20db, method="nn-cc+sym", symmetry="f1=none,f2=none")


# ---------------------------------------------------------------------- sticking only where the mass sticks
def _smooth_record(f1, f2, *, A, omega, t_end=40.0, n=1000):
    from scipy.integrate import solve_ivp

    from charcurves.data import Trajectory

    def rhs(t, y):
        return [y[1], A * np.cos(omega * t) - f1(np.array([y[1]]))[0] - f2(np.array([y[0]]))[0]]

    t = np.linspace(0, t_end, n)
    x, v = solve_ivp(rhs, (0, t_end), [0.5, -0.5], t_eval=t, rtol=1e-10, atol=1e-12, method="LSODA").y
    F = A * np.cos(omega * t)
    return Trajectory(t=t, x=x, F=F, v=v, a=F - f1(v) - f2(x))


_SMOOTH = {
    "duffing": lambda: get_system("duffing").simulate(),
    "pendulum": lambda: _smooth_record(lambda v: 0.1 * v, lambda x: 3 * np.sin(x), A=1.0, omega=1.2, t_end=60.0,
                                       n=3000),
    "pendulum-slow": lambda: _smooth_record(lambda v: 0.05 * v, lambda x: 2 * np.sin(x), A=0.8, omega=0.9,
                                            t_end=60.0, n=3000),
    "drag": lambda: _smooth_record(lambda v: 0.2 * v + 0.15 * v * np.abs(v), lambda x: 1.5 * np.tanh(2 * x), A=1.0,
                                   omega=1.0),
    "asymmetric": lambda: _smooth_record(lambda v: 0.3 * v, lambda x: 4 * x + 1.5 * x**2, A=1.0, omega=1.5),
}


@pytest.mark.parametrize("name", list(_SMOOTH))
def test_smooth_records_have_no_sticking_samples(name):
    """The former test (|x'| <= 1 % of max over 3 samples), measured on these records with x noise-free
    or at 40, 30, 20 dB (seeds 0-2): up to 3, 6, 15, 0 and 7 false sticking samples per record on
    Duffing, the pendulum, the slow pendulum, drag and the asymmetric spring; now 0. Not yet 0: Duffing
    sampled 3000 times over 60 s at 20 dB on x (76 samples for seed 0), Duffing's scripts variant at
    30 dB (6)."""
    from charcurves.data import estimate_derivatives
    from charcurves.templates import ESTIMATED_STICK_TOL, sticking_mask

    clean = _SMOOTH[name]()
    assert not sticking_mask(clean).any() and not sticking_mask(corrupt(clean, 25, seed=0)).any()
    for snr in (None, 40.0, 30.0):
        for seed in (0, 1):
            noisy = clean if snr is None else corrupt(clean, snr, on="state", seed=seed)
            record = estimate_derivatives(noisy.replace(v=None, a=None), "auto")
            assert int(sticking_mask(record, rel_tol=ESTIMATED_STICK_TOL).sum()) == 0, (name, snr, seed)


def test_true_sticking_is_still_found_with_estimated_derivatives():
    """Stick-slip: 372 sticking samples of 1000. Measured, derivatives estimated from x with 40 / 30 dB
    noise (seed 0): found 350 / 348 (the former 1 % test: 211 / 117), and 35 / 32 samples beside the
    sticks (within 10 samples of one: the differentiator's smoothing; former 8 / 4)."""
    from charcurves.data import estimate_derivatives
    from charcurves.templates import ESTIMATED_STICK_TOL, sticking_mask

    system = get_system("stick-slip")
    clean = system.simulate()
    truth = system.sticking_mask(clean)
    assert np.array_equal(sticking_mask(clean), truth) and int(truth.sum()) == 372
    near = np.convolve(truth, np.ones(21), mode="same") > 0  # within 10 samples of a stick
    for snr, found in ((40.0, 350), (30.0, 348)):
        record = estimate_derivatives(corrupt(clean, snr, on="state", seed=0).replace(v=None, a=None), "auto")
        mask = sticking_mask(record, rel_tol=ESTIMATED_STICK_TOL)
        assert int((mask & truth).sum()) == found
        assert not (mask & ~near).any()


def test_jump_none_leaves_no_sample_out_as_sticking():
    record = get_system("stick-slip").simulate()
    est = CharacteristicCurves.from_method(method="poly-cc", threads=1)
    assert est.fit(record).model_.info["n_sticking_samples"] == 372
    assert CharacteristicCurves.from_method(method="poly-cc", jump="none", threads=1).fit(record).model_.info[
        "n_sticking_samples"] == 0


def test_a_learned_jump_is_never_negative():
    """A jump forced onto Duffing's damping (no friction; 20 s, 500 samples, 25 dB on F) ends at
    2.2e-17, before the bound at -1.14e-3 (friction that feeds energy in). Measured on the full
    record: +1.9e-4 (before -2.6e-4); on drag 0.2v + 0.15v|v| with a tanh spring +0.089 (before
    -0.590); stick-slip's jump unchanged (0.8109 at 20 dB, true mu N 0.801; see the stick-slip
    tests above)."""
    record = corrupt(get_system("duffing").simulate(t_end=20.0, n_points=500), 25, seed=0)
    model = CharacteristicCurves.from_method(method="nn-cc+sym", jump="f1", threads=1).fit(record).model_
    height = model.curves["f1"].components()["jump_height"]
    assert 0.0 <= height < 1e-6
