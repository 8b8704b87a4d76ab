"""Notebook views of a fitted model: closed forms to the precision a fit supports, to_sympy/to_latex,
plot(ax=...), _repr_html_ with an inline PNG (issue 24, items 2 and 5)."""

import base64
import io
import re

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402
import pytest  # noqa: E402
import sympy as sp  # noqa: E402

import charcurves as cc  # noqa: E402
from charcurves import ConfigError  # noqa: E402
from charcurves.curves import SymbolicFittedCurve  # noqa: E402
from charcurves.fitting import (FittedModel, display_expression, equation_text, format_closed_form,  # noqa: E402
                                plot_curves)
from charcurves.templates import get_template  # noqa: E402

Z = sp.Symbol("z")
# the example: fifteen digits and a 1e-17 term, as a basis fit prints them
NOISY_F2 = "-1.27e-17*z**10 + 1.000000001*z**3 - 0.999999999*z"


def hand_model(f1="0.299654627958613*z", f2=NOISY_F2, gain=1.0, offset=0.0):
    curves = {"f1": SymbolicFittedCurve("f1", "x'", (-1.0, 1.0), f1),
              "f2": SymbolicFittedCurve("f2", "x", (-1.5, 1.5), f2)}
    return FittedModel(get_template("separable", free_gain=gain != 1.0), "test", curves, gain, offset, 0.0)


@pytest.fixture(scope="module")
def neural_model(duffing_20db):
    return cc.fit(duffing_20db, method="nn-cc", random_state=0)


def test_display_rounds_to_four_digits_and_drops_terms_below_that_precision():
    assert display_expression("-1.27e-17*z**10 + 0.999999999*z**2 - 1.000000001", (-1.5, 1.5)) == Z**2 - 1
    assert format_closed_form("0.299654627958613*z", (-1, 1), argument="x'") == "0.2997*x'"
    # the threshold is relative to the curve's size over its range: 2e-4 of it is kept, 5e-5 is dropped
    assert format_closed_form("2e-4*z + 1", (-1, 1)) == "0.0002*z + 1"
    assert format_closed_form("5e-5*z + 1", (-1, 1)) == "1"
    # a small coefficient on a large power is not small where the data are: kept
    assert format_closed_form("1e-3*z**10 + z", (-2, 2)) == "0.001*z**10 + z"
    # without a range nothing is dropped, only rounded
    assert format_closed_form("1e-9*z + 1.23456*z**2") == "1.235*z**2 + 1.0e-9*z"
    assert format_closed_form("0.123456*z", (-1, 1), digits=2) == "0.12*z"
    with pytest.raises(ValueError, match="digits"):
        display_expression("z", digits=0)


def test_to_sympy_gives_curves_and_equation_and_keeps_every_digit(tmp_path):
    model = hand_model(gain=2.0, offset=0.05)
    exact = model.to_sympy(curves=True)
    assert set(exact) == {"f1", "f2"}
    assert exact["f2"].coeff(Z, 10) == pytest.approx(-1.27e-17)  # the stored model keeps all terms
    shown = model.to_sympy(curves=True, digits=4)
    assert sp.simplify(shown["f2"] - (Z**3 - Z)) == 0 and str(shown["f1"]) == "0.2997*z"
    eq = model.to_sympy()
    t = sp.Symbol("t")
    x = sp.Function("x")(t)
    assert eq.rhs == 2.0 * sp.Function("F")(t)
    assert eq.lhs.has(sp.Derivative(x, (t, 2))) and eq.lhs.coeff(x**10) == pytest.approx(-1.27e-17)
    latex = model.to_latex()
    assert "0.2997" in latex and "0.05" in latex and "10^{-17}" not in latex and "x^{10}" not in latex
    assert "\\frac{d^{2}}{d t^{2}}" in latex and "2 F" in latex
    assert "10^{-17}" in model.to_latex(digits=None)
    model.save(tmp_path / "m")  # save/load keeps every digit too
    again = cc.load_model(tmp_path / "m")
    assert again.to_sympy(curves=True)["f2"].coeff(Z, 10) == pytest.approx(-1.27e-17)


