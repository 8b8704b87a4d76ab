"""The families beyond separable: recovery of known curves at 25 dB, simulation, persistence,
post-SR, multi-DOF records and the CLI (--family two-dof, --equation).

Normalised RMSE = RMSE over the curve's training range / standard deviation of the true curve
there (stricter than dividing by the range)."""

import json

import numpy as np
import pytest

from charcurves import ConfigError, DataError, IdentifiabilityError
from charcurves.cli import main
from charcurves.data import corrupt
from charcurves.data._trajectory import MultiTrajectory
from charcurves.fitting import DEFAULT_GENERAL_BASIS, PRESETS, CharacteristicCurves, load_model
from charcurves.simulate import simulate_model
from charcurves.systems import corrupt_forces, get_system


def nrmse(curve, truth):
    z = np.linspace(*curve.domain, 1000)
    t = truth(z)
    return float(np.sqrt(np.mean((curve(z) - t) ** 2)) / np.std(t))


@pytest.fixture(scope="module")
def vdp():
    s = get_system("van-der-pol")
    clean = s.simulate()
    return s, clean, corrupt(clean, 25.0, seed=0)


@pytest.fixture(scope="module")
def first_order():
    s = get_system("first-order")
    clean = s.simulate()
    return s, clean, corrupt(clean, 25.0, seed=0)


@pytest.fixture(scope="module")
def two_dof():
    s = get_system("two-dof")
    clean = s.simulate(t_end=50.0, n_points=1000)
    return s, clean, corrupt_forces(clean, 25.0, seed=0)


def _fit(system, record, method, **kw):
    if method == "parametric":  # no default basis: a cubic per curve, given explicitly
        kw.setdefault("basis", DEFAULT_GENERAL_BASIS)
    return CharacteristicCurves.from_method(family=system.family, method=method, random_state=0, threads=1, **kw).fit(record).model_


#: (f1, f2) normalised-RMSE bounds per method on the 25 dB van der Pol record. Measured (issue 25) over
#: noise seeds 0-5 x fit seeds 0, 1 (12 fits each), worst f1 / f2: nn-cc 6.00e-3 / 9.04e-4,
#: parametric 2.06e-3 / 1.10e-3, poly-cc 7.01e-3 / 1.70e-3, sindy-cc 7.01e-3 / 1.70e-3,
#: nn-cc+sym 6.10e-3 / 8.22e-4, sindy-cc+sym 6.31e-3 / 1.22e-3 (the test's noise seed 0 is the worst
#: or within 12 % of it everywhere). Each bound is at most 1.5 times its worst measured value. Wrong
#: models miss by far more: f1 declared odd (it is even) gives f1 1.08; a basis or a polynomial
#: without the cubic of f2 gives f2 0.25.
VDP_BOUNDS = {"nn-cc": (9e-3, 1.3e-3), "parametric": (3e-3, 1.6e-3), "poly-cc": (1e-2, 2.5e-3),
              "sindy-cc": (1e-2, 2.5e-3), "nn-cc+sym": (9e-3, 1.2e-3), "sindy-cc+sym": (9e-3, 1.8e-3)}


@pytest.mark.parametrize("method, kw", [("nn-cc", {}), ("parametric", {}), ("poly-cc", {}), ("sindy-cc", {}),
                                        ("nn-cc+sym", {"symmetry": "f1=none,f2=odd"}),
                                        ("sindy-cc+sym", {"symmetry": "f1=even,f2=odd"})])
def test_position_damping_recovers_van_der_pol_curves_at_25db(vdp, method, kw):
    s, _, noisy = vdp
    model = _fit(s, noisy, method, **kw)
    errs = {k: nrmse(c, s.true_curves()[k]) for k, c in model.curves.items()}
    f1_bound, f2_bound = VDP_BOUNDS[method]
    assert errs["f1"] <= f1_bound and errs["f2"] <= f2_bound, errs
    # appendix A.2: strictly unique; with odd f2 no curve carries a constant, so the equation gets one
    assert model.result_dict()["gauge"] == "none (no constant to trade)"
    if kw:  # the true constant is 0; measured |offset| at most 2.6e-3 over the same 12 fits
        assert abs(model.offset) < 4e-3
    assert model.curves["f1"].argument == "x" and model.curves["f2"].argument == "x"


def test_even_prior_on_the_damping_curve_fits_as_well_as_unconstrained(vdp):
    """f1 = x^2 - 1 under an exact even prior (issue 5: it used to stall at ~8 %, f2 at ~2 %;
    unconstrained f1 reaches 0.6 % on this record)."""
    s, _, noisy = vdp
    model = _fit(s, noisy, "nn-cc+sym", symmetry="f1=even,f2=odd")
    errs = {k: nrmse(c, s.true_curves()[k]) for k, c in model.curves.items()}
    assert errs["f1"] <= 0.015 and errs["f2"] <= 0.01, errs  # measured 0.58 % and 0.10 %
    z = np.linspace(0.0, 2.0, 9)
    np.testing.assert_allclose(model.curves["f1"](z), model.curves["f1"](-z), rtol=0, atol=1e-12)
    assert model.curves["f1"](np.array([0.0]))[0] == pytest.approx(-1.0, abs=0.03)  # the constant is carried


