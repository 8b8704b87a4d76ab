"""Benchmark systems: parameters, trajectories, stick-slip switching, registry."""

from __future__ import annotations

import dataclasses
import time

import numpy as np
import pytest

from charcurves._errors import ConfigError, DataError, SimulationError
from charcurves.data import Trajectory
from charcurves.systems import SYSTEM_NAMES, BenchmarkSystem, Duffing, StickSlip, get_system


@pytest.fixture(scope="module")
def duffing_paper() -> Trajectory:
    return Duffing().simulate()


@pytest.fixture(scope="module")
def stick_paper() -> Trajectory:
    return StickSlip().simulate()


# ---------------------------------------------------------------------- Duffing
def test_duffing_parameters():
    assert Duffing().parameters() == {
        "alpha": -1.0, "beta": 1.0, "delta": 0.3, "A": 0.5, "Omega": 1.2, "x0": 0.5, "v0": -0.5,
    }
    scripts = Duffing(variant="scripts")
    assert (scripts.alpha, scripts.beta) == (-1.05, 1.02)
    assert (scripts.rtol, scripts.atol) == (1e-3, 1e-6)
    assert (Duffing().rtol, Duffing().atol) == (1e-10, 1e-12)
    assert (Duffing(tolerance="scipy-default").rtol, Duffing(tolerance="scipy-default").atol) == (1e-3, 1e-6)
    assert Duffing(variant="scripts", alpha=-1.0).alpha == -1.0  # explicit fields beat the variant
    assert Duffing(rtol=1e-7).rtol == 1e-7


def test_duffing_curves():
    d = Duffing()
    np.testing.assert_allclose(d.f1([-1.0, 2.0]), [-0.3, 0.6])
    np.testing.assert_allclose(d.f2([-1.0, 0.0, 2.0]), [0.0, 0.0, 6.0])
    curves = d.true_curves()
    assert set(curves) == {"f1", "f2"}
    assert curves["f2"](1.5) == pytest.approx(-1.5 + 1.5**3)
    np.testing.assert_allclose(d.forcing([0.0, np.pi / 1.2]), [0.5, -0.5])


def test_duffing_trajectory_range(duffing_paper):
    tr = duffing_paper
    assert isinstance(tr, Trajectory) and tr.name == "duffing"
    assert tr.n_samples == 1000 and tr.t[0] == 0.0 and tr.t[-1] == 40.0
    assert tr.x[0] == 0.5 and tr.v[0] == -0.5
    assert np.abs(tr.x).max() < 1.6
    # the paper quotes the training range x ∈ [−1.50, 1.45]
    assert abs(tr.x.min() - (-1.50)) < 0.02
    assert abs(tr.x.max() - 1.45) < 0.02


def test_duffing_scripts_range():
    # protocol §2.1: with α = −1.05, β = 1.02 the range is [−1.425, 1.534]
    tr = Duffing(variant="scripts").simulate()
    assert tr.x.min() == pytest.approx(-1.425, abs=2e-3)
    assert tr.x.max() == pytest.approx(1.534, abs=2e-3)


def test_duffing_acceleration_is_rhs(duffing_paper):
    tr, d = duffing_paper, Duffing()
    rhs = 0.5 * np.cos(1.2 * tr.t) - 0.3 * tr.v + tr.x - tr.x**3
    np.testing.assert_allclose(tr.a, rhs, atol=1e-13)
    np.testing.assert_allclose(tr.F, d.forcing(tr.t), atol=0)
    # and the acceleration is consistent with the solver's velocity (not differentiated though)
    dv = np.gradient(tr.v, tr.t)
    assert np.abs(dv - tr.a)[5:-5].max() < 5e-3


