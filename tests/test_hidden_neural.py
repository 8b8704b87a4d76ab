"""Neural and closed-form (post-SR) curves of hidden-state fits (issue 47, item 3)."""

from __future__ import annotations

import numpy as np
import pytest

from charcurves._errors import ConfigError
from charcurves.curves import Neural, NeuralFittedCurve, Symbolic, SymbolicFittedCurve
from charcurves.fitting import fit_state_space, load_model
from charcurves.systems import TwoTank
from charcurves.templates import StateSpace

TANKS = "x1' = g*F - f1(x1); x2' = f1(x1) - f2(x2)"
SMALL = dict(n_starts=2, degree=3, start="linear", schedule=(16, 48), max_iter=20, substeps=1, seed=0,
             time_budget=1e6)  # no wall-clock cut: the same fit on a loaded machine


def _record():
    system = TwoTank(hold=15.0)
    return system, system.simulate(n_points=150, t_end=300.0, seed=0), system.states(n_points=150, t_end=300.0, seed=0)


def _error(model, system, clean, name):
    true, x = (system.f1, clean["x1"]) if name == "f1" else (system.f2, clean["x2"])
    z = np.linspace(x.min(), x.max(), 200)
    return float(np.sqrt(np.mean((model.curves[name](z) - true(z)) ** 2)) / np.std(true(z)))


@pytest.fixture(scope="module")
def tank_fits():
    system, record, clean = _record()
    poly = fit_state_space(StateSpace(TANKS, measured={"x2": "x"}), record, **SMALL)
    nets = fit_state_space(StateSpace(TANKS, measured={"x2": "x"}, f1=Neural(hidden=(8,)), f2=Neural(hidden=(8,))),
                           record, **SMALL)
    return system, record, clean, poly, nets


@pytest.mark.slow  # two small fits: about 15 s on one core
def test_neural_curves_of_a_hidden_fit_match_the_polynomial_fit(tank_fits):
    system, record, clean, poly, nets = tank_fits
    assert nets.info["representations"] == {"f1": "neural", "f2": "neural"}
    assert poly.info["representations"] == {"f1": "Polynomial", "f2": "Polynomial"}
    assert all(isinstance(c, NeuralFittedCurve) for c in nets.curves.values())
    last = nets.info["stages"][-1]
    assert last["curves"] == "neural" and last["segment_length"] == 48 and last["networks"] == ["f1", "f2"]
    # the lower outflow and the free run within 1.5x of the polynomial fit's (measured ratios below)
    e_poly, e_nets = _error(poly, system, clean, "f2"), _error(nets, system, clean, "f2")
    assert e_nets < 1.5 * e_poly and e_nets < 0.15
    rmse_poly, rmse_nets = poly.info["free_run_rmse"]["x2"], nets.info["free_run_rmse"]["x2"]
    assert rmse_nets < 1.5 * rmse_poly and rmse_nets < 0.06  # noise 0.01
    assert nets.gain == pytest.approx(1.0, abs=0.1)


@pytest.mark.slow
def test_a_neural_hidden_model_file_free_runs_to_the_last_bit(tank_fits, tmp_path):
    _, record, _, _, nets = tank_fits
    nets.save(tmp_path / "model")
    back = load_model(tmp_path / "model")
    assert isinstance(back.curves["f1"], NeuralFittedCurve)
    a, b = nets.simulate(record), back.simulate(record)
    assert all(np.array_equal(a[k], b[k]) for k in a)


def _root_of_z(expr) -> bool:
    """Whether ``expr`` holds a fractional power (a square root, a fourth root) of something in z."""
    import sympy as sp

    z = sp.Symbol("z")
    return any(p.has(z) and p.exp.is_Rational and 0 < p.exp < 1 for p in expr.atoms(sp.Pow))


