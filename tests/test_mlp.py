"""The batched MLP and neural curves: analytic Jacobians against autograd, exact symmetry."""

import numpy as np
import pytest
import torch

from charcurves.curves import NeuralCurve
from charcurves.curves._mlp import ACTIVATIONS, BatchedMLP


@pytest.mark.parametrize("activation", sorted(ACTIVATIONS))
@pytest.mark.parametrize("hidden", [(5,), (4, 3)])
def test_mlp_jacobian_matches_autograd(activation, hidden):
    mlp = BatchedMLP(hidden, activation)
    gen = torch.Generator().manual_seed(0)
    theta = mlp.init(3, gen)
    u = torch.linspace(-1.3, 1.1, 17, dtype=torch.float64)
    y, J = mlp.forward_jacobian(theta, u)
    assert torch.allclose(y, mlp.forward(theta, u), atol=1e-14)
    for k in range(3):
        Jref = torch.autograd.functional.jacobian(lambda th: mlp.forward(th.unsqueeze(0), u)[0], theta[k])
        assert torch.allclose(J[k], Jref, atol=1e-10), activation


@pytest.mark.parametrize(
    "symmetry,jump", [("none", False), ("odd", False), ("even", False), ("none", True), ("odd", True)]
)
def test_curve_jacobian_matches_autograd(symmetry, jump):
    spec = NeuralCurve(hidden=(6,), symmetry=symmetry, jump=jump)
    theta = spec.init(2, torch.Generator().manual_seed(1))
    theta[:, -1] = np.log(0.2) if jump else theta[:, -1]
    if jump:
        theta[:, spec.slices()["jump_height"]] = 0.7
    u = torch.linspace(-1, 1, 11, dtype=torch.float64)
    y, J = spec.evaluate_jacobian(theta, u)
    assert torch.allclose(y, spec.evaluate(theta, u), atol=1e-14)
    Jref = torch.autograd.functional.jacobian(lambda th: spec.evaluate(th.unsqueeze(0), u)[0], theta[0])
    assert torch.allclose(J[0], Jref, atol=1e-10)


def test_exact_symmetry_holds_for_any_weights():
    u = torch.linspace(-1, 1, 101, dtype=torch.float64)
    for seed in range(5):
        gen = torch.Generator().manual_seed(seed)
        odd = NeuralCurve(hidden=(7,), symmetry="odd", jump=True)
        th = odd.init(1, gen) * 3
        assert torch.allclose(odd.evaluate(th, u), -odd.evaluate(th, -u), atol=1e-14)
        assert float(odd.evaluate(th, torch.zeros(1, dtype=torch.float64))) == 0.0
        even = NeuralCurve(hidden=(7,), symmetry="even")
        th = even.init(1, gen) * 3
        assert torch.allclose(even.evaluate(th, u), even.evaluate(th, -u), atol=1e-14)


def test_curve_settings_are_validated():
    from charcurves import ConfigError

    with pytest.raises(ConfigError, match="jump at 0 is odd"):
        NeuralCurve(symmetry="even", jump=True)
    with pytest.raises(ConfigError, match="unknown symmetry 'sideways'"):
        NeuralCurve(symmetry="sideways")
    with pytest.raises(ConfigError, match="unknown activation"):
        NeuralCurve(activation="sigmoidish")


def test_paper_network_size():
    # the paper: 2 (2 n^2 + 5 n + 1) parameters for two n-wide, 3-hidden-layer networks
    n = 100
    spec = NeuralCurve(hidden=(n, n, n), activation="relu", linear_term=False)
    assert 2 * spec.n_params == 2 * (2 * n * n + 5 * n + 1) == 41002


def test_numpy_evaluation_of_fitted_curves_matches_torch():
    # simulation evaluates networks with numpy; training used torch: both must agree
    from charcurves.curves import NeuralFittedCurve

    for act in sorted(ACTIVATIONS):
        for sym, jump in (("none", False), ("odd", True), ("even", False)):
            spec = NeuralCurve(hidden=(5,), activation=act, symmetry=sym, jump=jump)
            theta = spec.init(3, torch.Generator().manual_seed(2)).numpy() * 2
            curve = NeuralFittedCurve("f1", "x'", (-1, 1), spec, theta, in_scale=1.7, out_scale=0.3, shift=0.1)
            z = np.linspace(-2, 2, 41)
            assert np.allclose(curve.raw(z), curve.raw_torch(z), rtol=1e-12, atol=1e-13), (act, sym)
