"""Long records: normal equations over chunks of samples, the two-stage fit (subset, then all
samples), and the Levenberg-Marquardt stop at convergence."""

import numpy as np
import pytest
import torch

import charcurves as cc
from charcurves.curves import Neural, Polynomial
from charcurves.data import corrupt
from charcurves.fitting import PRESETS
from charcurves.train import _long_record, _problem
from charcurves.train._problem import BatchedProblem, CurveTerm, LeastSquaresProblem
from charcurves.train._train import train
from charcurves.metrics import curve_errors


def _problem_for(n: int, *, penalty: bool = False, seed: int = 0) -> tuple[BatchedProblem, torch.Tensor]:
    """A two-curve problem (an odd network with a jump, and a polynomial) over ``n`` samples of
    3 models, with per-sample weights, a multiplier, a free gain, a constant and Bayesian decay."""
    g = torch.Generator().manual_seed(seed)
    preset = PRESETS["default"].replace(symmetry_mode="penalty") if penalty else PRESETS["default"]
    net = Neural(symmetry="odd").network(preset, jump=True)
    poly = Polynomial(degree=3).parametrisation(preset)
    K = 3
    u1 = torch.rand(K, n, generator=g, dtype=torch.float64) * 2 - 1
    u2 = torch.rand(K, n, generator=g, dtype=torch.float64) * 2 - 1
    mult = 1 + 0.5 * torch.rand(K, n, generator=g, dtype=torch.float64)
    sym = torch.linspace(-1, 1, 50, dtype=torch.float64).expand(K, -1) if penalty else None
    y = torch.randn(K, n, generator=g, dtype=torch.float64)
    F = torch.randn(K, n, generator=g, dtype=torch.float64)
    used = (torch.rand(K, n, generator=g) > 0.1).to(torch.float64)
    w = used / used.sum(1, keepdim=True).sqrt()
    prob = BatchedProblem([CurveTerm(net, u1, None, sym), CurveTerm(poly, u2, mult, None)], y, F, w,
                          free_gain=True, bias=True, lambda_sym=10.0 if penalty else 0.0, weight_decay=0.0,
                          bayesian=True, decay_groups="per-layer")
    prob.set_weight_decay(torch.rand(K, prob.n_decay_groups, generator=g, dtype=torch.float64) * 1e-3)
    parts = [net.init(K, g, torch.float64), poly.init(K, g, torch.float64), torch.ones(K, 1, dtype=torch.float64),
             torch.zeros(K, 1, dtype=torch.float64)]
    return prob, torch.cat(parts, dim=1)


@pytest.mark.parametrize("penalty", [False, True])
def test_chunked_normal_equations_equal_those_of_the_whole_jacobian(monkeypatch, penalty):
    prob, theta = _problem_for(5000, penalty=penalty)
    whole = LeastSquaresProblem.normal_equations(prob, theta)  # from the full Jacobian
    monkeypatch.setattr(_problem, "CHUNK_BYTES", 3 * prob.n_params * 8 * 700)  # 1024-sample chunks
    assert len(prob._chunks()) == 5
    chunked = prob.normal_equations(theta)
    for a, b in zip(whole, chunked):
        assert torch.allclose(a, b, rtol=1e-12, atol=1e-14)
    # the chunked losses equal the sums of squares of the whole residual vector
    r = prob.residuals(theta)
    assert torch.allclose(prob.loss(theta), r.pow(2).sum(1), rtol=1e-12)
    assert torch.allclose(prob.data_loss(theta), r[:, :5000].pow(2).sum(1), rtol=1e-12)
    # and the decay's share completes them: JtJ + diag(w2), cost + decay cost = the full system
    rf, Jf = prob.residuals_jacobian(theta)
    w2, cost_d = prob.decay_terms(theta)
    JtJ = chunked[0].clone()
    JtJ[:, prob.decay_index, prob.decay_index] += w2
    assert torch.allclose(JtJ, Jf.transpose(1, 2) @ Jf, rtol=1e-12, atol=1e-14)
    assert torch.allclose(chunked[2] + cost_d, rf.pow(2).sum(1), rtol=1e-12)


def test_subset_indices_cover_the_record_one_per_stretch():
    idx = _long_record.subset_indices(100_000, 4096, seed=3)
    assert idx.shape == (4096,) and np.all(np.diff(idx) > 0) and idx[0] >= 0 and idx[-1] < 100_000
    edges = np.linspace(0, 100_000, 4097)
    assert np.all((idx >= np.floor(edges[:-1])) & (idx < np.ceil(edges[1:])))
    assert np.array_equal(idx, _long_record.subset_indices(100_000, 4096, seed=3))
    other = _long_record.subset_indices(100_000, 4096, seed=4)
    assert (other != idx).mean() > 0.9