def test_duffing_tolerance_sensitivity():
    tight = Duffing().simulate()
    loose = Duffing(tolerance="scipy-default").simulate()
    dx = np.abs(tight.x - loose.x)
    # chaos amplifies the rtol = 1e-3 error: |Δx| first exceeds 1e-2 near 18 s (protocol: 18.4 s)
    t_sep = tight.t[np.argmax(dx > 1e-2)]
    assert 15.0 < t_sep < 22.0
    assert dx[tight.t < 10].max() < 1e-2
    # the tight reference itself is converged
    tighter = Duffing(rtol=1e-12, atol=1e-14).simulate()
    assert np.abs(tighter.x - tight.x).max() < 1e-7
    # the scripts variant with default tolerances departs from its tight solution too
    s_loose = Duffing(variant="scripts").simulate()
    s_tight = Duffing(variant="scripts", tolerance="tight").simulate()
    ds = np.abs(s_loose.x - s_tight.x)
    assert ds[s_loose.t > 18].max() > 0.1


def test_duffing_overrides_and_t_eval():
    d = Duffing()
    tr = d.simulate(t_end=10.0, n_points=201, x0=0.1, v0=0.2, A=0.45, Omega=1.1)
    assert tr.n_samples == 201 and tr.t[-1] == 10.0
    assert (tr.x[0], tr.v[0]) == (0.1, 0.2)
    np.testing.assert_allclose(tr.F, 0.45 * np.cos(1.1 * tr.t))
    assert d.A == 0.5  # the system itself is unchanged
    t = np.linspace(5.0, 8.0, 31)
    tr2 = d.simulate(t_eval=t)
    np.testing.assert_array_equal(tr2.t, t)
    assert tr2.x[0] == pytest.approx(0.5, abs=1e-14)  # the initial conditions hold at t_eval[0]


def test_duffing_simulate_is_fast():
    t0 = time.perf_counter()
    Duffing().simulate()
    assert time.perf_counter() - t0 < 1.0


def test_systems_are_frozen():
    with pytest.raises(dataclasses.FrozenInstanceError):
        Duffing().alpha = 2.0  # type: ignore[misc]


# ---------------------------------------------------------------------- stick-slip
def test_stick_slip_parameters():
    s = StickSlip()
    assert s.parameters() == {
        "k": 1.274, "c": 0.386, "mu_N": 0.801, "A": 2.0, "Omega": 0.363, "x0": -0.076, "v0": 0.146,
    }
    assert s.friction == "coulomb" and (s.rtol, s.atol) == (1e-10, 1e-12)
    scripts = StickSlip(variant="scripts")
    assert scripts.Omega == 0.3 and scripts.friction == "tanh" and (scripts.rtol, scripts.atol) == (1e-3, 1e-6)
    assert StickSlip(variant="smooth").Omega == 0.363


def test_stick_slip_curves():
    s, sm = StickSlip(), StickSlip(variant="smooth")
    np.testing.assert_allclose(s.f1([-1.0, 0.0, 1.0]), [-1.187, 0.0, 1.187])
    np.testing.assert_allclose(s.f2([2.0]), [2.548])
    assert sm.f1(0.0) == 0.0
    assert sm.f1(0.1) == pytest.approx(0.0386 + 0.801 * np.tanh(50.0))
    assert sm.f1(1e-3) == pytest.approx(0.000386 + 0.801 * np.tanh(0.5))


def test_stick_slip_sticks(stick_paper):
    s, tr = StickSlip(), stick_paper
    stuck = s.sticking_mask(tr)
    assert stuck.sum() >= 50  # measured: 372 of 1000 samples, 5 sticking intervals
    assert 0.3 < stuck.mean() < 0.45
    assert (tr.v[stuck] == 0.0).all() and (tr.a[stuck] == 0.0).all()
    # static friction can hold the mass: |F − k x| ≤ μN
    assert (np.abs(tr.F - s.k * tr.x)[stuck] <= s.mu_N + 1e-9).all()
    # x is constant during each sticking interval
    starts = np.flatnonzero(np.diff(stuck.astype(int)) == 1) + 1
    assert len(starts) >= 3
    for i0 in starts:
        i1 = i0 + np.argmin(stuck[i0:]) if not stuck[i0:].all() else tr.n_samples
        assert np.ptp(tr.x[i0:i1]) == 0.0


