"""State-space templates with hidden states: analysis, refusals, systems and a small fit."""

from __future__ import annotations

import numpy as np
import pytest

from charcurves import ConfigError, DataError, IdentifiabilityError
from charcurves.systems import BoucWen, TwoTank
from charcurves.templates import StateSpace, parse_measured

TANKS = "x1' = g*F - f1(x1); x2' = f1(x1) - f2(x2)"
BOUC_WEN = "x1'' + f1(x1') + f2(x1) + x2 = g*F; x2' = f3(x2)*Abs(x1') + f4(x2)*x1'"


def test_two_tank_hidden_offset_is_fixed_by_its_initial_value():
    a = StateSpace(TANKS, measured={"x2": "x"}, initial={"x1": 0.5}).analysis()
    assert a.hidden == ("x1",) and a.measured == {"x2": "x"}
    assert a.fixed_initial == {"x1": 0.5} and not a.gain_fixed and a.anchored == ()
    assert a.freedoms == ("the offset of hidden x1 moves the argument of f1; fixed by x1(t0) = 0.5",)


def test_bouc_wen_hidden_offset_is_fixed_by_anchoring_the_curves_that_carry_it():
    a = StateSpace(BOUC_WEN, measured="x1=x").analysis()
    assert a.hidden == ("x2",) and a.anchored == ("f1", "f2") and a.fixed_initial == {}
    assert a.freedoms == ("the offset of hidden x2 moves the constants of f1 and f2 and the argument of f3 and f4; "
                          "fixed by f1(0) = 0 and f2(0) = 0",)


def test_hidden_scale_trades_with_a_free_gain_and_is_fixed_by_it():
    a = StateSpace("x1' = g*F - f1(x1); x2' = f2(x1) - f3(x2)", measured={"x2": "x"}).analysis()
    assert a.gain_fixed
    assert "the scale of hidden x1 trades with the gain g; fixed by g = 1" in a.freedoms
    # with the gain fixed, F sets x1's scale: no scale freedom
    assert not StateSpace("x1' = F - f1(x1); x2' = f2(x1) - f3(x2)", measured={"x2": "x"}).analysis().gain_fixed


def test_a_curve_shared_by_two_equations_fixes_the_hidden_scale():
    assert not StateSpace(TANKS, measured={"x2": "x"}).analysis().gain_fixed


@pytest.mark.parametrize("equation, measured, error, message", [
    ("x1' = g*F - f1(x1); x2' = - f2(x2)", "x1=x", IdentifiabilityError,
     "the hidden state x2 enters no equation of a measured state"),
    (TANKS, "x3=x", ConfigError, "measured names 'x3', which is not a state of the template; the states are x1, x2"),
    (TANKS, "x2", ConfigError, "--measured 'x2': write state=column pairs"),
    ("x1' = g - f1(x1); x2' = f1(x1) - f2(x2)", "x2=x", ConfigError, "the gain g must multiply a forcing"),
])
def test_bad_templates_are_refused_with_the_reason(equation, measured, error, message):
    with pytest.raises(error, match=message.replace("(", r"\(").replace(")", r"\)")):
        StateSpace(equation, measured=measured).analysis()


def test_initial_must_name_a_hidden_state():
    with pytest.raises(ConfigError, match="initial names x2, which is not a hidden state"):
        StateSpace(TANKS, measured={"x2": "x"}, initial={"x2": 1.0}).analysis()


def test_parse_measured_reads_the_cli_spelling():
    assert parse_measured("x2=x, x1=y") == {"x2": "x", "x1": "y"}
    with pytest.raises(ConfigError, match="measured must name at least one"):
        parse_measured({})


def test_measured_map_naming_no_column_is_refused():
    from charcurves.fitting import fit_state_space

    record = TwoTank().simulate(n_points=101, t_end=100.0)
    with pytest.raises(DataError, match="measured maps x2 to the column 'y', which the record lacks"):
        fit_state_space(StateSpace(TANKS, measured={"x2": "y"}), record)