def test_sample_subset_is_the_problem_on_those_samples():
    prob, theta = _problem_for(3000)
    idx = torch.as_tensor(np.stack([_long_record.subset_indices(3000, 500, s) for s in range(3)]))
    small = prob.sample_subset(idx)
    # each model's used samples of the subset, as a mean: the residual of sample j is the full
    # problem's residual of sample idx[k, j], rescaled by sqrt(n_used / n_used_subset)
    full = prob.residuals(theta)[:, :3000] / prob.weights.clamp_min(1e-300)
    part = small.residuals(theta)[:, :500] / small.weights.clamp_min(1e-300)
    used = small.weights > 0
    assert torch.allclose(part[used], torch.gather(full, 1, idx)[used], rtol=1e-12)
    assert torch.allclose(small.n_used, used.sum(1).double())


def test_levenberg_marquardt_stops_at_convergence_and_a_restart_gains_nothing():
    prob, theta = _problem_for(2000)
    preset = dict(adam_steps=0, adam_lr=1e-2, lm_tol=1e-7, stop_loss=1e-12)
    th, log = train(prob, theta, lm_max_iter=300, **preset)
    assert log.stopped_by == "stall" and log.lm_iterations < 120, log.lm_iterations
    # converged: LM from there, with the decay it ended with, stops within the three steps the
    # stall rule needs (refused steps that rounding alone refuses count: without that rule the
    # damping grows to its cap over ~30 refused steps) and gains nothing above the tolerance
    before = float(prob.loss(th).sum())
    again, log2 = train(prob, th, lm_max_iter=300, keep_decay=True, **preset)
    assert log2.lm_iterations <= 4 and log2.stopped_by == "stall"
    assert 0 <= before - float(prob.loss(again).sum()) <= 3 * 1e-7 * before


@pytest.fixture(scope="module")
def long_duffing():
    system = cc.get_system("duffing")
    clean = system.simulate(t_end=240.0, n_points=6000)
    return system, corrupt(clean, 20.0, on="force", seed=1)


def test_two_stage_fit_reaches_the_whole_record_optimum(monkeypatch, long_duffing):
    """A 6000-sample record, trained in two stages (a 1500-sample subset, then all samples) and in
    one stage on all samples: the same optimum (the curves agree to far below their error)."""
    system, rec = long_duffing
    preset = PRESETS["default"].replace(n_starts=2, adam_steps=60, lm_max_iter=60)
    monkeypatch.setattr(_long_record, "SUBSET_SAMPLES", 1500)
    two = cc.fit(rec, method="nn-cc+sym", preset=preset, random_state=0, threads=1)
    monkeypatch.setattr(_long_record, "SUBSET_SAMPLES", 10**9)
    one = cc.fit(rec, method="nn-cc+sym", preset=preset, random_state=0, threads=1)
    assert two.info["long_record"]["subset_samples"] == 1500 and "long_record" not in one.info
    # the refinement starts near the whole record's optimum and stops on its own (a stall), in 4-5 LM
    # iterations on noise seeds 1-3 (measured); one that ran to its budget of 60 would fail here
    assert two.info["stopped_by"] == "stall" and two.info["long_record"]["refine_iterations"] <= 10
    assert two.loss == pytest.approx(one.loss, rel=1e-5)
    errs = curve_errors(two, system.true_curves())
    assert errs["f1"] < 2e-3 and errs["f2"] < 2e-3, errs  # 6x the paper's 1000 samples at 20 dB
    for name in ("f1", "f2"):
        z = two.curves[name].grid(41)
        assert np.max(np.abs(two.curves[name](z) - one.curves[name](z))) < 0.05 * errs[name], name


def test_batched_adam_is_torch_adam_bit_for_bit():
    from charcurves.train._train import BatchedAdam

    g = torch.Generator().manual_seed(0)
    A = torch.randn(4, 7, 7, generator=g, dtype=torch.float64)
    b = torch.randn(4, 7, generator=g, dtype=torch.float64)
    start = torch.randn(4, 7, generator=g, dtype=torch.float64)
    ours, ref = start.clone().requires_grad_(True), start.clone().requires_grad_(True)
    opt_ours, opt_ref = BatchedAdam(ours, lr=1e-2), torch.optim.Adam([ref], lr=1e-2)
    for _ in range(60):
        for p, opt in ((ours, opt_ours), (ref, opt_ref)):
            opt.zero_grad(set_to_none=True)
            ((A @ p.unsqueeze(-1)).squeeze(-1) - b).pow(2).sum().backward()
            opt.step()
    assert torch.equal(ours.detach(), ref.detach())
    assert not torch.equal(ours.detach(), start)