def test_stick_slip_slip_residual(stick_paper):
    s, tr = StickSlip(), stick_paper
    slip = ~s.sticking_mask(tr)
    res = tr.a + s.f1(tr.v) + s.f2(tr.x) - tr.F
    assert np.abs(res[slip]).max() < 1e-12
    # the public acceleration agrees with the stored one everywhere (also while stuck)
    np.testing.assert_allclose(s.acceleration(tr.t, tr.x, tr.v), tr.a, atol=1e-12)


def test_stick_slip_continuity(stick_paper):
    tr = stick_paper
    # no jumps in x or v: largest step bounded by max|v|·dt (and max|a|·dt)
    assert np.abs(np.diff(tr.x)).max() <= np.abs(tr.v).max() * tr.dt * 1.01
    assert np.abs(np.diff(tr.v)).max() <= np.abs(tr.a).max() * tr.dt * 1.01
    # v is the derivative of x (central differences; skip the kinks where the mass stops)
    stuck = StickSlip().sticking_mask(tr)
    smooth = ~(stuck[:-2] ^ stuck[2:]) & ~(stuck[1:-1] ^ stuck[2:])
    dxdt = (tr.x[2:] - tr.x[:-2]) / (tr.t[2:] - tr.t[:-2])
    assert np.abs(dxdt - tr.v[1:-1])[smooth].max() < 2e-3


def test_stick_slip_close_to_tanh(stick_paper):
    smooth = StickSlip(variant="smooth").simulate()
    assert smooth.v is not None and not StickSlip(variant="smooth").sticking_mask(smooth).any()
    dx = np.abs(stick_paper.x - smooth.x)
    assert dx.max() < 0.01  # measured 0.0041 over 40 s
    assert np.abs(stick_paper.v - smooth.v).max() < 0.01


def test_stick_slip_converged(stick_paper):
    tighter = StickSlip(rtol=1e-12, atol=1e-14).simulate()
    assert np.abs(tighter.x - stick_paper.x).max() < 1e-8
    np.testing.assert_array_equal(StickSlip().sticking_mask(tighter), StickSlip().sticking_mask(stick_paper))


@pytest.mark.parametrize("variant", ["paper", "smooth", "scripts"])
def test_stick_slip_simulation_time(variant):
    s = StickSlip(variant=variant)
    t0 = time.perf_counter()
    tr = s.simulate()
    assert time.perf_counter() - t0 < 2.0
    assert tr.n_samples == 1000 and tr.name == "stick-slip"


def test_stick_slip_validation_cases():
    # the validation protocol's ranges; starts from rest included
    s = StickSlip()
    rng = np.random.default_rng(0)
    for i in range(20):
        kw = dict(x0=rng.uniform(-0.5, 0.5), v0=0.0 if i % 4 == 0 else rng.uniform(-0.5, 0.5),
                  A=rng.uniform(1.0, 1.5), Omega=rng.uniform(0.2, 1.0))
        tr = s.simulate(**kw)
        stuck = s.sticking_mask(tr)
        assert (np.abs(tr.F - s.k * tr.x)[stuck] <= s.mu_N + 1e-9).all()
        res = (tr.a + s.f1(tr.v) + s.f2(tr.x) - tr.F)[~stuck & (tr.v != 0)]
        assert np.abs(res).max() < 1e-11