def test_negligible_constant_is_dropped_but_a_real_one_kept():
    assert equation_text(hand_model(offset=1e-17)) == "x'' + 0.2997*x' + (x**3 - x) = F"
    assert equation_text(hand_model(gain=2.0, offset=-0.05)) == "x'' + 0.2997*x' + (x**3 - x) - 0.05 = 2*F"
    assert equation_text(hand_model(f1="-0.5*z")) == "x'' - 0.5*x' + (x**3 - x) = F"
    assert "0.05" not in hand_model(offset=1e-17).to_latex()


def test_neural_curves_have_no_closed_form_and_the_error_names_the_fix(neural_model):
    for call in (neural_model.to_sympy, neural_model.to_latex, lambda: neural_model.to_sympy(curves=True)):
        with pytest.raises(ConfigError) as err:
            call()
        message = str(err.value)
        assert "f1 (neural)" in message and "post_sr=True" in message and "--method nn-cc+post-sr" in message
    assert equation_text(neural_model) is None


def _png_images(page: str) -> list[bytes]:
    return [base64.b64decode(m) for m in re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', page)]


def test_repr_html_shows_closed_forms_statistics_and_an_inline_png(duffing_20db):
    model = cc.fit(duffing_20db, method="parametric", basis="f1=z; f2=z, z**3")
    page = model._repr_html_().replace("&#x27;", "'")
    c1 = float(model.curves["f1"].coefficients[0])
    assert f"f1(x') = {c1:.4g}*x'" in page  # the stored coefficient, to 4 significant digits
    assert str(model.curves["f1"].expression()).split("*")[0] not in page  # not the 15-digit number
    assert f"{model.loss:.4g}" in page and "x'' + f1(x') + f2(x) = F" in page
    (png,) = _png_images(page)
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    image = matplotlib.image.imread(io.BytesIO(png), format="png")
    assert image.shape[:2] == (200, 528)  # 2 panels of 3.3 x 2.5 inches at 80 dpi
    assert image[..., :3].std() > 0.05  # something is drawn


def test_repr_html_of_a_neural_model_says_how_to_get_a_closed_form(neural_model):
    page = neural_model._repr_html_()
    assert page.count("no closed form; distil it with post_sr=True") == 2
    assert len(_png_images(page)) == 1


def test_plot_returns_axes_with_the_curves_and_the_truth(duffing, duffing_20db):
    import matplotlib.pyplot as plt

    system, _ = duffing
    model = cc.fit(duffing_20db, method="parametric", basis="f1=z; f2=z, z**3")
    axes = model.plot(truth="duffing")
    assert len(axes) == 2 and [a.get_ylabel() for a in axes] == ["f1(x')", "f2(x)"]
    for ax, name in zip(axes, ("f1", "f2")):
        fitted, truth = ax.get_lines()[:2]
        assert truth.get_label() == "truth"
        z, y = fitted.get_data()
        assert np.allclose(y, model.curves[name](z))
        assert np.allclose(truth.get_ydata(), system.true_curves()[name](z))
    assert axes[0].get_title() == f"f1(x') = {float(model.curves['f1'].coefficients[0]):.4g}*x'"
    plt.close(axes[0].figure)
    fig, ax = plt.subplots()
    assert model.plot(ax=ax) is ax  # one Axes for every curve, each labelled with its name
    assert [ln.get_label() for ln in ax.get_lines()] == ["f1(x')", "f2(x)"]
    with pytest.raises(ConfigError, match="one Axes per curve"):
        model.plot(ax=[ax])
    plt.close(fig)


def test_report_plot_curves_is_the_fitting_one():
    from charcurves.report import plot_curves as report_plot_curves

    assert report_plot_curves is plot_curves and cc.plot_curves is plot_curves