def test_even_prior_in_a_user_equation_with_scalars(vdp):
    """An even curve next to unknown scalars (constant-argument terms of the same batched problem)."""
    s, _, noisy = vdp
    model = CharacteristicCurves.from_method(family="custom", equation="x'' + f1(x)*x' + a1*x + a2*x**3 = F",
                                 method="nn-cc+sym", symmetry="f1=even", random_state=0, threads=1).fit(noisy).model_
    assert nrmse(model.curves["f1"], s.f1) <= 0.015  # measured 0.62 %
    assert model.info["scalars"]["a1"] == pytest.approx(1.0, abs=0.02)  # measured 0.995
    assert model.info["scalars"]["a2"] == pytest.approx(0.5, abs=0.01)  # measured 0.501


def test_even_curves_start_away_from_their_stationary_point_and_expose_their_output_layer():
    import torch

    from charcurves.curves import NeuralCurve
    from charcurves.curves import EVEN_INPUT_WEIGHTS

    even = NeuralCurve(hidden=(8,), activation="softplus", symmetry="even")
    plain = NeuralCurve(hidden=(8,), activation="softplus", symmetry="none")
    th_even = even.init(3, torch.Generator().manual_seed(5))
    th_plain = plain.init(3, torch.Generator().manual_seed(5))
    w_even, w_plain = th_even[:, :8], th_plain[:, :8]
    lo, hi = EVEN_INPUT_WEIGHTS
    assert float(w_even.abs().min()) >= lo and float(w_even.abs().max()) <= hi
    # the same draws, moved: signs kept, |w| mapped affinely; every other weight identical
    torch.testing.assert_close(w_even, torch.sign(w_plain) * (lo + (hi - lo) * w_plain.abs()))
    torch.testing.assert_close(th_even[:, 8:], th_plain[:, 8 : th_even.shape[1]])
    # the output layer enters linearly: its columns times its weights give the curve
    u = torch.linspace(-1, 1, 21, dtype=torch.float64)
    cols, where = even.output_layer(th_even, u)
    assert cols.shape == (3, 21, 9) and where == slice(16, 25)
    torch.testing.assert_close((cols * th_even[:, where].unsqueeze(1)).sum(-1), even.evaluate(th_even, u))


#: (f1, f2) normalised-RMSE bounds on the 25 dB first-order record (noise on the forcing). Measured
#: over noise seeds 0-2 (fit seed 0), worst f1 / f2: nn-cc 1.53e-3 / 1.18e-2, parametric 4.21e-3 /
#: 1.50e-2 (noise seed 0, the test's, is the worst f2 of both); each bound is 1.5 times the worst.
FIRST_ORDER_BOUNDS = {"nn-cc": (2.3e-3, 1.8e-2), "parametric": (6.5e-3, 2.3e-2)}


@pytest.mark.parametrize("method", ["nn-cc", "parametric"])
def test_first_order_recovers_curves_at_25db(first_order, method):
    s, _, noisy = first_order
    model = _fit(s, noisy, method)
    errs = {k: nrmse(c, s.true_curves()[k]) for k, c in model.curves.items()}
    f1_bound, f2_bound = FIRST_ORDER_BOUNDS[method]
    assert errs["f1"] <= f1_bound and errs["f2"] <= f2_bound, errs


def test_first_order_measured_record_gets_its_quadratic_and_reaches_the_limit():
    """Noise on x only (40 dB), the default objective. f2 = 0.5 + x^2 enters times x', which vanishes
    at the ends of x's range: a network alone was flattened there by its weight decay (f2 1.94 %).
    The unconstrained curves are now tested for a quadratic (beside the cubic) as well as a cubic
    term, and f2 gets its x^2: measured f1 0.13 %, f2 0.24 %, against the limit of the parametric fit
    on the true basis refined by output error, 0.14 % / 0.17 % (benchmarks/bench_first_order_edges.py)."""
    s = get_system("first-order")
    record = corrupt(s.simulate(), 40.0, on="state", seed=0)
    model = _fit(s, record, "nn-cc")
    assert model.curves["f1"].spec.powers == (3,) and model.curves["f2"].spec.powers == (2,)
    assert model.info["objective"] == "output-error"
    errs = {k: nrmse(c, s.true_curves()[k]) for k, c in model.curves.items()}
    assert errs["f1"] <= 2.5e-3 and errs["f2"] <= 4e-3, errs


