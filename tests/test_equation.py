"""User-written templates: the equation parser, gauge freedoms, identifiability errors, and
equivalence of "x'' + f1(x') + f2(x) = F" with the separable family."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from charcurves import CharCurvesError, ConfigError, IdentifiabilityError
from charcurves.fitting import CharacteristicCurves, load_model
from charcurves.templates import EquationTemplate, get_template, parse_equation


def test_parse_separable_equation_gives_curves_arguments_and_gauge():
    t = parse_equation("x'' + f1(x') + f2(x) = F")
    assert t.curve_names == ("f1", "f2")
    assert t.arguments == {"f1": "x'", "f2": "x"}
    assert t.scalar_names == ()
    assert t.gauge_conditions() == ["f2(0) = 0"]
    assert t.gauge_freedoms() == ["a constant c moves between f2 and f1; fixed by f2(0) = 0"]
    # odd curves carry no constant: no freedom, and the equation gets its own free constant
    both_odd = {"f1": True, "f2": True}
    assert t.gauge_conditions(both_odd) == [] and t.offsets_needed(both_odd) == [0]


def test_families_have_the_appendix_a_gauges():
    assert get_template("position-damping").gauge_conditions() == []  # strict uniqueness (A.2)
    assert get_template("first-order").gauge_conditions() == []  # strict uniqueness (A.3)
    two = get_template("two-dof")
    assert two.gauge_conditions() == ["f2(0) = 0", "f4(0) = 0"]  # C1, C2 of A.4
    assert two.arguments == {"f1": "x1'", "f2": "x1 - x2", "f3": "x2'", "f4": "x2 - x1"}
    assert two.states == ("x1", "x2") and two.forces == ("F1", "F2")
    # the gauge can anchor the damping curves instead
    assert get_template("two-dof", gauge="f1,f3").gauge_conditions() == ["f1(0) = 0", "f3(0) = 0"]


def test_scalars_and_several_equations():
    t = parse_equation("x'' + a1*x' + f1(x) = F")
    assert t.scalar_names == ("a1",) and t.curve_names == ("f1",)
    assert t.gauge_conditions() == []
    t2 = parse_equation("x1'' + f1(x1') + f2(x1 - x2) = F1; x2'' + a1*x2' + f3(x2 - x1) = 0")
    assert t2.n_equations == 2 and t2.scalar_names == ("a1",)
    # equation 1: f1 and f2 trade a constant; equation 2's constant sits in f3 alone (no freedom)
    assert t2.gauge_conditions() == ["f2(0) = 0"]
    assert t2.offsets_needed({n: False for n in t2.curve_names}) == []


@pytest.mark.parametrize("text, words", [
    ("x'' + f1(x) + f2(x) = F", ["f1(x) and f2(x)", "merge them"]),
    ("x'' + f1(x') + f2(-x) + f3(2*x + 1) = F", ["f2(-x) and f3(2*x + 1)", "neither is identifiable"]),
    ("x'' + a1*x + f1(x) + f2(x') = F", ["a1*x", "absorbed by f1(x)", "drop a1"]),
    ("x'' + a1*f1(x) = F", ["a1*f1(x)", "drop a1"]),
    ("f1(x) + f2(x') = 0", ["no known term", "scale is not identifiable"]),
])
def test_non_identifiable_templates_raise_naming_terms_and_fix(text, words):
    with pytest.raises(IdentifiabilityError) as err:
        parse_equation(text)
    msg = str(err.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg


def test_scalar_trading_with_curve_constants_depends_on_priors():
    t = parse_equation("x'' + f1(x') + f2(x) + a1 = F")
    with pytest.raises(IdentifiabilityError, match="scalar a1 trades with the constants of .*drop a1"):
        t.check_identifiable({"f1": False, "f2": False})
    t.check_identifiable({"f1": True, "f2": True})  # odd curves: a1 is the only constant, identifiable


@pytest.mark.parametrize("text, message", [
    ("x'' + __import__(\"os\").system(\"ls\") = F", "'__import__' is not allowed"),
    ("x'' + f1(x') = os'", "not a state"),
    ("x'' + f1(x)*f2(x') = F", "product of curves"),
    ("x'' + f1(x)**2 = F", "not linear in f1"),
    ("x''' + f1(x) = F", "order 3"),
    ("x'' + f1 = F", "must be applied"),
    ("x'' + f1(x, x') = F", "univariate"),
    ("x'' + f1(x) + f1(x') = F", "two arguments"),
    ("x'' + f1(a1*x) = F", "contains unknowns"),
    ("x'' + f1(2) = F", "constant argument"),
    ("x'' + f1(x') + f2(x) = F = 0", "exactly one '='"),
    ("x'' + f1(x') = ", "empty side"),
    ("x'' + f1(x) + y = F", "'y' is not allowed"),
    ("F'' + f1(x) = F", "not a state"),
    ("", "empty"),
    ("x'' + 9**9**9**9*f1(x) = F", "too large"),
    ("x'' + (x + x' + F)**100 + f1(x) = F", "too large"),
    ("x'' + x**x + f1(x) = F", "exponents must be numbers"),
    ("x'' + sqrt(-1)*f1(x) = F", "not a finite real number"),
    ("x'' + f1(x') + f2(x) = F/0", "not a finite real number"),
    ("x'' + f1(x) - f1(x) + f2(x') = F", "f1 cancels out"),
])
def test_bad_equations_give_one_line_config_errors(text, message):
    with pytest.raises(ConfigError) as err:
        parse_equation(text)
    assert message in str(err.value) and "\n" not in str(err.value)


def test_gauge_option_must_fix_a_freedom():
    with pytest.raises(ConfigError, match="anchoring f1 at 0 fixes no freedom.*no gauge freedom"):
        get_template("position-damping", gauge="f1")
    with pytest.raises(ConfigError, match="unknown curve 'f9'"):
        get_template("two-dof", gauge="f9")
    with pytest.raises(ConfigError, match="unknown family 'bogus'"):
        get_template("bogus")
    with pytest.raises(ConfigError, match="either a family"):
        get_template("two-dof", equation="x'' + f1(x) = F")


_ATOMS = st.sampled_from(["x", "x'", "x''", "x1", "x2'", "F", "F1", "t", "2", "0.5", "f1(x)", "f2(x')",
                          "f3(x1 - x2)", "a1", "a2*x", "sin(x)", "exp(", "(", ")", "f1", "'", "__import__",
                          "lambda", "=", ";", "import", "os", "[", "]", ".", "\"", "{", "#", "\\", "**", "/0",
                          "sqrt(-1)", "log(0)", "1e400", "9**9**9", "f1(f2(x))", "x1''", "(x+x')**13"])
_OPS = st.sampled_from([" + ", " - ", "*", "/", "**", " = ", "; ", " ", ""])


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(_ATOMS, _OPS), min_size=1, max_size=8))
def test_parser_fuzz_never_tracebacks(parts):
    text = "".join(a + o for a, o in parts)
    try:
        t = parse_equation(text)
    except CharCurvesError as exc:
        assert str(exc) and "\n" not in str(exc)
    else:
        assert isinstance(t, EquationTemplate) and t.curve_names


def _check_parse(text):
    """Either a CharCurvesError whose message is one non-empty line, or a template with curves."""
    try:
        t = parse_equation(text)
    except CharCurvesError as exc:
        message = str(exc)
        assert message.strip(), f"empty message for {text!r}"
        assert len(message.splitlines()) == 1, f"multi-line message for {text!r}: {message!r}"
        return None
    assert isinstance(t, EquationTemplate) and t.curve_names, text
    return t


#: arbitrary text, and a valid equation between whitespace or with arbitrary text after it (so that
#: both branches of the check run: about a third of the inputs parse)
_SPACE = st.text(" \t\n", max_size=3)
_TEXT = st.one_of(st.text(max_size=60),
                  st.builds(lambda a, b: a + "x'' + f1(x') + f2(x) = F" + b, _SPACE,
                            st.one_of(_SPACE, st.text(max_size=8))))


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_TEXT)
def test_parser_fuzz_arbitrary_text(text):
    _check_parse(text)


def test_parser_fuzz_check_can_fail_and_can_pass():
    """The fuzz check above asserts something: a valid equation passes it with its curves, and
    text with control characters and line breaks still gets a one-line message."""
    assert _check_parse("x'' + f1(x') + f2(x) = F").curve_names == ("f1", "f2")
    for text in ("", "\n", "x'' + f1(x)\n= F + \n\r", "x''\r+ f1(\u2028x) = F", "\x00", "f1(x) = f1(x)"):
        assert _check_parse(text) is None, text


# ---------------------------------------------------------------------------------- fitting
def test_separable_equation_gives_the_same_fit_as_the_separable_family(duffing_20db):
    z = np.linspace(-1.2, 1.2, 25)
    text = "x'' + f1(x') + f2(x) = F"
    for method, kw in (("poly-cc", {}), ("nn-cc+sym", {}), ("parametric", {"basis": "f1=z; f2=z, z**3"})):
        a = CharacteristicCurves.from_method(method=method, random_state=0, threads=1, **kw).fit(duffing_20db).model_
        b = CharacteristicCurves.from_method(equation=text, method=method, random_state=0, threads=1, **kw).fit(duffing_20db).model_
        for k in ("f1", "f2"):
            np.testing.assert_allclose(b.curves[k](z), a.curves[k](z), rtol=0, atol=1e-9)
        assert b.loss == pytest.approx(a.loss, rel=1e-9)
        assert b.offset == pytest.approx(a.offset, abs=1e-12)
        # odd curves (nn-cc+sym) and a basis without constants pin both curves: no freedom to fix
        assert b.result_dict()["gauge"] == ("f2(0) = 0" if method == "poly-cc" else "none (no constant to trade)")


def test_equation_with_scalar_recovers_linear_damping(duffing_20db, tmp_path):
    """x'' + a1*x' + f2(x) = F on Duffing: a1 = delta = 0.3 and f2 = -x + x^3."""
    model = CharacteristicCurves.from_method(equation="x'' + a1*x' + f2(x) = F", method="poly-cc",
                                 options={"degree": 5}).fit(duffing_20db).model_
    assert model.info["scalars"]["a1"] == pytest.approx(0.3, abs=0.01)
    x = np.linspace(*model.curves["f2"].domain, 200)
    assert np.sqrt(np.mean((model.curves["f2"](x) - (-x + x**3)) ** 2)) < 0.02
    model.save(tmp_path / "m")  # scalars survive save/load
    back = load_model(tmp_path / "m")
    assert back.info["scalars"] == model.info["scalars"]
    np.testing.assert_array_equal(back.force_residual(duffing_20db), model.force_residual(duffing_20db))
    nn = CharacteristicCurves.from_method(equation="x'' + a1*x' + f2(x) = F", method="nn-cc", threads=1).fit(duffing_20db).model_
    assert nn.info["scalars"]["a1"] == pytest.approx(0.3, abs=0.01)
    assert nn.result_dict()["scalars"]["a1"] == nn.info["scalars"]["a1"]