def test_two_tank_system_is_seeded_and_noisy_on_the_level_only():
    system = TwoTank()
    a, b = system.simulate(n_points=201, t_end=200.0, seed=3), system.simulate(n_points=201, t_end=200.0, seed=3)
    assert np.array_equal(a.x, b.x) and np.array_equal(a.F, b.F)
    clean = system.states(n_points=201, t_end=200.0, seed=3)
    assert np.std(a.x - clean["x2"]) == pytest.approx(0.01, rel=0.15)
    assert np.array_equal(a.F, clean["u"]) and clean["x1"][0] == 0.0 and clean["x1"].max() > 1.0
    # mass balance: the upper tank's level change is the inflow minus its outflow
    dx1 = np.gradient(clean["x1"], clean["t"])
    resid = dx1 - (clean["u"] - system.f1(clean["x1"]))
    assert np.median(np.abs(resid)) < 0.02 * np.median(np.abs(clean["u"]))


def test_bouc_wen_multisine_and_its_hysteresis_state():
    system = BoucWen()
    u = system.multisine(seed=1, period=1500)
    assert u.size == 1500 and np.sqrt(np.mean(u ** 2)) == pytest.approx(50.0)
    s = system.states(system.multisine(seed=1, period=1500, band=(1.0, 20.0)))  # slow: finite differences hold
    # w = z / m satisfies its own equation: w' = f3(w)|y'| + f4(w) y'
    c = system.curves()
    dw = np.gradient(s["w"], s["t"])
    rhs = c["f3"](s["w"]) * np.abs(s["v"]) + c["f4"](s["w"]) * s["v"]
    assert np.corrcoef(dw[5:-5], rhs[5:-5])[0, 1] > 0.999


def _small_tank_fit(degree):
    from charcurves.fitting import fit_state_space

    system = TwoTank(hold=15.0)
    record = system.simulate(n_points=150, t_end=300.0, seed=0)
    clean = system.states(n_points=150, t_end=300.0, seed=0)
    model = fit_state_space(StateSpace(TANKS, measured={"x2": "x"}), record, n_starts=2, degree=degree,
                            start="linear", schedule=(16, 48), max_iter=20, substeps=1)
    errors = {}
    for name, true, x in [("f1", system.f1, clean["x1"]), ("f2", system.f2, clean["x2"])]:
        z = np.linspace(x.min(), x.max(), 200)
        errors[name] = float(np.sqrt(np.mean((model.curves[name](z) - true(z)) ** 2)) / np.std(true(z)))
    return model, errors


@pytest.mark.slow  # about 10 s on one core
def test_a_small_two_tank_fit_recovers_both_outflows_with_the_upper_level_hidden():
    model, errors = _small_tank_fit(3)
    assert model.info["start"] == "linear" and model.info["hidden"] == ["x1"]
    assert model.info["gauge_conditions"] == ["x1(t0) = 0"] and model.initial_state["x1"] == 0.0
    assert [s["segment_length"] for s in model.info["stages"]] == [16, 48]
    assert errors["f1"] < 0.3 and errors["f2"] < 0.15  # measured: 0.21 and 0.076
    assert model.info["free_run_rmse"]["x2"] < 0.06  # noise 0.01; the levels span 0 to about 5
    assert model.gain == pytest.approx(1.0, abs=0.1)


@pytest.mark.slow
def test_a_wrong_model_of_the_outflows_fails_those_tolerances():
    _, errors = _small_tank_fit(1)  # straight outflow lines cannot drain like square roots
    assert errors["f1"] > 0.3 and errors["f2"] > 0.15


