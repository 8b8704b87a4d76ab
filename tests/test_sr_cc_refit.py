"""SR-CC as the paper runs it (the coefficients of its own searches) against ``sr-cc+refit`` (the
structure SR found, its coefficients refitted jointly by least squares), on one noisy record."""

from __future__ import annotations

import pytest
import sympy as sp

from charcurves.curves import Symbolic
from charcurves.data import corrupt
from charcurves.fitting import DEFAULT_BASIS, METHODS, CharacteristicCurves
from charcurves.metrics import curve_errors
from charcurves.systems import get_system

pytest.importorskip("pyoperon")


@pytest.fixture(scope="module")
def fits():
    system = get_system("duffing")
    record = corrupt(system.simulate(), 0.0, seed=3)  # 0 dB: the coefficients of the searches carry the noise
    out = {}
    for method in ("sr-cc", "sr-cc+refit", "parametric"):
        basis = {"basis": DEFAULT_BASIS} if method == "parametric" else {}
        model = CharacteristicCurves.from_method(method=method, sr_options={"generations": 20}, threads=1, **basis).fit(record).model_
        out[method] = (model, curve_errors(model, system.true_curves()))
    return out


def test_sr_cc_keeps_the_coefficients_of_its_own_searches(fits):
    model, _ = fits["sr-cc"]
    assert model.info["refit"] is False
    last = model.info["history"][-1]  # the expressions SR returned in the last iteration
    z = sp.Symbol("z")
    for name in ("f1", "f2"):
        searched = sp.sympify(last[name], locals={"z": z})
        searched -= sum((t for t in sp.Add.make_args(sp.expand(searched)) if not t.free_symbols), sp.Integer(0))
        fitted = model.curves[name].expression()
        assert float(sp.Abs(sp.expand(fitted - searched).subs(z, 0.7))) < 1e-12, name


def test_the_refit_differs_from_sr_cc_and_equals_parametric_on_the_true_structure(fits):
    (plain, e_plain), (refit, e_refit), (_, e_par) = fits["sr-cc"], fits["sr-cc+refit"], fits["parametric"]
    assert refit.info["refit"] is True
    # the same structure (x', x, x^3) from the same searches: the refit is least squares on the true basis
    assert refit.info["history"] == plain.info["history"]
    assert e_refit["f1"] == pytest.approx(e_par["f1"], rel=1e-9)
    assert e_refit["f2"] == pytest.approx(e_par["f2"], rel=1e-9)
    # SR-CC's own coefficients are not Parametric's: measured 1.26e-3 / 1.21e-2 against 1.04e-3 / 9.33e-3
    assert e_plain["f1"] > 1.1 * e_par["f1"] and e_plain["f2"] > 1.1 * e_par["f2"]


def test_refit_is_a_composed_part_and_a_named_method():
    assert METHODS["sr-cc+refit"]["representation"] == "sr-cc" and METHODS["sr-cc+refit"]["refit"] is True
    assert "refit" not in METHODS["sr-cc"]
    assert repr(Symbolic(refit=True)) == "Symbolic(refit=True)"
    from charcurves import ConfigError

    with pytest.raises(ConfigError, match="refit=True is for SR-CC"):
        Symbolic(joint=True, refit=True).check()
    with pytest.raises(ConfigError, match="Symbolic refit must be True or False, got 'yes'"):
        Symbolic(refit="yes").check()