def test_fit_refuses_scalar_that_trades_with_curve_constants(duffing_20db):
    est = CharacteristicCurves.from_method(equation="x'' + f1(x') + f2(x) + a1 = F", method="poly-cc")
    with pytest.raises(IdentifiabilityError, match="scalar a1"):
        est.fit(duffing_20db)
    # with odd curves a1 is the record's offset, and it is identifiable (Duffing: 0)
    model = CharacteristicCurves.from_method(equation="x'' + f1(x') + f2(x) + a1 = F", method="poly-cc",
                                 symmetry="odd").fit(duffing_20db).model_
    assert abs(model.info["scalars"]["a1"]) < 0.01


def test_separable_only_methods_say_which_families_they_support(duffing_20db):
    with pytest.raises(ConfigError, match="supports the separable family only.*nn-cc"):
        CharacteristicCurves.from_method(family="position-damping", method="sr-cc").fit(duffing_20db)


def test_summary_names_a_user_written_equation_and_a_family(tmp_path, capsys):
    """summary.txt says what was fitted: a user-written equation is not "the separable family"."""
    from charcurves.cli import main

    csv = tmp_path / "d.csv"
    assert main(["simulate", "duffing", "--out", str(csv), "--snr", "30", "--seed", "0"]) == 0
    for args, out, expected in (
        (["--equation", "x'' + f1(x') + f2(x) = F"], "eq", "on a user-written equation: x'' + f1(x') + f2(x) = F"),
        ([], "sep", "on the separable family: x'' + f1(x') + f2(x) = F"),
    ):
        assert main(["fit", str(csv), *args, "--method", "poly-cc", "--out", str(tmp_path / out), "--no-figure",
                     "--quiet"]) == 0
        first = (tmp_path / out / "summary.txt").read_text().splitlines()[0]
        assert first.endswith(expected) and "— poly-cc " in first, first
