"""The composition API: representations, templates and objectives as objects, mixed in one fit."""

from __future__ import annotations

import importlib.util
import os

import numpy as np
import pytest

import charcurves as cc
from charcurves import ConfigError
from charcurves.data import corrupt
from charcurves.metrics import curve_errors
from charcurves.systems import get_system

EXAMPLES = os.path.join(os.path.dirname(__file__), os.pardir, "examples")


@pytest.fixture(scope="module")
def duffing():
    system = get_system("duffing")
    return system, corrupt(system.simulate(), 30, seed=0)


def test_issue_acceptance_mixed_representations_save_and_reload(tmp_path, duffing):
    """A polynomial f1 beside a neural f2, Savitzky-Golay derivatives: fits, saves, reloads."""
    system, record = duffing
    est = cc.CharacteristicCurves(template=cc.Separable(f1=cc.Polynomial(degree=3, symmetry="odd"),
                                                        f2=cc.Neural(symmetry="odd")),
                                  differentiator=cc.SavitzkyGolay(window=31, order=3), objective="equation-error",
                                  threads=1)
    model = est.fit(record.replace(v=None, a=None)).model_
    assert model.curves["f1"].kind == "basis" and model.curves["f2"].kind == "neural"
    errs = curve_errors(model, system.true_curves())
    # SG 31/3 flattens x'' at the paper's sampling (docs/differentiators.md): measured 3.3e-3 / 4.2e-2
    assert errs["f1"] < 5e-3 and errs["f2"] < 6.5e-2, errs
    model.save(tmp_path / "m")
    back = cc.load_model(tmp_path / "m")
    z = np.linspace(-1, 1, 31)
    for name in ("f1", "f2"):
        np.testing.assert_allclose(back.curves[name](z), model.curves[name](z), rtol=0, atol=1e-12)
    settings = model.info["settings"]
    assert settings["curves"]["f1"] == "Polynomial(degree=3, symmetry='odd')"
    assert settings["differentiator"].startswith("SavitzkyGolay(window=31, order=3")


#: normalised-RMSE bounds per arrangement, 1.5x the worst measured over noise seeds 1-3 (nn/poly:
#: f1 1.11e-3, f2 5.7e-4; poly/nn: f1 2.31e-3, f2 3.1e-4). Before a polynomial without a constant
#: column got its own constant in the gradient fit, nn/poly's f2 was 2.2e-2 (pinned at its centre)
#: and poly/nn's f1 0.89 (it could not hold f1(0) = -1 as the factor of x').
MIXED_BOUNDS = {"nn/poly": {"f1": 1.7e-3, "f2": 9e-4}, "poly/nn": {"f1": 3.5e-3, "f2": 5e-4}}


@pytest.mark.parametrize("arrangement", ["nn/poly", "poly/nn"])
def test_issue_acceptance_user_equation_with_mixed_curves(arrangement):
    """``Equation("x'' + f1(x)*x' + f2(x) = F", f1=Neural(), f2=Polynomial(degree=5))`` (and the
    other way round) on a position-damping record (Van der Pol type: f1 = x^2 - 1, f2 = x + x^3/2)."""
    system = get_system("van-der-pol")
    record = corrupt(system.simulate(), 30, seed=1)
    first, second = (cc.Neural(), cc.Polynomial(degree=5)) if arrangement == "nn/poly" else \
        (cc.Polynomial(degree=5), cc.Neural())
    template = cc.Equation("x'' + f1(x)*x' + f2(x) = F", f1=first, f2=second)
    model = cc.CharacteristicCurves(template=template, threads=1).fit(record).model_
    truth = system.true_curves()
    for name, curve in model.curves.items():
        z = curve.grid(400)
        nrmse = np.sqrt(np.mean((curve(z) - truth[name](z)) ** 2)) / np.std(truth[name](z))
        assert nrmse < MIXED_BOUNDS[arrangement][name], (name, nrmse)
    assert model.template.family == "custom"


def test_method_presets_build_the_same_objects(duffing):
    """``method="poly-cc"`` is a shorthand for Polynomial curves: the same fit to the last bit."""
    _, record = duffing
    a = cc.CharacteristicCurves.from_method(method="poly-cc").fit(record).model_
    b = cc.CharacteristicCurves(template=cc.Separable(f1=cc.Polynomial(), f2=cc.Polynomial())).fit(record).model_
    z = np.linspace(-1, 1, 21)
    for name in ("f1", "f2"):
        np.testing.assert_array_equal(a.curves[name](z), b.curves[name](z))


def test_nested_parameters_follow_the_scikit_learn_contract():
    est = cc.CharacteristicCurves(template=cc.Separable(f1=cc.Neural(hidden=(8,)), f2=cc.Polynomial(degree=5)))
    params = est.get_params(deep=True)
    assert params["template__f1__hidden"] == (8,) and params["template__f2__degree"] == 5
    est.set_params(template__f1__hidden=(16, 16), template__f2__degree=7, random_state=3)
    assert est.template.f1.hidden == (16, 16) and est.template.f2.degree == 7 and est.random_state == 3
    with pytest.raises(ConfigError, match="Separable has no parameter 'f3'"):
        est.set_params(template__f3__degree=2)
    with pytest.raises(ConfigError, match="Polynomial has no parameter 'width'"):
        est.set_params(template__f2__width=2)
    clone = cc.CharacteristicCurves(**est.get_params(deep=False))
    assert clone.get_params(deep=True) == est.get_params(deep=True)


