"""Forward simulation of fitted models and the dynamical metrics."""

import numpy as np
import pytest

import charcurves as cc
from charcurves.curves import SymbolicFittedCurve
from charcurves.fitting import FittedModel, PRESETS
from charcurves.metrics import largest_lyapunov_exponent, separation_time, trajectory_rmse
from charcurves.simulate import simulate_model, sinusoidal_forcing
from charcurves.templates import SeparableTemplate


def symbolic_model(f1, f2, gain=1.0, offset=0.0, domain=(-2, 2)):
    curves = {"f1": SymbolicFittedCurve("f1", "x'", domain, f1), "f2": SymbolicFittedCurve("f2", "x", domain, f2)}
    return FittedModel(SeparableTemplate(), "test", curves, gain, offset, 0.0)


def test_a_model_with_the_true_curves_reproduces_the_system(duffing):
    system, clean = duffing
    model = symbolic_model("0.3*z", "z**3 - z")
    res = simulate_model(model, clean.t, 0.5, -0.5, system.forcing, rtol=1e-10, atol=1e-12)
    assert res.ok and res.status == "ok"
    # chaos amplifies solver differences only slowly over the first 20 s
    first = clean.t <= 20
    assert np.max(np.abs(res.x[first] - clean.x[first])) < 1e-5


def test_neural_model_simulates_through_numpy_curves(duffing, duffing_20db):
    system, clean = duffing
    model = cc.fit(duffing_20db, method="nn-cc+sym", random_state=0, threads=1)
    t = np.linspace(0, 10, 250)
    res = simulate_model(model, t, 0.5, -0.5, system.forcing, time_budget=30)
    assert res.ok
    tsep, censored = separation_time(t, res.x, system.simulate(t_eval=t).x)
    assert tsep >= 10 and censored  # a 20 dB NN-CC+sym model tracks the truth for 10 s
    assert res.seconds < 10


def test_a_diverging_model_ends_with_a_status_not_a_hang():
    model = symbolic_model("-0.5*z", "-z**3")  # negative damping, softening spring: blows up
    res = simulate_model(model, np.linspace(0, 100, 1000), 1.0, 1.0, lambda t: 0.0, max_abs=1e3)
    assert res.status == "diverged" and "larger than" in res.message
    assert res.t_end_reached < 100
    boxed = simulate_model(model, np.linspace(0, 100, 1000), 0.5, 0.0, lambda t: 0.0, box={"x": (-2, 2)})
    assert boxed.status == "left_box" and "left [-2, 2]" in boxed.message
    assert np.all(np.abs(boxed.x) <= 2.0 + 1e-9)


def test_time_budget_stops_a_crawling_simulation():
    # an extremely stiff jump makes the solver crawl; the budget ends it
    model = symbolic_model("0.3*z + tanh(1e9*z)", "z")
    res = simulate_model(model, np.linspace(0, 1e4, 100), 0.0, 0.0, sinusoidal_forcing(2, 0.3),
                         time_budget=0.5, method="RK45")
    assert res.status == "timeout" and "time budget" in res.message
    assert res.seconds < 5


def test_separation_time_and_rmse():
    t = np.linspace(0, 10, 11)
    a = np.zeros(11)
    b = np.where(t >= 4, 0.25, 0.0)
    assert separation_time(t, a, b) == (4.0, False)
    assert separation_time(t, a, np.full(11, 0.2)) == (10.0, True)  # strict: 0.2 is not > 0.2
    assert trajectory_rmse(a, np.full(11, 3.0)) == pytest.approx(3.0)


def test_lyapunov_of_a_linear_damped_oscillator_is_minus_half_the_damping():
    # x'' + c x' + k x = 0: both exponents are -c/2 (underdamped), so the largest is -c/2
    lam = largest_lyapunov_exponent(lambda v: 0.2 * v, lambda x: 1.0 * x, lambda t: 0.0, 1.0, 0.0,
                                    t_transient=0.0, t_total=200.0)
    assert lam == pytest.approx(-0.1, abs=5e-3)


def _two_trajectory_exponent(system, t_total, t_transient=50.0, d0=1e-8):
    """Independent estimate: two trajectories d0 apart, renormalised every time unit."""
    from scipy.integrate import solve_ivp

    rhs = lambda t, y: [y[1], system.forcing(t) - system.f1(y[1]) - system.f2(y[0])]  # noqa: E731
    y = solve_ivp(rhs, (0, t_transient), [0.5, -0.5], rtol=1e-10, atol=1e-12, method="LSODA").y[:, -1]
    z, t, tot = y + [d0, 0], t_transient, 0.0
    n = int(t_total)
    for _ in range(n):
        a = solve_ivp(rhs, (t, t + 1), y, rtol=1e-10, atol=1e-12, method="LSODA").y[:, -1]
        b = solve_ivp(rhs, (t, t + 1), z, rtol=1e-10, atol=1e-12, method="LSODA").y[:, -1]
        d = np.linalg.norm(b - a)
        tot += np.log(d / d0)
        y, z, t = a, a + (b - a) * d0 / d, t + 1
    return tot / n


def test_lyapunov_of_chaotic_duffing_is_positive(duffing):
    system, _ = duffing
    lam = largest_lyapunov_exponent(system.f1, system.f2, system.forcing, 0.5, -0.5, t_transient=50,
                                    t_total=600)
    # finite-time estimates over 600 time units scatter by about +-0.02 around the limit 0.10
    assert 0.07 < lam < 0.15


@pytest.mark.slow
def test_lyapunov_variational_agrees_with_two_trajectories_and_the_papers_value():
    from charcurves.systems import get_system

    paper = get_system("duffing")
    lam = largest_lyapunov_exponent(paper.f1, paper.f2, paper.forcing, 0.5, -0.5, t_total=5000)
    two = _two_trajectory_exponent(paper, 5000)
    assert lam == pytest.approx(two, abs=0.01)
    assert lam == pytest.approx(0.103, abs=0.01)  # alpha = -1, beta = 1: T_L ~ 9.7
    # the paper's T_L = 7.8 (lambda = 0.13) is the authors' scripts' Duffing, alpha = -1.05, beta = 1.02
    scripts = get_system("duffing", "scripts")
    lam_s = largest_lyapunov_exponent(scripts.f1, scripts.f2, scripts.forcing, 0.5, -0.5, t_total=5000)
    assert lam_s == pytest.approx(0.128, abs=0.01)
