"""The Bouc-Wen benchmark generated from its published definition (charcurves.datasets.bouc_wen)."""

from __future__ import annotations

import numpy as np
import pytest

from charcurves._errors import ConfigError
from charcurves.datasets import BENCHMARKS, BOUC_WEN_FS, BOUC_WEN_PARAMETERS, bouc_wen, bouc_wen_output, get_benchmark

SHORT = dict(periods=2, period=1024, sweep_samples=600)


@pytest.fixture(scope="module")
def data():
    return bouc_wen(seed=0, **SHORT)


def test_shapes_sampling_and_split(data):
    assert data.name == "bouc-wen" and data.unit == "m" and data.init_window == 50 and data.literature == {}
    assert list(data.tests) == ["multisine", "sinesweep"]
    assert data.estimation.n_samples == 2048 and data.tests["multisine"].n_samples == 1024
    assert data.tests["sinesweep"].n_samples == 600
    for rec in (data.estimation, *data.tests.values()):
        assert np.allclose(np.diff(rec.t), 1.0 / 750.0, rtol=0, atol=1e-12) and rec.t[0] == 0.0
    assert BOUC_WEN_FS == 750.0
    assert BOUC_WEN_PARAMETERS == {"m": 2.0, "c": 10.0, "k": 5e4, "alpha": 5e4, "beta": 1e3, "gamma": 0.8,
                                   "delta": -1.1, "nu": 1.0}
    u = data.estimation.F
    assert np.array_equal(u[:1024], u[1024:])  # two periods of one realisation
    assert float(np.sqrt(np.mean(u ** 2))) == pytest.approx(50.0, rel=1e-9)  # whole periods: the RMS exactly
    spectrum = np.abs(np.fft.rfft(u))
    freqs = np.fft.rfftfreq(u.size, 1.0 / 750.0)
    inside = (freqs >= 5.0) & (freqs <= 150.0)
    assert spectrum[~inside].max() < 1e-9 * spectrum[inside].max()  # the band 5-150 Hz only
    # the multisine test is another realisation, not the estimation's
    assert abs(np.corrcoef(data.tests["multisine"].F, u[:1024])[0, 1]) < 0.1


def test_the_same_seed_gives_the_same_bytes_another_seed_other_records(data):
    again = bouc_wen(seed=0, **SHORT)
    other = bouc_wen(seed=1, **SHORT)
    assert again.estimation.x.tobytes() == data.estimation.x.tobytes()
    assert again.tests["multisine"].F.tobytes() == data.tests["multisine"].F.tobytes()
    assert not np.allclose(other.estimation.F, data.estimation.F)


def test_free_run_identity_with_an_independent_integrator():
    """The clean record equals scipy's adaptive RK45 (tight tolerances) on the same definition and
    the same input as a function of time, to a small fraction of the response."""
    from scipy.integrate import solve_ivp

    f0, A, n = 12.0, 50.0, 400
    t_fine = np.arange(40 * (n - 1) + 1) / (40 * 750.0)
    s = bouc_wen_output(A * np.sin(2 * np.pi * f0 * t_fine))
    p = BOUC_WEN_PARAMETERS

    def rhs(t, q):
        y, v, z = q
        dz = p["alpha"] * v - p["beta"] * (p["gamma"] * abs(v) * z + p["delta"] * v * abs(z))  # nu = 1
        return [v, (A * np.sin(2 * np.pi * f0 * t) - p["c"] * v - p["k"] * y - z) / p["m"], dz]

    ref = solve_ivp(rhs, (0.0, s["t"][-1]), [0.0, 0.0, 0.0], t_eval=s["t"], rtol=1e-11, atol=1e-14, max_step=1e-3)
    assert np.abs(s["y"]).max() > 5e-4  # a response well into the hysteresis (z of the size of k*y)
    # measured: 3.2e-6 of the largest displacement (RK4 across the kinks of |y'| at the turning points)
    assert np.abs(s["y"] - ref.y[0]).max() < 1e-5 * np.abs(ref.y[0]).max()
    assert np.abs(s["z"] - ref.y[2]).max() < 1e-5 * np.abs(ref.y[2]).max()


def test_the_noise_is_the_stated_standard_deviation():
    clean = bouc_wen(seed=0, noise=0.0, **SHORT)
    noisy = bouc_wen(seed=0, noise=8e-6, **SHORT)
    e = noisy.estimation.x - clean.estimation.x
    assert float(np.std(e)) == pytest.approx(8e-6, rel=0.07)  # 2048 draws: 1.6 % standard error
    assert np.array_equal(noisy.estimation.F, clean.estimation.F)


def test_the_registry_offers_it():
    from charcurves.datasets._registry import _loaders

    assert BENCHMARKS == ("silverbox", "bouc-wen") and _loaders()["bouc-wen"] is bouc_wen
    with pytest.raises(ConfigError, match="unknown real benchmark 'boucwen'; choose one of silverbox, bouc-wen"):
        get_benchmark("boucwen")


@pytest.mark.parametrize("kwargs, message", [
    (dict(periods=0), "periods must be a whole number of at least 1, got 0"),
    (dict(noise=-1.0), "noise must be a standard deviation >= 0"),
    (dict(sweep_samples=10), "sweep_samples must be a whole number of at least 66, got 10"),
    (dict(period=True), "period must be a whole number of at least 66 samples, got True"),
    (dict(band=(400.0, 500.0)), "the multisine band (400.0, 500.0) holds no frequency line"),
])
def test_bad_arguments_are_refused(kwargs, message):
    with pytest.raises(ConfigError, match=message.replace("(", r"\(").replace(")", r"\)")):
        bouc_wen(**kwargs)
