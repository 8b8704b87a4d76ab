"""The multiple-shooting problem of output error: its exact RK4 sensitivities against central
finite differences, for every family's forward model (the first-order family divides by a curve)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

import charcurves as cc
from charcurves.data import MultiTrajectory, corrupt, estimate_derivatives
from charcurves.fitting import OutputError, get_preset, raw_fit
from charcurves.systems import get_system
from charcurves.templates import ForwardModel, get_template


def _case(name):
    if name == "two-dof":
        clean = get_system("two-dof").simulate(n_points=300, t_end=12)
        return MultiTrajectory(clean.t, clean.states, clean.forces), cc.CharacteristicCurves.from_method(
            method="nn-cc", family="two-dof", objective="equation-error", threads=1)
    system, method, kw = {
        "separable": ("duffing", "nn-cc+sym", {"free_gain": True}),
        "position-damping": ("van-der-pol", "poly-cc", {"options": {"degree": 4}}),
        "first-order": ("first-order", "nn-cc", {}),
    }[name]
    s = get_system(system)
    rec = corrupt(s.simulate(n_points=300, t_end=12), 40, on="state", seed=0)
    return rec, cc.CharacteristicCurves.from_method(method=method, family=s.family, objective="equation-error", threads=1, **kw)


@pytest.mark.parametrize("family", ["separable", "position-damping", "first-order", "two-dof"])
def test_shooting_jacobian_matches_finite_differences(family, monkeypatch):
    import charcurves.objectives._output_error as oe

    torch.set_num_threads(1)
    captured = {}
    real = oe.train

    def capture(problem, theta0, **kw):  # the real training, one iteration; keeps the problem it was given
        captured["problem"], captured["theta"] = problem, theta0
        kw["lm_max_iter"] = 1
        return real(problem, theta0, **kw)

    monkeypatch.setattr(oe, "train", capture)  # where output error looks it up
    rec, est = _case(family)
    models, prepared = raw_fit(est, [rec], [0])
    oe.output_error_fit(models[0], prepared[0], rec, OutputError(segment_length=40, continuity=3.0),
                        preset=get_preset("default"))
    p, th = captured["problem"], captured["theta"].double()
    r, J = p.residuals_jacobian(th)
    worst = 0.0
    cols = np.random.default_rng(0).choice(th.shape[1], 12, replace=False)
    for col in cols:
        e = torch.zeros_like(th)
        e[:, col] = 1e-6
        fd = (p.residuals(th + e) - p.residuals(th - e)) / 2e-6
        worst = max(worst, float((fd - J[:, :, col]).abs().max() / (fd.abs().max() + 1e-9)))
    assert worst < 1e-5, worst


def test_first_order_forward_model_divides_by_the_curve_factor():
    fm = ForwardModel(get_template("first-order"))
    assert fm.divides and fm.A_inv is None and fm.layout == ["x"] and fm.top == ["x__d1"]
    assert set(fm.equations[0]["mult_top"]) == {"f2"} and "f2" not in fm.equations[0]["mult"]
    sep = ForwardModel(get_template("separable"))
    assert not sep.divides and sep.A_inv == [[1.0]]


@pytest.fixture(scope="module")
def measured_duffing():
    return corrupt(get_system("duffing").simulate(n_points=400, t_end=16), 40, on="state", seed=0)


def test_a_template_output_error_cannot_simulate_falls_back_or_fails_in_one_line(measured_duffing):
    eq = "x'' + f1(x') + f2(x) + x''**3 = F"
    model = cc.CharacteristicCurves.from_method(template=cc.Equation(eq), method="poly-cc").fit(measured_duffing).model_
    oe = model.info["output_error"]
    assert oe["status"].startswith("not run: equation 1: x'' enters with the coefficient 3*x''**2 + 1")
    assert model.info["objective"] == "equation-error (output error not possible)"
    assert model.info["warnings"] == ["output error: " + oe["status"]]
    with pytest.raises(cc.ConfigError, match=r"^equation 1: x'' enters with the coefficient 3\*x''\*\*2 \+ 1, which "
                                             r"depends on the data; output error needs constant coefficients$"):
        cc.CharacteristicCurves.from_method(template=cc.Equation(eq), method="poly-cc",
                                objective="output-error").fit(measured_duffing)


def test_a_start_whose_free_run_diverges_keeps_the_equation_error_model(measured_duffing):
    from charcurves.curves import SymbolicFittedCurve
    from charcurves.fitting import FittedModel

    curves = {"f1": SymbolicFittedCurve("f1", "x'", (-2, 2), "0.3*z"),
              "f2": SymbolicFittedCurve("f2", "x", (-2, 2), "-40*z**3")}  # x'' = 40 x^3: blows up
    start = FittedModel(get_template("separable"), "test", curves, 1.0, 0.0, 1.0)
    prepared = estimate_derivatives(measured_duffing, "spectral")
    out = cc.fitting.output_error_fit(start, prepared, measured_duffing, OutputError(segment_length=200),
                                      preset=get_preset("default"))
    assert out is start and out.info["output_error"]["status"].startswith("failed: the free run")
    assert out.info["objective"] == "equation-error (output error failed)"


@pytest.mark.parametrize("basis, folds", [(["1", "z", "z**3"], 0), (["z**3", "1"], 1), (["z", "z**3"], None)])
@pytest.mark.parametrize("center, half", [(0.0, 1.0), (0.3, 2.0)])
def test_free_run_curve_values_carry_the_shift_in_the_constant_coefficient(basis, folds, center, half):
    """The free run's per-stage curve values (CurveBlock.evaluator) equal shift + out * param((u - c) / h);
    a polynomial with a constant monomial and no output scale carries the shift in that coefficient."""
    from charcurves.curves import Basis, LinearParametrisation
    from charcurves.objectives._shooting import CurveBlock, _constant_column

    param = LinearParametrisation(Basis(basis))
    col = lambda v: torch.full((2, 1), v, dtype=torch.float64)  # noqa: E731
    theta = torch.tensor([[0.5, -1.0, 2.0][:len(basis)], [1.5, 0.25, -0.75][:len(basis)]], dtype=torch.float64)
    u = torch.linspace(-2, 2, 7, dtype=torch.float64).expand(2, 7)
    assert _constant_column(param) == folds
    for out, shift in ((1.0, 0.037), (1.0, 0.0), (3.0, 0.037)):
        blk = CurveBlock("f", param, col(center), col(half), col(out), col(shift))
        expected = shift + out * param.evaluate(theta, (u - center) / half)
        got = blk.evaluator(theta)(u)
        assert torch.allclose(got, expected, rtol=0, atol=1e-14), (out, shift)
        assert torch.equal(theta, torch.tensor([[0.5, -1.0, 2.0][:len(basis)], [1.5, 0.25, -0.75][:len(basis)]],
                                               dtype=torch.float64))  # the caller's parameters untouched


class _Quantised:
    """Least squares ``A theta - b`` with residuals rounded to 1e-6: near the optimum a step changes the
    loss by rounding only, and the trial is refused (counts every trial the trainer makes)."""

    def __init__(self):
        from charcurves.train._problem import LeastSquaresProblem

        g = torch.Generator().manual_seed(0)
        self.A = torch.randn(50, 4, generator=g, dtype=torch.float64)
        self.b = torch.randn(50, generator=g, dtype=torch.float64)
        self.problem = type("Q", (LeastSquaresProblem,), {
            "residuals": lambda s, th: torch.round((th @ self.A.T - self.b) * 1e6) / 1e6,
            "residuals_jacobian": lambda s, th: (s.residuals(th), self.A.expand(th.shape[0], *self.A.shape)),
            "loss": lambda s, th: self._record(s.residuals(th).pow(2).sum(1)),
        })()
        p = self.problem
        p.y, p.n_data, p.n_params = self.b.new_zeros(1, 50), 50, 4
        p.n_used = torch.full((1,), 50.0, dtype=torch.float64)
        p.decay_index, p.decay_group, p.weight_decay = None, None, 0.0
        self.costs: list = []

    def _record(self, c):
        self.costs.append(float(c[0]))
        return c


def _train_quantised(theta0, window):
    from charcurves.train._train import train

    q = _Quantised()
    theta, log = train(q.problem, theta0, adam_steps=0, adam_lr=0.0, lm_max_iter=50, lm_tol=1e-6, stop_loss=0.0,
                       lm_window=window)
    return q, theta, log


def test_output_error_training_stops_at_the_first_step_that_gains_nothing():
    """With a stop window (output error), an accepted step that lowered the loss by less than the
    tolerance, where the linear model predicted no more (MINPACK's ftol test), ends the member at
    once: two trials from zero (each one free run in output error), where the window took two more;
    the parameters are the last step's. Without a window (equation error) the rule of three stalls
    is unchanged."""
    q, theta, log = _train_quantised(torch.zeros(1, 4, dtype=torch.float64), 4)
    assert log.stopped_by == "stall" and log.lm_iterations == 2 and len(q.costs) == 2, q.costs
    assert 0 < q.costs[0] - q.costs[1] < 1e-6 * q.costs[0]  # the second step gained by rounding only
    assert float(q.problem.loss(theta)[0]) == q.costs[1]
    exact = torch.linalg.lstsq(q.A, q.b).solution
    assert float((theta[0] - exact).abs().max()) < 1e-5
    q, _, log = _train_quantised(torch.zeros(1, 4, dtype=torch.float64), 0)
    assert log.lm_iterations == 4 and len(q.costs) == 4, q.costs


def test_output_error_training_stops_at_the_first_step_refused_by_rounding():
    """Started next to the optimum, the first step is refused because its loss changed by rounding
    only, and the linear model says it cannot gain more than the tolerance: the member ends at once
    (one trial, where filling the window took three more free runs) and keeps its parameters."""
    exact = torch.linalg.lstsq(_Quantised().A, _Quantised().b).solution
    start = (exact + 1e-7).view(1, -1)
    q, theta, log = _train_quantised(start.clone(), 4)
    assert log.stopped_by == "stall" and log.lm_iterations == 1 and len(q.costs) == 1, q.costs
    assert q.costs[0] > float(q.problem.loss(start)[0])  # refused...
    assert torch.equal(theta, start)  # ...and the start is kept


@pytest.mark.parametrize("basis", [["1", "z", "z**2", "z**3", "z**10"], ["z", "z**3", "z**5"], ["1"], ["z**2", "1"]])
def test_monomial_basis_features_and_derivatives_from_one_power_table(basis):
    """Plain monomials (the bases output error gives polynomials and libraries) take all their powers
    from one cumulative product: the columns z^k and k z^(k-1) in the basis' order, finite at z = 0
    (the constant's derivative is 0, not 0 * z^-1)."""
    from charcurves.curves import Basis

    b = Basis(basis)
    powers = b.monomial_powers()
    assert powers == tuple(0 if f == "1" else (1 if f == "z" else int(f[3:])) for f in basis)
    u = torch.tensor([[-1.5, -0.2, 0.0, 0.7, 2.0]], dtype=torch.float64)
    phi, dphi = b.features(u), b.feature_derivatives(u)
    assert phi.shape == dphi.shape == (1, 5, len(basis))
    expected = torch.stack([u**k for k in powers], dim=-1)
    d_expected = torch.stack([k * u ** max(k - 1, 0) for k in powers], dim=-1)
    assert torch.allclose(phi, expected, rtol=1e-14, atol=0) and torch.allclose(dphi, d_expected, rtol=1e-14, atol=0)
    assert bool(torch.isfinite(dphi).all())
    assert [float(d) for d in dphi[0, 2]] == [1.0 if k == 1 else 0.0 for k in powers]  # at z = 0


def test_output_error_settles_the_evidence_of_spare_terms_in_few_steps(monkeypatch):
    """A polynomial curve's spare terms are pruned by the evidence (automatic relevance determination).
    One MacKay update per Levenberg-Marquardt step moved each spare term's decay by a bounded factor,
    so output error spent some twenty steps (one free run each) after fitting the record; iterating
    the evidence on the linearised problem once the record is fitted (``EVIDENCE_SWEEPS``) ends in
    under half the steps with the same curves, the true Duffing terms kept and the others at zero."""
    import charcurves.objectives._output_error as oe
    from charcurves.metrics import curve_errors

    torch.set_num_threads(1)
    system = get_system("duffing")
    rec = corrupt(system.simulate(n_points=400, t_end=16), 40, on="state", seed=1)
    fits, default = {}, oe.EVIDENCE_SWEEPS
    for sweeps in (default, 0):
        monkeypatch.setattr(oe, "EVIDENCE_SWEEPS", sweeps)
        fits[sweeps] = cc.CharacteristicCurves.from_method(method="poly-cc", objective="auto", random_state=0, threads=1).fit(rec).model_
    settled, stepwise = fits[default], fits[0]
    its = settled.info["output_error"]["iterations"], stepwise.info["output_error"]["iterations"]
    assert default > 0 and its[0] <= 0.5 * its[1], its
    assert settled.info["output_error"]["evidence_sweeps_undone"] == 0
    for model in (settled, stepwise):
        errors = curve_errors(model, system.true_curves())
        assert max(errors.values()) < 1e-3, errors  # equation error on this record: about 2e-2
    z = np.linspace(-1.5, 1.5, 61)
    for name in ("f1", "f2"):
        assert np.abs(settled.curves[name](z) - stepwise.curves[name](z)).max() < 1e-6
    coef = dict(zip(settled.info["output_error"]["parameters"], settled.info["output_error"]["coefficients_after"]))
    kept = {"f1:z": 0.3, "f2:z": -1.0, "f2:z**3": 1.0}  # the true curves: 0.3 v and -x + x^3
    for label, value in coef.items():
        if label in kept:
            assert abs(value - kept[label]) < 3e-3, (label, value)
        elif label.startswith(("f1:", "f2:")):
            assert abs(value) < 1e-4, (label, value)


@pytest.mark.parametrize("family, relevance", [("separable", False), ("position-damping", True)])
def test_only_single_coefficients_are_relevance_groups(family, relevance, monkeypatch):
    """The evidence sweeps of output error touch the decays of single coefficients (a polynomial's
    terms: automatic relevance determination), never a network's weight groups: iterated on the
    linearised problem those settled at decays that held van der Pol fits far from the record."""
    import charcurves.objectives._output_error as oe

    torch.set_num_threads(1)
    captured = {}
    real = oe.train

    def capture(problem, theta0, **kw):
        captured["problem"] = problem
        kw["lm_max_iter"] = 1
        return real(problem, theta0, **kw)

    monkeypatch.setattr(oe, "train", capture)  # where output error looks it up
    rec, est = _case(family)
    models, prepared = raw_fit(est, [rec], [0])
    oe.output_error_fit(models[0], prepared[0], rec, OutputError(segment_length=40), preset=get_preset("default"))
    p = captured["problem"]
    labels = [label for _, label in p.decay_group_parts]
    assert p.relevance_groups.tolist() == [relevance] * len(labels), labels
    if relevance:  # van der Pol's two degree-4 polynomials: one group per coefficient
        assert len(labels) == sum(b.n_params for b in p.blocks) and p.n_decay_groups == len(labels)
    else:
        assert any(label.startswith("layer") for label in labels)
