"""Noise models: SNR conversion, noise size, reproducibility, corruption of trajectories."""

from __future__ import annotations

import math

import numpy as np
import pytest

from charcurves._errors import ConfigError, DataError
from charcurves.data import Trajectory, add_noise, corrupt, noise_sigma, snr_to_eta

N_BIG = 100_000


@pytest.fixture
def traj() -> Trajectory:
    t = np.linspace(0.0, 40.0, 1000)
    x = np.sin(t) + 0.2
    return Trajectory(t=t, x=x, F=0.5 * np.cos(1.2 * t), v=np.cos(t), a=-np.sin(t), name="demo")


@pytest.mark.parametrize(("snr", "eta"), [(40, 0.01), (20, 0.1), (0, 1.0), (-20, 10.0), (6, 0.501187)])
def test_snr_to_eta(snr, eta):
    assert snr_to_eta(snr) == pytest.approx(eta, rel=1e-6)


def test_snr_to_eta_inf_is_zero():
    assert snr_to_eta(math.inf) == 0.0
    assert snr_to_eta(np.inf) == 0.0


@pytest.mark.parametrize("snr", [40.0, 20.0, 0.0, -10.0])
def test_measured_noise_std_matches_eta_sigma(snr):
    clean = np.sin(np.linspace(0.0, 200.0 * np.pi, N_BIG))
    noisy = add_noise(clean, snr, rng=1)
    expected = snr_to_eta(snr) * clean.std()
    assert np.std(noisy - clean) == pytest.approx(expected, rel=0.02)
    assert abs(np.mean(noisy - clean)) < 4 * expected / math.sqrt(N_BIG)


def test_rms_and_std_reference_differ_by_the_mean():
    clean = 3.0 + np.sin(np.linspace(0.0, 200.0 * np.pi, N_BIG, endpoint=False))
    s_std = noise_sigma(clean, 20, "std")
    s_rms = noise_sigma(clean, 20, "rms")
    assert s_std == pytest.approx(0.1 * math.sqrt(0.5), rel=1e-6)
    assert s_rms == pytest.approx(0.1 * math.sqrt(9.5), rel=1e-6)
    noisy = add_noise(clean, 20, rng=2, reference="rms")
    assert np.std(noisy - clean) == pytest.approx(s_rms, rel=0.02)
    # zero-mean signal: both references agree
    z = clean - clean.mean()
    assert noise_sigma(z, 20, "rms") == pytest.approx(noise_sigma(z, 20, "std"), rel=1e-9)


def test_scripts_forcing_convention():
    # σ_n² = mean(F²) / 10^(SNR/10) as in the authors' scripts
    t = np.linspace(0.0, 40.0, 1000)
    F = 2.0 * np.cos(0.3 * t)
    assert noise_sigma(F, 13.0, "rms") ** 2 == pytest.approx(np.mean(F**2) / 10 ** 1.3, rel=1e-12)


def test_seeded_reproducibility():
    clean = np.linspace(-1.0, 1.0, 500)
    a = add_noise(clean, 10, rng=7)
    b = add_noise(clean, 10, rng=7)
    c = add_noise(clean, 10, rng=8)
    d = add_noise(clean, 10, rng=np.random.default_rng(7))
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(a, d)
    assert np.abs(a - c).max() > 1e-3


def test_generator_stream_advances():
    gen = np.random.default_rng(3)
    clean = np.linspace(-1.0, 1.0, 100)
    first, second = add_noise(clean, 10, gen), add_noise(clean, 10, gen)
    assert np.abs(first - second).max() > 1e-3


def test_inf_snr_returns_unchanged_copy():
    clean = np.linspace(-1.0, 1.0, 50)
    out = add_noise(clean, math.inf, rng=0)
    np.testing.assert_array_equal(out, clean)
    assert out is not clean
    out[0] = 99.0
    assert clean[0] == -1.0


def test_shape_kept():
    clean = np.arange(12.0).reshape(3, 4)
    assert add_noise(clean, 10, rng=0).shape == (3, 4)