def test_stick_slip_edge_cases():
    s = StickSlip()
    # too weak a force: never leaves the start
    tr = s.simulate(A=0.5, x0=0.0, v0=0.0)
    assert (tr.v == 0).all() and (tr.x == 0).all()
    # released from a stretched spring without forcing: slides, then rests inside |k x| ≤ μN
    tr = s.simulate(A=0.0, x0=1.0, v0=0.0)
    assert tr.v[0] == 0.0 and tr.a[0] == pytest.approx(-(1.274 - 0.801))
    assert not s.sticking_mask(tr)[0]
    assert abs(s.k * tr.x[-1]) <= s.mu_N and tr.v[-1] == 0.0
    # the switch guard
    with pytest.raises(SimulationError, match=r"more than 1 times"):
        StickSlip(max_switches=1).simulate()


def test_sticking_mask_needs_velocity(stick_paper):
    with pytest.raises(DataError, match=r"needs the velocity"):
        StickSlip().sticking_mask(stick_paper.replace(v=None, a=None))
    assert not Duffing().sticking_mask(stick_paper).any()


# ---------------------------------------------------------------------- registry
def test_registry():
    assert SYSTEM_NAMES == ("duffing", "stick-slip", "van-der-pol", "first-order", "two-dof")
    # every registered name builds its system, and each names the family that describes it
    families = {name: get_system(name).family for name in SYSTEM_NAMES}
    assert families == {"duffing": "separable", "stick-slip": "separable", "van-der-pol": "position-damping",
                        "first-order": "first-order", "two-dof": "two-dof"}
    assert isinstance(get_system("duffing"), Duffing)
    assert isinstance(get_system("stick_slip"), StickSlip)
    assert isinstance(get_system("Stick-Slip", "smooth"), BenchmarkSystem)
    assert get_system("stick-slip", "scripts").Omega == 0.3
    assert get_system("duffing", "paper", alpha=-1.05).alpha == -1.05


def test_registry_unknown_name():
    with pytest.raises(ConfigError, match=r"unknown system 'vanderpol'; choose one of 'duffing', 'stick-slip', "
                                          r"'van-der-pol', 'first-order', 'two-dof'$"):
        get_system("vanderpol")


def test_cli_simulate_offers_every_registered_system(tmp_path, capsys):
    from charcurves.cli import main

    assert main(["simulate", "vanderpol", "--out", str(tmp_path / "x.csv")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err
    assert "invalid choice: 'vanderpol' (choose from 'duffing', 'stick-slip', 'van-der-pol', 'first-order', " \
           "'two-dof')" in err
    # the names the CLI offers are the registry's, so a newly registered system is simulable at once
    assert main(["simulate", "first-order", "--out", str(tmp_path / "fo.csv"), "--n-points", "50", "--t-end",
                 "5"]) == 0
    assert (tmp_path / "fo.csv").read_text().splitlines()[0] == "t,x,v,a,F"


def test_registry_unknown_variant():
    with pytest.raises(ConfigError, match=r"unknown duffing variant 'smooth'; choose one of 'paper', 'scripts'"):
        get_system("duffing", "smooth")
    with pytest.raises(ConfigError, match=r"'paper', 'smooth', 'scripts'"):
        get_system("stick-slip", "fast")


def test_registry_unknown_parameter():
    with pytest.raises(ConfigError, match=r"unknown duffing parameter\(s\) 'gamma'; valid ones are"):
        get_system("duffing", gamma=1.0)


def test_bad_settings():
    with pytest.raises(ConfigError, match=r"unknown tolerance preset 'loose'"):
        Duffing(tolerance="loose")
    with pytest.raises(ConfigError, match=r"rtol must be positive"):
        Duffing(rtol=0.0)
    with pytest.raises(ConfigError, match=r"alpha must be a finite real number"):
        Duffing(alpha=float("nan"))
    with pytest.raises(ConfigError, match=r"unknown friction law 'viscous'"):
        StickSlip(friction="viscous")
    with pytest.raises(ConfigError, match=r"n_points must be an integer >= 2"):
        Duffing().simulate(n_points=1)
    with pytest.raises(ConfigError, match=r"strictly increasing"):
        Duffing().simulate(t_eval=[0.0, 1.0, 1.0])
