"""The evidence sweeps of output error (`train/_evidence.py`) on a linear problem, where the
linearised problem is the problem: the sweeps must reach MacKay's fixed point in one call, prune the
coefficients the data do not support, leave network groups alone, and the guard must restore what
it saved."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from charcurves.curves import Basis, LinearParametrisation
from charcurves.train._evidence import EVIDENCE_GUARD, EvidenceSweeps, evidence_update, initial_decay
from charcurves.objectives._output_error import _Ridge
from charcurves.train._problem import BatchedProblem, CurveTerm

BASIS = "z, z**2, z**3, z**4, z**5, z**6, z**7"
TRUE = np.array([1.0, 0.0, -0.5, 0.0, 0.0, 0.0, 0.0])  # f(z) = z - z^3 / 2: five spare terms


class _WithLayer(_Ridge):
    """Output error's relevance groups (one per coefficient), but the last two coefficients form one
    group labelled as a network layer."""

    def decay_groups(self) -> list:
        n = int(self.n_params) - 2
        return super().decay_groups()[:n] + [(slice(n, n + 2), "layer 1")]


def _problem(network=False, K=2, N=400, noise=0.01, seed=0):
    gen = np.random.default_rng(seed)
    u = gen.uniform(-1.5, 1.5, size=(K, N))
    phi = np.stack([u ** k for k in range(1, 8)], axis=-1)
    f = phi @ TRUE
    F = gen.normal(size=(K, N))
    y = F - f + noise * gen.normal(size=(K, N))  # y + f(u) - F = noise
    t = lambda a: torch.as_tensor(a, dtype=torch.float64)  # noqa: E731
    param = (_WithLayer if network else _Ridge)(LinearParametrisation(Basis(BASIS)))
    prob = BatchedProblem([CurveTerm(param, t(u))], t(y), t(F), torch.full((K, N), N ** -0.5, dtype=torch.float64),
                          bayesian=True, decay_groups="per-layer")
    prob.scaled_initial_decay = True
    return prob


def _least_squares(prob):
    JtJ, g, _, _ = prob.normal_equations(torch.zeros(prob.K, prob.n_params, dtype=torch.float64))
    return -torch.linalg.solve(JtJ, g)


def _settled(prob, n=50):
    theta = _least_squares(prob)
    prob.set_weight_decay(initial_decay(prob, theta, (prob.K, prob.n_decay_groups)))
    sweeps = EvidenceSweeps(theta, n)
    normal = prob.normal_equations(theta)
    JtJ, g, _ = sweeps.settle(prob, theta, normal, torch.ones(prob.K, dtype=torch.bool))
    star = theta - torch.cholesky_solve(g.unsqueeze(-1), torch.linalg.cholesky(JtJ)).squeeze(-1)
    return prob, sweeps, theta, normal, JtJ, star


def test_the_sweeps_reach_the_fixed_point_and_prune_the_spare_terms():
    prob, sweeps, _, normal, JtJ, star = _settled(_problem())
    lam = prob.decay_per_group(prob.K)
    # every relevant coefficient keeps a decay far below every spare one's (ARD)
    relevant, spare = lam[:, [0, 2]], lam[:, [1, 3, 4, 5, 6]]
    assert float(spare.min() / relevant.max()) > 1e4, lam
    # at the decays the sweeps left, the solution of the (linear) problem is the truth to the noise's
    # level and the spare terms are pruned to nothing
    assert np.allclose(star[:, [0, 2]].numpy(), [[1.0, -0.5]] * 2, atol=2e-3), star
    assert float(star[:, [1, 3, 4, 5, 6]].abs().max()) < 1e-4, star
    # a fixed point: one more evidence update at that solution moves no decay by 1 % (the sweeps' stop)
    before = lam.clone()
    new, _ = evidence_update(prob, star, JtJ, normal[3])
    assert float((new.log() - before.log()).abs().max()) < 1e-2
    # the guard has saved the point it was given and the decays before the sweeps
    assert sweeps.saved is not None and torch.equal(sweeps.saved[0], _least_squares(prob))
    assert torch.isfinite(sweeps.ref).all() and not sweeps.off.any()


def test_one_sweep_is_a_single_evidence_update():
    """n = 1 leaves the decays where one MacKay update puts them: far from the pruned fixed point."""
    prob, *_ = _settled(_problem(), n=1)
    one = prob.decay_per_group(prob.K)
    full, *_ = _settled(_problem(), n=50)
    spare = [1, 3, 4, 5, 6]
    assert float((full.decay_per_group(2)[:, spare] / one[:, spare]).min()) > 10.0


def test_network_groups_are_never_swept():
    prob = _problem(network=True)
    theta = _least_squares(prob)
    start = initial_decay(prob, theta, (prob.K, prob.n_decay_groups))
    prob.set_weight_decay(start)
    assert prob.relevance_groups.tolist() == [True] * 5 + [False]
    EvidenceSweeps(theta, 50).settle(prob, theta, prob.normal_equations(theta), torch.ones(2, dtype=torch.bool))
    lam = prob.decay_per_group(2)
    assert torch.equal(lam[:, 5], start[:, 5])  # the "layer" group keeps its decay
    assert float(lam[:, [1, 3]].min() / lam[:, [0, 2]].max()) > 1e4  # the coefficients were swept


@pytest.mark.parametrize("factor, undone", [(1.0 + 0.9 * EVIDENCE_GUARD, False), (1.0 + 1.1 * EVIDENCE_GUARD, True)])
def test_the_guard_restores_a_model_whose_data_loss_rose(factor, undone):
    prob, sweeps, theta, normal, _, _ = _settled(_problem())
    saved_theta, saved_lam = sweeps.saved[0].clone(), sweeps.saved[1].clone()
    moved_theta = theta + 0.01
    lam_after = prob.decay_per_group(2).clone()
    # model 0's next step raised its data loss by `factor`; model 1's did not move
    data = normal[3].clone()
    data[0] = sweeps.ref[0] * factor
    fake = (normal[0], normal[1], normal[2], data)
    out, _, bad = sweeps.guard(prob, moved_theta, fake, torch.tensor([True, False]))
    assert bad.tolist() == [undone, False]
    if undone:
        assert torch.equal(out[0], saved_theta[0]) and torch.equal(out[1], moved_theta[1])
        assert torch.equal(prob.decay_per_group(2)[0], saved_lam[0])
        assert torch.equal(prob.decay_per_group(2)[1], lam_after[1])
        assert sweeps.off.tolist() == [True, False]
        # an undone model takes no more sweeps: settle leaves its decays alone
        before = prob.decay_per_group(2).clone()
        sweeps.settle(prob, out, prob.normal_equations(out), torch.tensor([True, False]))
        assert torch.equal(prob.decay_per_group(2), before)
    else:
        assert torch.equal(out, moved_theta) and not sweeps.off.any()


def test_output_error_training_ends_a_model_only_once_its_decays_stay_put():
    """In output error (a stop window) an accepted step that gains nothing ends a model only if its
    evidence update left every decay within ``SWEEP_TOL`` (in log): a moved decay opens new ground.
    With one evidence update per step (``evidence_sweeps=1``) the spare decays of this record's second
    model still move by about 1.2 % when its steps have stopped gaining; training goes on until one
    more update moves none by more than 1 %."""
    from charcurves.train._evidence import SWEEP_TOL, set_evidence, with_decay
    from charcurves.train._train import train

    prob = _problem(noise=0.05, seed=1)
    theta, log = train(prob, torch.zeros(prob.K, prob.n_params, dtype=torch.float64), adam_steps=0, adam_lr=0.0,
                       lm_max_iter=60, lm_tol=1e-6, stop_loss=0.0, lm_window=4, evidence_sweeps=1)
    assert log.stopped_by == "stall" and log.lm_iterations < 60
    normal = prob.normal_equations(theta)
    JtJ, _, _ = with_decay(prob, theta, normal)
    move = set_evidence(prob, theta, JtJ, normal[3], torch.ones(prob.K, dtype=torch.bool))
    assert float(move.max()) < SWEEP_TOL, move
    assert np.allclose(theta[:, [0, 2]].numpy(), [[1.0, -0.5]] * 2, atol=2e-2)  # the noise (5 %) allows this
