"""Output error reopens a network that equation error pruned (objectives/_revive.py)."""

from __future__ import annotations

import numpy as np
import pytest

import charcurves as cc
from charcurves.curves import NeuralCurve, NeuralFittedCurve, jump_log_eps
from charcurves.fitting import OutputError, get_preset, output_error_fit, raw_fit
from charcurves.objectives import _revive
from charcurves.objectives._revive import REVIVE_SCALE, network_spread, revive_pruned_networks
from charcurves.systems import CurveSystem


def test_only_pruned_members_restart_small_and_the_rest_is_kept():
    spec = NeuralCurve(hidden=(4,), symmetry="odd", powers=(3,))
    theta = np.zeros((3, spec.n_params))
    theta[1] = np.linspace(-1.0, 1.0, spec.n_params)  # a live network
    sl = spec.slices()
    theta[:, sl["linear"]] = 0.7
    theta[:, sl["poly"]] = -0.2
    new, rows = revive_pruned_networks(spec, theta, seed=3)
    assert rows.tolist() == [True, False, True]
    np.testing.assert_array_equal(new[1], theta[1])
    # the parts beside the network and the output bias are kept
    np.testing.assert_array_equal(new[:, sl["linear"]], theta[:, sl["linear"]])
    np.testing.assert_array_equal(new[:, sl["poly"]], theta[:, sl["poly"]])
    n_mlp = spec.mlp.n_params
    assert new[0, n_mlp - 1] == 0.0
    # the output weights are the initialisation's times REVIVE_SCALE: the curve hardly moves
    spread = network_spread(spec, new)
    assert spread[1] > 0.1 and 0 < spread[0] < 10 * REVIVE_SCALE and 0 < spread[2] < 10 * REVIVE_SCALE
    # the same seed gives the same restart
    again, _ = revive_pruned_networks(spec, theta, seed=3)
    np.testing.assert_array_equal(again, new)


@pytest.fixture(scope="module")
def pruned_sinh():
    """x'' + 0.1 x' + 0.05 x'^3 + 0.5 sinh(2 x) = F, 40 dB on x; a quick nn-cc fit with a cubic beside
    each network, whose f2 network is then zeroed, as equation error's evidence leaves it when the
    cubic takes over: f2 is its linear and cubic terms alone, which cannot hold sinh's x^5."""
    system = CurveSystem("separable", {"f1": lambda v: 0.1 * v + 0.05 * v**3, "f2": lambda x: 0.5 * np.sinh(2 * x)},
                         forcing=[(1.2, 1.2), (0.6, 2.2)], initial=(0.0, 0.0))
    clean = system.simulate(t_end=40.0, n_points=600)
    measured = cc.corrupt(clean, 40, on="state", seed=0)
    preset = get_preset("default").replace(n_starts=1, powers=(3,), harmonics=())
    est = cc.CharacteristicCurves.from_method(method="nn-cc", preset=preset, random_state=0, threads=1)
    [model], [prepared] = raw_fit(est, [measured])
    f2 = model.curves["f2"]
    theta = f2.theta.copy()
    theta[:, :f2.spec.mlp.n_params] = 0.0
    model.curves["f2"] = NeuralFittedCurve(f2.name, f2.argument, f2.domain, f2.spec, theta, f2.in_scale,
                                           f2.out_scale, f2.shift)
    sigma = float(np.std(np.asarray(measured.x) - np.asarray(clean.x)))
    return model, prepared, measured, preset, sigma


def _refit(pruned_sinh):
    model, prepared, measured, preset, sigma = pruned_sinh
    new = output_error_fit(model, prepared, measured, OutputError(segment_length=32, substeps=2, max_iter=40),
                           preset=preset)
    return new.info["output_error"], sigma


def test_output_error_revives_a_pruned_network_and_reaches_the_noise(pruned_sinh):
    oe, sigma = _refit(pruned_sinh)
    assert oe["status"] == "ok" and oe["networks_revived"].get("f2") == 1
    assert oe["segmented_rmse_before"] > 2 * sigma
    assert oe["segmented_rmse_after"] < 1.2 * sigma, oe["segmented_rmse_after"] / sigma


def test_without_the_revival_the_pruned_network_stays_off_the_noise(pruned_sinh, monkeypatch):
    monkeypatch.setattr(_revive, "PRUNED_SPREAD", -1.0)  # nothing counts as pruned
    oe, sigma = _refit(pruned_sinh)
    assert oe["networks_revived"] == {}
    assert oe["segmented_rmse_after"] > 2 * sigma, oe["segmented_rmse_after"] / sigma


def test_a_smooth_jump_keeps_the_width_equation_error_found():
    """tanh friction (width 1/3 of a unit velocity) fitted with a learned jump: output error trains
    it at the width equation error profiled and hands that width back, not Coulomb's sign."""
    system = CurveSystem("separable", {"f1": lambda v: 0.1 * v + 0.5 * np.tanh(3 * v), "f2": lambda x: x},
                         forcing=[(1.2, 1.1), (0.6, 2.1)], initial=(0.0, 0.0))
    measured = cc.corrupt(system.simulate(t_end=40.0, n_points=600), 40, on="state", seed=0)
    preset = get_preset("default").replace(n_starts=1, powers=(), harmonics=())
    est = cc.CharacteristicCurves.from_method(method="nn-cc", preset=preset, jump=["f1"], random_state=0, threads=1)
    [model], [prepared] = raw_fit(est, [measured])
    new = output_error_fit(model, prepared, measured, OutputError(segment_length=32, substeps=2, max_iter=10),
                           preset=preset)
    assert new.info["output_error"]["status"] == "ok"
    sl = model.curves["f1"].spec.slices()["jump_log_eps"]
    eps_ee = float(np.exp(jump_log_eps(model.curves["f1"].theta[0, sl]))[0])
    eps_oe = float(np.exp(jump_log_eps(new.curves["f1"].theta[0, sl]))[0])
    assert eps_ee > 0.01  # in units of the scaled velocity: a smooth saturation, far above RK4's floor
    assert eps_oe == eps_ee