def test_bad_compositions_say_what_to_fix(duffing):
    _, record = duffing
    with pytest.raises(ConfigError, match="Symbolic curves are found by symbolic regression and cannot be mixed"):
        cc.CharacteristicCurves(template=cc.Separable(cc.Symbolic(), cc.Neural())).fit(record)
    with pytest.raises(ConfigError, match="poly-cc degree must be an integer from 1 to 30"):
        cc.CharacteristicCurves(template=cc.Separable(cc.Polynomial(degree=0), cc.Neural())).fit(record)
    with pytest.raises(ConfigError, match="curve f1 must be a representation"):
        cc.CharacteristicCurves(template=cc.Separable(f1="neural")).fit(record)
    with pytest.raises(ConfigError, match="the equation has curves f1, f2, but a representation was given for f3"):
        cc.CharacteristicCurves(template=cc.Equation("x'' + f1(x') + f2(x) = F", f3=cc.Neural())).fit(record)
    with pytest.raises(ConfigError, match="template must be a template object"):
        cc.CharacteristicCurves(template="separable").fit(record)


def test_a_user_written_representation_plugs_into_every_objective(tmp_path, duffing):
    """The example of docs/architecture.md (examples/custom_curve.py): radial basis functions as a
    LinearCurve work by least squares, beside a neural curve, by output error, and reload."""
    spec = importlib.util.spec_from_file_location("custom_curve", os.path.join(EXAMPLES, "custom_curve.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    errors = module.main(str(tmp_path / "rbf"))
    assert errors["f1"] < 2e-3 and errors["f2"] < 2.5e-2, errors  # measured 6.6e-4 and 1.1e-2
    system, record = duffing
    mixed = cc.CharacteristicCurves(template=cc.Separable(f1=cc.Neural(symmetry="odd"), f2=module.RadialBasis(15)),
                                    threads=1).fit(record).model_
    assert mixed.curves["f2"].kind == "linear"
    assert curve_errors(mixed, system.true_curves())["f2"] < 2.5e-2
    measured = corrupt(system.simulate(), 40, on="state", seed=0)
    oe = cc.CharacteristicCurves(template=cc.Separable(f1=cc.Polynomial(degree=1, symmetry="odd"),
                                                       f2=module.RadialBasis(15)),
                                 objective="output-error").fit(measured).model_
    assert oe.info["output_error"]["status"] == "ok"
    assert oe.info["output_error"]["segmented_rmse_after"] < 0.7 * oe.info["output_error"]["segmented_rmse_before"]
    # fifteen overlapping radial basis functions: the evidence sweeps' fixed point on the linearised problem
    # prunes terms the free run needs (the next step raised the data loss 6000-fold, and without the guard
    # the fit ended "the free run did not improve"); the guard undoes them and the member goes on stepwise
    assert oe.info["output_error"]["evidence_sweeps_undone"] == 1
    assert curve_errors(oe, system.true_curves())["f1"] < 1e-3


def test_a_saved_linear_curve_rebuilds_only_a_registered_representation():
    """The table of loadable representations (curves/_loadable.py): a model file names the class, and
    only a class given to register_curve is rebuilt; a representation nested in another cannot be saved."""
    import torch

    from charcurves import ModelFileError
    from charcurves.curves import LinearCurve, LinearFittedCurve, Polynomial, curve_from_spec, register_curve

    class Ramp(LinearCurve):  # f(u) = c u
        def __init__(self, inner=None):
            self.inner = inner

        def features(self, u):
            return torch.stack([u], dim=-1)

    curve = LinearFittedCurve("f2", "x", (-2.0, 2.0), Ramp(), np.array([3.0]), 0.0, 2.0)
    spec, arrays = curve.to_spec()
    assert spec["representation"] == "Ramp" and spec["parameters"] == {"inner": None}
    with pytest.raises(ModelFileError, match="'Ramp', which is not registered in this process"):
        curve_from_spec(spec, arrays)
    assert register_curve(Ramp) is Ramp
    again = curve_from_spec(spec, arrays)
    assert type(again.representation) is Ramp
    assert float(again(1.0)) == float(curve(1.0)) == 1.5  # 3 * (1 - 0) / 2
    nested = LinearFittedCurve("f2", "x", (-2.0, 2.0), Ramp(inner=Polynomial(degree=1)), np.array([3.0]))
    with pytest.raises(ModelFileError, match="curve f2: nested representations cannot be saved"):
        nested.to_spec()
    with pytest.raises(ConfigError, match="register_curve takes a LinearCurve subclass"):
        register_curve(Polynomial(degree=1))
