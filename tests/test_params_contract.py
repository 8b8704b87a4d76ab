"""One parameter contract (charcurves._params.Params) on every kind of settings object: curves,
templates, differentiators, objectives, method presets and the estimator."""

import warnings

import numpy as np
import pytest

import charcurves as cc
from charcurves import ConfigError
from charcurves.data import SavitzkyGolay, SmoothingSpline, Spectral
from charcurves.fitting import Auto, CharacteristicCurves, MethodPreset, cli_objective

sklearn_base = pytest.importorskip("sklearn.base")


def _objects():
    return {
        "Polynomial": cc.Polynomial(degree=5, symmetry="odd"),
        "Neural": cc.Neural(hidden=(8, 8), symmetry="odd"),
        "Basis": cc.Basis(["z", "z**3"]),
        "Separable": cc.Separable(f1=cc.Polynomial(degree=3), f2=cc.Neural(hidden=(4,)), free_gain=True),
        "Equation": cc.Equation("x'' + a1*x' + f1(x) = F", f1=cc.Polynomial(degree=3)),
        "SavitzkyGolay": SavitzkyGolay(window=21, order=3),
        "SmoothingSpline": SmoothingSpline(lam=0.5),
        "Spectral": Spectral(),
        "EquationError": cc.EquationError(),
        "OutputError": cc.OutputError(segment_length=64, hold="zoh"),
        "Auto": Auto(output_error=cc.OutputError(substeps=2)),
        "MethodPreset": MethodPreset("poly-cc", symmetry="odd", options={"degree": 5}),
        "estimator (objects)": CharacteristicCurves(
            template=cc.Separable(f1=cc.Polynomial(degree=3, symmetry="odd"), f2=cc.Neural()),
            differentiator=SavitzkyGolay(window=31), objective=cc.OutputError(max_iter=5), random_state=4),
        "estimator (from_method)": CharacteristicCurves.from_method("parametric", basis="f1=z; f2=z, z**3",
                                                                    differentiator="spectral", threads=1),
    }


@pytest.mark.parametrize("name", list(_objects()))
def test_clone_and_the_deep_round_trip_keep_every_parameter(name):
    obj = _objects()[name]
    deep = obj.get_params(deep=True)
    twin = sklearn_base.clone(obj)
    assert type(twin) is type(obj) and twin is not obj
    assert twin.get_params(deep=True) == deep
    for key, value in obj.get_params(deep=False).items():  # a copy, not the same parts
        if hasattr(value, "get_params"):
            assert getattr(twin, key) is not value and getattr(twin, key) == value
    rebuilt = type(obj)(**obj.get_params(deep=False))
    assert rebuilt.get_params(deep=True) == deep


def test_nested_names_are_routed_to_the_part_that_owns_them():
    est = _objects()["estimator (objects)"]
    est.set_params(differentiator__window=51, template__f1__degree=5, objective__hold="zoh", random_state=9)
    assert est.differentiator.window == 51 and est.template.f1.degree == 5 and est.objective.hold == "zoh"
    assert est.get_params()["differentiator__window"] == 51 and est.random_state == 9
    preset = CharacteristicCurves.from_method("poly-cc").set_params(method__symmetry="f1=odd", method__options={"degree": 7})
    assert preset.method.symmetry == "f1=odd" and preset.get_params()["method__options"] == {"degree": 7}
    auto = Auto(output_error=cc.OutputError()).set_params(output_error__hold="zoh")
    assert auto.output_error.hold == "zoh"


def test_unknown_and_unroutable_names_say_what_is_valid():
    est = CharacteristicCurves.from_method("poly-cc")
    with pytest.raises(ConfigError) as info:
        est.set_params(learning_rate=1)
    assert str(info.value) == ("CharacteristicCurves has no parameter 'learning_rate'; valid: template, method, "
                               "differentiator, objective, post_sr, preset, random_state, threads, device, progress, "
                               "snr_db")
    with pytest.raises(ConfigError, match=r"^SavitzkyGolay has no parameter 'width'; valid: window, order, mode$"):
        CharacteristicCurves(differentiator=SavitzkyGolay()).set_params(differentiator__width=3)
    with pytest.raises(ConfigError) as info:
        est.set_params(differentiator__window=51)  # a name, not an object: nothing to route to (was sent to the template)
    assert str(info.value) == ("CharacteristicCurves.differentiator is None, which has no parameters of its own; give "
                               "differentiator= an object first (e.g. set_params(differentiator=...)), then "
                               "differentiator__window")
    with pytest.raises(ConfigError, match="^MethodPreset has no parameter 'colour'; valid: name, family, equation"):
        est.set_params(method__colour="red")
    with pytest.raises(ConfigError, match="^OutputError has no parameter 'segments'; valid: segment_length"):
        cc.OutputError().set_params(segments=3)