@pytest.mark.slow  # a small fit and the post-SR searches: about 15 CPU s, minutes of wall time under load
def test_post_sr_of_a_hidden_fit_gives_a_square_root_outflow_and_refits_its_constants():
    system, record, clean = _record()
    template = StateSpace(TANKS, measured={"x2": "x"}, f1=Neural(hidden=(8,)), f2=Neural(hidden=(8,)))
    model = fit_state_space(template, record, post_sr=True, **SMALL)
    post = model.info["post_sr"]
    assert model.info["representations"] == {"f1": "closed form", "f2": "closed form"}
    assert all(isinstance(c, SymbolicFittedCurve) for c in model.curves.values())
    f1 = model.curves["f1"].expression()
    assert _root_of_z(f1) and "sqrt(Abs(" in str(f1)  # measured: -0.0164*z + 1.006*sqrt(Abs(1.186*z + 0.366)) - 0.393
    assert post["curves"]["f1"]["expression"] == str(f1)
    assert post["loss_refit"] <= post["loss_distilled"]  # the refit of the constants only lowers the loss
    assert model.info["stages"][-1]["curves"] == "closed form" and model.info["stages"][-2]["curves"] == "neural"
    # measured under the suite's settings (conftest): f2 = 0.820*sqrt(Abs(z)) - 0.169 + 0.256*exp(-6.66*z),
    # 0.080 off the truth, free run 0.0131 (noise 0.01); from a plain script the search gives another f2
    e2, rmse = _error(model, system, clean, "f2"), model.info["free_run_rmse"]["x2"]
    assert e2 < 0.1 and rmse < 0.02, (e2, rmse)


def test_the_root_check_tells_a_square_root_from_a_polynomial():
    import sympy as sp

    assert _root_of_z(sp.sympify("1.0*sqrt(Abs(z + 0.05)) - 0.2")) and _root_of_z(sp.sympify("Abs(z)**(1/4)"))
    assert not _root_of_z(sp.sympify("0.5*z**3 - z + sqrt(2)"))


def test_a_symbolic_curve_of_a_hidden_fit_is_refused_with_the_fix():
    _, record, _ = _record()
    with pytest.raises(ConfigError, match="f1: a hidden-state fit cannot search closed forms .* post_sr=True"):
        fit_state_space(StateSpace(TANKS, measured={"x2": "x"}, f1=Symbolic()), record, n_starts=1)


def test_a_network_the_gauge_anchors_at_zero_must_be_odd():
    from charcurves.systems import BoucWen

    system = BoucWen()
    record = system.simulate(system.multisine(seed=0, period=300), seed=0).slice(slice(0, 64))
    eq = "x1'' + f1(x1') + f2(x1) + x2 = g*F; x2' = f3(x2)*Abs(x1') + f4(x2)*x1'"
    with pytest.raises(ConfigError, match="f1 is anchored at 0 by the template's gauge.*Neural\\(symmetry='odd'\\)"):
        fit_state_space(StateSpace(eq, measured={"x1": "x"}, f1=Neural()), record, n_starts=1)


@pytest.mark.parametrize("extra, message", [
    (["--method", "sindy-cc"], "charcurves: error: --method does not apply here: a hidden-state fit (--measured) "
                               "learns its curves as poly-cc or nn-cc, not sindy-cc; give --method nn-cc or poly-cc "
                               "(and --post-sr for closed forms) (see 'charcurves fit --help')"),
    (["--method", "sr"], "charcurves: error: --method does not apply here: a hidden-state fit (--measured) learns its "
                         "curves as poly-cc or nn-cc, not sr; give --method nn-cc or poly-cc (and --post-sr for closed "
                         "forms) (see 'charcurves fit --help')"),
    (["--sr-generations", "5"], "charcurves: error: --sr-generations does not apply here: a hidden-state fit runs "
                                "symbolic regression only with --post-sr; add --post-sr or drop --sr-generations (see "
                                "'charcurves fit --help')"),
])
def test_cli_refuses_what_a_hidden_fit_cannot_use_in_one_line(tmp_path, capsys, extra, message):
    from charcurves.cli import main

    csv = tmp_path / "tank.csv"
    TwoTank().simulate(n_points=101, t_end=100.0).to_csv(csv)
    assert main(["fit", str(csv), "--out", str(tmp_path / "out"), "--equation", TANKS, "--measured", "x2=x",
                 *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [message]


def test_cli_post_sr_needs_measured_states(tmp_path, capsys):
    from charcurves.cli import main

    csv = tmp_path / "tank.csv"
    TwoTank().simulate(n_points=101, t_end=100.0).to_csv(csv)
    assert main(["fit", str(csv), "--out", str(tmp_path / "out"), "--post-sr"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--post-sr does not apply here" in err[0] and "nn-cc+post-sr" in err[0]
