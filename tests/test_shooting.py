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
        return MultiTrajectory(clean.t, clean.states, clean.forces), cc.CharacteristicCurves(
            method="nn-cc", family="two-dof", objective="equation-error", threads=1)
    system, method, kw = {
        "separable": ("duffing", "nn-cc+sym", {"free_gain": True}),
        "position-damping": ("van-der-pol", "poly-cc", {"options": {"degree": 4}}),
        "first-order": ("first-order", "nn-cc", {}),
    }[name]
    s = get_system(system)
    rec = corrupt(s.simulate(n_points=300, t_end=12), 40, on="state", seed=0)
    return rec, cc.CharacteristicCurves(method=method, family=s.family, objective="equation-error", threads=1, **kw)


@pytest.mark.parametrize("family", ["separable", "position-damping", "first-order", "two-dof"])
def test_shooting_jacobian_matches_finite_differences(family, monkeypatch):
    import charcurves.fitting._output_error as oe
    import charcurves.fitting._train as tr

    torch.set_num_threads(1)
    captured = {}
    real = tr.train

    def capture(problem, theta0, **kw):  # the real training, one iteration; keeps the problem it was given
        captured["problem"], captured["theta"] = problem, theta0
        kw["lm_max_iter"] = 1
        return real(problem, theta0, **kw)

    monkeypatch.setattr(tr, "train", capture)
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
    model = cc.CharacteristicCurves(template=cc.Equation(eq), method="poly-cc").fit(measured_duffing).model_
    oe = model.info["output_error"]
    assert oe["status"].startswith("not run: equation 1: x'' enters with the coefficient 3*x''**2 + 1")
    assert model.info["objective"] == "equation-error (output error not possible)"
    assert model.info["warnings"] == ["output error: " + oe["status"]]
    with pytest.raises(cc.ConfigError, match=r"^equation 1: x'' enters with the coefficient 3\*x''\*\*2 \+ 1, which "
                                             r"depends on the data; output error needs constant coefficients$"):
        cc.CharacteristicCurves(template=cc.Equation(eq), method="poly-cc",
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
