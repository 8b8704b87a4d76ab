"""± on the constants of closed forms (to_sympy / to_latex with uncertainty=True): the coefficient's
sd is the least-squares formula's, the gain's is the posterior's, and a model without a posterior
says why."""

from __future__ import annotations

import numpy as np
import pytest

import charcurves as cc
from charcurves._errors import ConfigError
from charcurves.model import constant_sds_of
from charcurves.model._posterior import _pm
from charcurves.systems import get_system

BASIS = "f1=z; f2=z, z**3"


@pytest.fixture(scope="module")
def record():
    return cc.corrupt(get_system("duffing").simulate(), 20, seed=0)


def test_basis_coefficients_get_the_least_squares_sd(record):
    """x'' - F = -(d v + a x + b x^3 + c): the sd of b is sqrt(s^2 (X^T X)^-1)[2, 2] (iid posterior)."""
    model = cc.fit(record, method="parametric", basis=BASIS)
    model.posterior = model.posterior.with_kind("gauss")
    X = np.column_stack([record.v, record.x, record.x**3, np.ones(record.n_samples)])
    y = record.F - record.a
    coef, *_ = np.linalg.lstsq(X, y, rcond=None)
    s2 = np.sum((y - X @ coef) ** 2) / (record.n_samples - 4)
    sd = np.sqrt(np.diag(s2 * np.linalg.inv(X.T @ X)))
    got = {round(float(f), 9): s for f, s in constant_sds_of(model, "f2").items()}
    assert got[round(coef[1], 9)] == pytest.approx(sd[1], rel=1e-6)
    assert got[round(coef[2], 9)] == pytest.approx(sd[2], rel=1e-6)
    (d_sd,) = constant_sds_of(model, "f1").values()
    assert d_sd == pytest.approx(sd[0], rel=1e-6)


def test_latex_and_sympy_write_the_constants_with_their_sd(record):
    model = cc.fit(record, method="parametric", basis="f1=z; f2=z, z**3", free_gain=True)
    stats = model.posterior.scalar_stats()
    latex = model.to_latex(uncertainty=True)
    text = str(model.to_sympy(uncertainty=True))
    g, s = stats["mean"]["gain"], stats["sd"]["gain"]
    pm = _pm(g, s)  # as summary.txt writes it
    assert f"= ({pm.replace('±', chr(92) + 'pm')}) F" in latex and "±" not in latex
    assert f"({pm})*F(t)" in text
    curves = model.to_sympy(curves=True, uncertainty=True)
    assert str(curves["f1"]).count("±") == 1 and str(curves["f2"]).count("±") == 2
    assert model.to_latex() == model.to_latex(uncertainty=False)  # the default is unchanged


def test_without_a_posterior_the_option_says_why(record):
    model = cc.fit(record, method="parametric", basis=BASIS)
    model.curves["f2"].shift += 1.0  # the posterior no longer describes the curve
    with pytest.raises(ConfigError, match="has no posterior, so its constants have no ±"):
        model.to_latex(uncertainty=True)


def test_summary_txt_writes_each_closed_form_with_its_sds(record, tmp_path):
    from charcurves.cli import main
    from charcurves.model import closed_form_lines

    csv = tmp_path / "rec.csv"
    record.to_csv(csv)
    out = tmp_path / "fit"
    assert main(["fit", str(csv), "--method", "parametric", "--basis", BASIS, "--out", str(out), "--no-figure",
                 "--quiet"]) == 0
    summary = (out / "summary.txt").read_text(encoding="utf-8")
    lines = closed_form_lines(cc.load_model(out / "model"))
    assert len(lines) == 2 and all(line in summary for line in lines)
    assert lines[0].startswith("  f1(z) = (0.30") and lines[0].endswith("*z (1 sd, posterior)")