def test_corrupt_force(traj):
    noisy = corrupt(traj, 20, on="force", seed=0)
    assert isinstance(noisy, Trajectory) and noisy.name == "demo"
    np.testing.assert_array_equal(noisy.x, traj.x)
    np.testing.assert_array_equal(noisy.v, traj.v)
    np.testing.assert_array_equal(noisy.a, traj.a)
    np.testing.assert_array_equal(noisy.t, traj.t)
    eps = noisy.F - traj.F
    assert np.std(eps) == pytest.approx(0.1 * traj.F.std(), rel=0.15)  # 1000 samples: ±~5 %
    np.testing.assert_array_equal(corrupt(traj, 20, seed=0).F, noisy.F)  # "force" is the default
    # the rms reference of the scripts uses the same draws, scaled by rms/std
    rms = corrupt(traj, 20, seed=0, reference="rms")
    ratio = math.sqrt(np.mean(traj.F**2)) / traj.F.std()
    np.testing.assert_allclose(rms.F - traj.F, eps * ratio, rtol=1e-9, atol=1e-15)


def test_corrupt_state_drops_derivatives(traj):
    noisy = corrupt(traj, 10, on="state", seed=1)
    assert noisy.v is None and noisy.a is None
    assert not noisy.has_derivatives
    np.testing.assert_array_equal(noisy.F, traj.F)
    assert np.std(noisy.x - traj.x) == pytest.approx(snr_to_eta(10) * traj.x.std(), rel=0.15)


def test_corrupt_inf_keeps_everything(traj):
    same = corrupt(traj, math.inf, on="force", seed=0)
    np.testing.assert_array_equal(same.F, traj.F)
    state = corrupt(traj, math.inf, on="state", seed=0)
    np.testing.assert_array_equal(state.x, traj.x)
    assert state.v is None


@pytest.mark.parametrize("bad", [float("nan"), np.nan])
def test_nan_snr_message(bad):
    with pytest.raises(ConfigError, match=r"snr_db is NaN; pass a number of decibels"):
        add_noise(np.ones(3) * [1, 2, 3], bad, rng=0)


@pytest.mark.parametrize("bad", ["20", None, True, [20]])
def test_non_numeric_snr_message(bad):
    with pytest.raises(ConfigError, match=r"snr_db must be a real number of decibels"):
        snr_to_eta(bad)


def test_minus_inf_snr_message():
    with pytest.raises(ConfigError, match=r"-inf"):
        snr_to_eta(-math.inf)


def test_unknown_target_lists_valid(traj):
    with pytest.raises(ConfigError, match=r"unknown noise target on='velocity'; choose one of 'force', 'state'"):
        corrupt(traj, 20, on="velocity", seed=0)


def test_unknown_reference_lists_valid(traj):
    with pytest.raises(ConfigError, match=r"unknown noise reference 'var'; choose one of 'std', 'rms'"):
        corrupt(traj, 20, seed=0, reference="var")


def test_state_noise_refuses_rms(traj):
    with pytest.raises(ConfigError, match=r"standard deviation of x"):
        corrupt(traj, 20, on="state", seed=0, reference="rms")


def test_bad_rng_message():
    with pytest.raises(ConfigError, match=r"rng must be a numpy.random.Generator or an integer seed, got float"):
        add_noise(np.arange(5.0), 20, rng=1.5)


def test_constant_signal_message():
    with pytest.raises(DataError, match=r"constant.*reference='rms'"):
        add_noise(np.full(10, 2.0), 20, rng=0)
    # the rms reference is defined for a non-zero constant
    assert noise_sigma(np.full(10, 2.0), 20, "rms") == pytest.approx(0.2)


def test_non_finite_signal_message():
    with pytest.raises(DataError, match=r"NaN or infinite"):
        add_noise(np.array([1.0, np.nan]), 20, rng=0)


def test_corrupt_needs_trajectory():
    with pytest.raises(DataError, match=r"needs a Trajectory"):
        corrupt(np.arange(3.0), 20)