def test_the_quadratic_test_does_not_mistake_duffings_cubic_for_one():
    """Duffing's f2 = -x + x^3 is odd: beside its cubic, a quadratic is not significant (F 0.006 on
    the 20 dB record; 14.9 when the quadratic was tested without the cubic in the base). On a
    measured record (30 dB noise on x, estimated derivatives) F reaches 16.3, above the 0.1 % point
    of the exact test but far below the 100 an unconstrained curve's quadratic needs (the
    first-order f2 = 0.5 + x^2: 3400); with the quadratic, nn-cc's f2 there was 1.9x worse."""
    s = get_system("duffing")
    quick = PRESETS["default"].replace(n_starts=1, adam_steps=0, lm_max_iter=2)
    for record in (corrupt(s.simulate(), 20.0, seed=0), corrupt(s.simulate(), 30.0, on="state", seed=0)):
        model = CharacteristicCurves.from_method(method="nn-cc", preset=quick, objective="equation-error", random_state=0,
                                     threads=1).fit(record).model_
        assert model.curves["f2"].spec.powers == (3,)
        assert 2 not in model.curves["f1"].spec.powers


@pytest.mark.parametrize("method", ["nn-cc", "parametric", "poly-cc"])
def test_two_dof_recovers_four_curves_at_25db(two_dof, method):
    s, _, noisy = two_dof
    model = _fit(s, noisy, method)
    errs = {k: nrmse(c, s.true_curves()[k]) for k, c in model.curves.items()}
    assert max(errs.values()) <= 0.05, errs
    # the gauge of appendix A.4: zero coupling force at equilibrium
    assert model.curves["f2"](np.array([0.0]))[0] == pytest.approx(0.0, abs=1e-12)
    assert model.curves["f4"](np.array([0.0]))[0] == pytest.approx(0.0, abs=1e-12)
    assert model.force_residual(noisy).shape == (1000, 2)


def test_fitted_models_simulate_forward(vdp, two_dof):
    s, clean, _ = vdp
    model = _fit(s, clean, "parametric")
    res = simulate_model(model, clean.t[:500], s.x0, s.v0, lambda t: s.A * np.cos(s.Omega * t))
    assert res.ok and np.max(np.abs(res.x - clean.x[:500])) < 1e-4
    s2, clean2, _ = two_dof
    m2 = _fit(s2, clean2, "parametric")
    r2 = simulate_model(m2, clean2.t[:400], {"x1": s2.x10, "x2": s2.x20}, {"x1": 0.0, "x2": 0.0}, s2.forcing)
    truth = np.column_stack([clean2.states["x1"][:400], clean2.states["x2"][:400]])
    assert r2.ok and r2.x.shape == (400, 2) and np.max(np.abs(r2.x - truth)) < 1e-4
    with pytest.raises(ConfigError, match="x0 needs 2 value"):
        simulate_model(m2, clean2.t[:10], 0.1, 0.0, s2.forcing)


def test_two_dof_model_saves_and_loads(two_dof, tmp_path):
    s, _, noisy = two_dof
    model = _fit(s, noisy, "poly-cc", options={"degree": 5})
    model.save(tmp_path / "m")
    back = load_model(tmp_path / "m")
    assert back.template.family == "two-dof" and back.template.curve_names == ("f1", "f2", "f3", "f4")
    np.testing.assert_array_equal(back.force_residual(noisy), model.force_residual(noisy))
    eqs = back.to_sympy()
    assert len(eqs) == 2 and "x1''" in str(eqs[0].lhs) and str(eqs[1].rhs) == "F2"


def test_post_sr_distils_position_damping_curves(vdp):
    s, clean, _ = vdp
    model = CharacteristicCurves.from_method(family="position-damping", method="nn-cc+post-sr", threads=1,
                                 sr_options={"generations": 20}).fit(clean).model_
    assert model.is_symbolic
    errs = {k: nrmse(c, s.true_curves()[k]) for k, c in model.curves.items()}
    assert max(errs.values()) <= 0.02, errs


def test_multi_dof_record_checks(two_dof):
    s, clean, _ = two_dof
    cc = CharacteristicCurves.from_method(family="two-dof", method="parametric", basis=DEFAULT_GENERAL_BASIS)
    with pytest.raises(DataError, match="multi-DOF record"):
        cc.fit(get_system("duffing").simulate())
    together = clean.replace(states={"x1": clean.states["x1"], "x2": clean.states["x1"]},
                             velocities={"x1": clean.velocities["x1"], "x2": clean.velocities["x1"]})
    with pytest.raises(IdentifiabilityError, match="x1 - x2 of f2 is constant.*move together"):
        cc.fit(together)
    with pytest.raises(DataError, match="give all or none"):
        MultiTrajectory.from_columns({"t": clean.t, "x1": clean.states["x1"], "x2": clean.states["x2"],
                                      "F1": clean.forces["F1"], "F2": clean.forces["F2"], "v1": clean.t})
    # derivatives estimated from x1, x2 when the record has none
    bare = MultiTrajectory(clean.t, clean.states, clean.forces)
    model = cc.fit(bare).model_
    assert max(nrmse(c, s.true_curves()[k]) for k, c in model.curves.items()) <= 0.05