@pytest.mark.parametrize("extra, message", [
    (["--measured", "x2=y"], "no state column 'y'"),
    (["--measured", "x1=x", "--equation", "x1' = g*F - f1(x1); x2' = - f2(x2)"],
     "the hidden state x2 enters no equation of a measured state"),
    (["--measured", "x2"], "--measured 'x2': write state=column pairs"),
])
def test_cli_refuses_bad_hidden_state_fits_with_one_line(tmp_path, capsys, extra, message):
    from charcurves.cli import main

    csv = tmp_path / "tank.csv"
    TwoTank().simulate(n_points=101, t_end=100.0).to_csv(csv)
    args = ["fit", str(csv), "--out", str(tmp_path / "out"), "--equation", TANKS, *extra]
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0] and "Traceback" not in err[0]


def test_a_fit_reports_its_cpu_seconds_and_iterations_per_stage_with_degree_10_curves_by_default():
    from charcurves.fitting import fit_state_space

    record = TwoTank().simulate(n_points=81, t_end=160.0, seed=0)
    model = fit_state_space(StateSpace(TANKS, measured={"x2": "x"}), record, n_starts=1, schedule=(16, 40),
                            max_iter=3, substeps=1)
    assert [c.representation.degree for c in model.curves.values()] == [10, 10]
    assert [c.coefficients.size for c in model.curves.values()] == [10, 10]  # the constant stored apart
    assert [s["lm_iterations"] for s in model.info["stages"]] == [3, 3]  # capped by max_iter
    assert 0.0 < model.info["cpu_seconds"]
    fitted_start = model.free_run_rmse(record, initial=model.initial_state)
    assert model.info["free_run_rmse_fitted_start"] == fitted_start
    assert fitted_start["x2"] != model.info["free_run_rmse"]["x2"]  # the measured level's start differs


def test_bouc_wen_start_scales_the_hidden_state_by_the_force_and_lets_it_move():
    from charcurves.statespace import _fit as H
    from charcurves.statespace._model import record_table
    from charcurves.templates import ForwardModel

    system = BoucWen()
    record = system.simulate(system.multisine(seed=0, period=300), seed=0)
    template = StateSpace(BOUC_WEN, measured={"x1": "x"})
    structure = template.structure()
    fm = ForwardModel(structure)
    analysis = template.analysis()
    cols, dt = record_table(record, analysis.measured, structure.forces)
    data = H._measured_layout(fm, cols, analysis.measured, dt)
    measured_std = np.array([np.nanstd(data[:, d]) if np.isfinite(data[:, d]).any() else np.nan for d in range(3)])
    scale = H._hidden_scales(fm, cols, measured_std, 1.0)
    assert fm.layout == ["x1", "x1__d1", "x2"] and scale[2] == pytest.approx(np.std(record.F))  # + x2 = g*F
    reps = {n: H._pinned(4) if n in analysis.anchored else H._representations(template, structure, 4)[n]
            for n in structure.curve_names}
    tau = H._time_scale(cols, analysis.measured)
    start = {c.name: c for c in H._start_shared(fm, structure, reps, analysis, scale, tau, np.random.default_rng(0),
                                                4, "growing", data)}
    at0 = {n: c.values(np.zeros((4, 1)))[:, 0] for n, c in start.items()}
    # f4 multiplies x1' (zero mean): a positive constant, so z = f4 * x1 restores x1; f3 multiplies
    # |x1'| (one-signed) and stays a line through 0
    assert (at0["f4"] > 1e4).all() and np.allclose(at0["f3"], 0.0, atol=1e-6)
    u = np.linspace(-50.0, 50.0, 5)
    assert np.ptp(start["f4"].values(np.broadcast_to(u, (4, 5))), axis=1).max() < 1e-6 * at0["f4"].min()
    # the two-tank's hidden level enters no equation as a known term: no scale from the force
    tanks = StateSpace(TANKS, measured={"x2": "x"})
    tfm = ForwardModel(tanks.structure())
    tcols, _ = record_table(TwoTank().simulate(n_points=101, t_end=100.0), {"x2": "x"}, ("F",))
    assert np.isnan(H._hidden_scales(tfm, tcols, np.array([np.nan, 1.0]), 1.0)[0])