def test_set_params_of_a_differentiator_checks_the_value_as_its_constructor():
    diff = SavitzkyGolay(window=31)
    with pytest.raises(ConfigError, match="window"):
        diff.set_params(window=30)  # even: the constructor refuses it too
    assert SavitzkyGolay(window=31).set_params(window=np.int64(41)).window == 41


def test_shorthands_that_would_be_ignored_are_refused():
    cases = [
        (dict(method="nn-cc", degree=5), "degree= applies to poly-cc and the SINDy methods, not to method 'nn-cc'"),
        (dict(method="poly-cc", hidden=(8,)), "hidden would be ignored: method 'poly-cc' does not take them"),
        (dict(basis="f1=z; f2=z"), "basis would be ignored: the default method (neural curves) does not take them"),
        (dict(template=cc.Separable(f1=cc.Polynomial(), f2=cc.Neural()), symmetry="odd", hidden=(4,)),
         "symmetry, hidden would be ignored: the template Separable sets them itself"),
        (dict(template=cc.Separable(), family="two-dof"), "family would be ignored: the template Separable sets"),
        (dict(method="poly-cc", template=cc.Separable(f1=cc.Polynomial(), f2=cc.Polynomial()),
              options={"degree": 7, "stick_tol": 0.1}), "options['degree'] would be ignored"),
    ]
    for kwargs, words in cases:
        with pytest.raises(ConfigError) as info:
            CharacteristicCurves.from_method(**kwargs)
        assert words in str(info.value), (kwargs, str(info.value))
    # what a template leaves to the method is not ignored: its unset curves, sticking options
    CharacteristicCurves.from_method("poly-cc", template=cc.Separable(f1=cc.Polynomial()), symmetry="odd",
                                     options={"degree": 7})


def test_the_old_spelling_warns_once_and_builds_the_same_model(duffing_20db):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        old = CharacteristicCurves(method="poly-cc", symmetry="odd", derivatives="given", threads=1, random_state=2)
    ours = [w for w in caught if issubclass(w.category, FutureWarning)]
    assert len(ours) == 1 and "CharacteristicCurves.from_method" in str(ours[0].message)
    assert ours[0].filename == __file__  # attributed to the caller's line
    new = CharacteristicCurves.from_method("poly-cc", symmetry="odd", differentiator="given", threads=1, random_state=2)
    assert old.get_params() == new.get_params()
    z = np.linspace(-1.5, 1.5, 201)
    a, b = old.fit(duffing_20db).model_, new.fit(duffing_20db).model_
    for name in ("f1", "f2"):
        assert np.asarray(a.curves[name](z)).tobytes() == np.asarray(b.curves[name](z)).tobytes()


def test_old_objective_names_become_objective_objects():
    with pytest.warns(FutureWarning, match="from_method"):
        est = CharacteristicCurves(refine="none")
    assert est.objective == "equation-error" and est.method == MethodPreset()
    with pytest.warns(FutureWarning):
        est = CharacteristicCurves(refine="auto", refine_options={"hold": "zoh", "max_nfev": 7})
    assert est.objective == Auto(output_error=cc.OutputError(hold="zoh", max_iter=7))
    assert cli_objective("output-error", None, {"substeps": 2}) == cc.OutputError(substeps=2)
    assert cli_objective(None, None, None) == "auto"
    with pytest.raises(TypeError, match="unexpected keyword argument.*'colour'"):
        CharacteristicCurves(colour="red")


def test_repr_shows_how_to_build_the_estimator_again():
    est = CharacteristicCurves.from_method("poly-cc", symmetry="odd", random_state=3)
    assert repr(est) == "CharacteristicCurves.from_method('poly-cc', symmetry='odd', random_state=3)"
    assert repr(CharacteristicCurves(template=cc.Separable(f1=cc.Neural()))) == \
        "CharacteristicCurves(template=Separable(f1=Neural()))"
    assert CharacteristicCurves.from_method(**est.flat_params()).get_params() == est.get_params()


def test_the_shortcuts_take_the_old_names_with_a_warning(duffing_20db):
    new = cc.fit(duffing_20db, method="poly-cc", differentiator="given", objective="equation-error", threads=1)
    with pytest.warns(FutureWarning, match="derivatives=, refine= is the older spelling"):
        old = cc.fit(duffing_20db, method="poly-cc", derivatives="given", refine="none", threads=1)
    z = np.linspace(-1.0, 1.0, 101)
    assert np.asarray(old.curves["f2"](z)).tobytes() == np.asarray(new.curves["f2"](z)).tobytes()
    assert old.info["settings"] == new.info["settings"]
