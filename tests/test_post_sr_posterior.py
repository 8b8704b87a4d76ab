"""The posterior of post-SR closed forms' constants: at the least-squares optimum the linearised
problem is the least-squares posterior itself; the gauge of an anchored curve is kept; the ± reach
summary.txt; a closed form the record does not determine warns."""

from __future__ import annotations

import numpy as np
import pytest

import charcurves as cc
from charcurves.curves import SymbolicFittedCurve
from charcurves.fitting import FittedModel, closed_form_lines, closed_form_posterior
from charcurves.systems import get_system
from charcurves.templates import get_template

BASIS = "f1=z; f2=z, z**3"


@pytest.fixture(scope="module")
def record():
    return cc.corrupt(get_system("duffing").simulate(), 20, seed=0)


def _closed(model, exprs, gain=None):
    curves = {nm: SymbolicFittedCurve(nm, c.argument, c.domain, exprs[nm]) for nm, c in model.curves.items()}
    return FittedModel(model.template, "demo", curves, model.gain if gain is None else gain, model.offset, 0.0)


@pytest.mark.parametrize("kind,free_gain,rtol", [("hac", False, 1e-6), ("gauss", False, 1e-6), ("hac", True, 1e-2)])
def test_at_the_least_squares_optimum_it_is_the_linear_posterior(record, kind, free_gain, rtol):
    """Fixed gain: the same problem, the same sds. A free gain divides the coefficients in the least-squares
    fit (the delta method) and is a column of the linearised one: they agree to first order (here to 0.7 %, |g - 1| = 0.005)."""
    fit = cc.fit(record, method="parametric", basis=BASIS, free_gain=free_gain, threads=1)
    closed = _closed(fit, {nm: c.expression() for nm, c in fit.curves.items()})
    post = closed_form_posterior(closed, record).with_kind(kind)
    ref = fit.posterior.with_kind(kind)
    for nm, c in fit.curves.items():
        z = np.linspace(*c.domain, 9)
        assert np.allclose(post.curve_sd(nm, z)[1], ref.curve_sd(nm, z)[1], rtol=rtol, atol=1e-12)
    s, r = post.scalar_stats(), ref.scalar_stats()
    assert sorted(s["names"]) == sorted(r["names"]) == (["gain", "offset"] if free_gain else ["offset"])
    for k in r["names"]:  # the least-squares fit regresses F on the curves (the gain divides): 3 % apart here
        assert s["sd"][k] == pytest.approx(r["sd"][k], rel=rtol if k != "gain" else 0.05)
    assert post.bandwidth == ref.bandwidth


def test_an_anchored_nonlinear_closed_form_keeps_its_gauge(record):
    tpl = get_template("separable")
    curves = {"f1": SymbolicFittedCurve("f1", "x'", (-1.5, 1.5), "0.3*z"),
              "f2": SymbolicFittedCurve("f2", "x", (-1.6, 1.6), "z**3 - z + 0.2*cos(1.1*z) - 0.2")}
    model = FittedModel(tpl, "demo", curves, 1.0, 0.0, 0.0)
    post = closed_form_posterior(model, record)
    assert [p for p in post.params if p[0] == "f2"] == [("f2", "theta0"), ("f2", "theta1")]  # 0.2 and 1.1, not -0.2
    _, sd = post.curve_sd("f2", np.array([0.0, 1.0]))
    assert sd[0] == 0.0 and sd[1] > 1e-3  # f2(0) = 0 is the gauge: no width there
    assert "offset" in post.params  # no curve carries a constant: b does


def test_post_sr_fit_writes_the_constants_with_their_sd(record):
    from charcurves.fitting import distill_model

    fit = cc.fit(record, method="poly-cc", options={"degree": 3}, threads=1)
    model = distill_model(fit, sr_options={"generations": 5}, n=100, traj=record)
    assert type(model.posterior).__name__ == "ClosedFormPosterior"
    lines = closed_form_lines(model)
    assert [ln.split("(z)")[0].strip() for ln in lines] == ["f1", "f2"]
    assert all("±" in ln and ln.endswith("(1 sd, posterior)") for ln in lines)
    assert "\\pm" in model.to_latex(uncertainty=True) and "\\pm" not in model.to_latex()


def test_a_constant_the_record_does_not_determine_warns(record):
    curves = {"f1": SymbolicFittedCurve("f1", "x'", (-1.5, 1.5), "0.3*z"),
              "f2": SymbolicFittedCurve("f2", "x", (-1.6, 1.6), "z**3 - z + 1e-3*tanh(40.0*(z - 7.0))")}
    model = FittedModel(get_template("separable"), "demo", curves, 1.0, 0.0, 0.0)
    post = closed_form_posterior(model, record)
    assert post.warnings() and "does not determine every constant" in post.warnings()[0]


def test_kinked_closed_forms_get_a_posterior_and_a_derivative_numpy_cannot_print_gives_none(record):
    curves = {"f1": SymbolicFittedCurve("f1", "x'", (-1.5, 1.5), "0.3*z + 0.01*sign(z)"),
              "f2": SymbolicFittedCurve("f2", "x", (-1.6, 1.6), "z**3 - z + 0.1*Abs(z - 0.5) - 0.05")}
    model = FittedModel(get_template("separable"), "demo", curves, 1.0, 0.0, 0.0)
    post = closed_form_posterior(model, record)  # Abs' derivative on a real z: sign
    assert post.params == [("f1", "theta0"), ("f1", "theta1"), ("f2", "theta0"), ("f2", "theta1"), "offset"]
    _, sd = post.curve_sd("f2", np.array([0.0, 1.0]))
    assert sd[0] == 0.0 and np.isfinite(sd[1]) and sd[1] > 0
    curves["f2"] = SymbolicFittedCurve("f2", "x", (-1.6, 1.6), "z**3 - z + 0.1*sign(z - 0.5) + 0.1")
    assert closed_form_posterior(FittedModel(get_template("separable"), "demo", curves, 1.0, 0.0, 0.0),
                                 record) is None  # d/dc sign(z - c) = -2 DiracDelta(z - c): no posterior, no error