def test_cli_two_dof_and_equation(tmp_path, capsys):
    csv = tmp_path / "two.csv"
    assert main(["simulate", "two-dof", "--out", str(csv), "--snr", "25", "--t-end", "50"]) == 0
    assert csv.read_text().splitlines()[0] == "t,x1,x2,v1,a1,v2,a2,F1,F2"
    out = tmp_path / "fit"
    assert main(["fit", str(csv), "--family", "two-dof", "--method", "parametric", "--out", str(out),
                 "--basis", "; ".join(f"f{k}=1, z, z**2, z**3" for k in range(1, 5)),
                 "--truth", "two-dof", "--no-figure", "--quiet"]) == 0
    res = json.loads((out / "result.json").read_text())
    assert res["family"] == "two-dof" and res["gauge"] == "f2(0) = 0, f4(0) = 0"
    assert {k: v["argument"] for k, v in res["curves"].items()} == {"f1": "x1'", "f2": "x1 - x2", "f3": "x2'",
                                                                     "f4": "x2 - x1"}
    assert max(res["curve_rmse"].values()) < 0.01
    # the bare contract columns t,x1,x2,F1,F2: derivatives are estimated per state
    s = get_system("two-dof")
    clean = s.simulate(t_end=50.0, n_points=1000)
    bare = tmp_path / "bare.csv"
    MultiTrajectory(clean.t, clean.states, clean.forces).to_csv(bare)
    assert bare.read_text().splitlines()[0] == "t,x1,x2,F1,F2"
    out3 = tmp_path / "bare-fit"
    assert main(["fit", str(bare), "--family", "two-dof", "--method", "poly-cc", "--out", str(out3), "--no-figure",
                 "--quiet"]) == 0
    model = load_model(out3 / "model")
    assert max(nrmse(c, s.true_curves()[k]) for k, c in model.curves.items()) <= 0.05
    # a CSV without x2 for the two-dof family: exit 2 with one line
    bad = tmp_path / "bad.csv"
    bad.write_text("t,x1,F1,F2\n" + "\n".join(f"{i},{i},{i},{i}" for i in range(40)) + "\n")
    capsys.readouterr()
    assert main(["fit", str(bad), "--family", "two-dof", "--out", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("charcurves: error:") and "x2" in err and "\n" not in err

    one = tmp_path / "vdp.csv"
    assert main(["simulate", "van-der-pol", "--out", str(one), "--snr", "25"]) == 0
    out2 = tmp_path / "eq"
    assert main(["fit", str(one), "--equation", "x'' + f1(x)*x' + a1*x + f2(x) = F", "--method", "poly-cc",
                 "--out", str(out2), "--no-figure", "--quiet"]) == 2  # a1*x duplicates what f2(x) can carry
    assert "a1 is not identifiable" in capsys.readouterr().err
    assert main(["fit", str(one), "--equation", "x'' + f1(x)*x' + a1*x + a2*x**3 = F", "--method", "poly-cc",
                 "--out", str(out2), "--no-figure", "--quiet", "--truth", "van-der-pol"]) == 0
    res = json.loads((out2 / "result.json").read_text())
    assert res["family"] == "custom" and res["scalars"]["a1"] == pytest.approx(1.0, abs=0.02)
    assert res["scalars"]["a2"] == pytest.approx(0.5, abs=0.02)
    assert res["curve_rmse"]["f1"] < 0.05


def test_first_order_uses_given_velocity_alone(first_order):
    s, clean, _ = first_order
    model = CharacteristicCurves.from_method(family="first-order", method="parametric", differentiator="given",
                                 basis=DEFAULT_GENERAL_BASIS).fit(
        clean.replace(a=None)).model_  # x' is all a first-order template needs
    z = np.linspace(-1.2, 1.2, 50)
    np.testing.assert_allclose(model.curves["f1"](z), s.f1(z), atol=1e-9)
    np.testing.assert_allclose(model.curves["f2"](z), s.f2(z), atol=1e-9)
    with pytest.raises(DataError, match="--derivatives given needs"):
        CharacteristicCurves.from_method(family="position-damping", method="parametric", differentiator="given",
                             basis=DEFAULT_GENERAL_BASIS).fit(
            clean.replace(a=None))
