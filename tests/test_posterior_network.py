"""The Laplace posterior of gradient-trained fits (train/_posterior_network.py): the least-squares
formula where the problem is linear, the linear posterior's gain and gauge, the exact Jacobian of
nn-cc curves against finite differences, a dependent direction, and the user's surfaces."""

import dataclasses
import json

import numpy as np
import pytest

from charcurves._errors import ConfigError

import charcurves as cc
from charcurves.cli import main
from charcurves.curves import Basis
from charcurves.fitting import posterior_bands, uncertainty_summary
from charcurves.systems import get_system
from charcurves.train import fit_gradient, get_preset


@pytest.fixture(scope="module")
def record():
    return cc.corrupt(get_system("duffing").simulate(), 20, seed=0)


@pytest.fixture(scope="module")
def short():
    return cc.corrupt(get_system("duffing").simulate(t_end=20.0, n_points=400), 20, seed=1)


def _gradient_fit(record, template, reps):
    """One start, Levenberg-Marquardt alone: the problem is linear."""
    mask = np.ones(record.n_samples, dtype=bool)
    preset = dataclasses.replace(get_preset("default"), adam_steps=0, n_starts=1)
    return fit_gradient([record], template, reps, preset, [0], method="test", masks=[mask])[0]


def test_a_linear_curve_trained_by_gradient_has_the_least_squares_posterior(record):
    """f1 = d z, f2 = a z + b z^3 through the gradient trainer: the problem is linear, no decay, so the
    Laplace posterior is s^2 (X^T X)^-1 with X = [v, x, x^3, 1] and s^2 = RSS / (N - 4)."""
    model = _gradient_fit(record, cc.fit(record, method="poly-cc").template,
                          {"f1": Basis("z"), "f2": Basis("z, z**3")})
    post = model.posterior.with_kind("gauss")
    X = np.column_stack([record.v, record.x, record.x**3, np.ones(record.n_samples)])
    y = record.F - record.a
    coef, *_ = np.linalg.lstsq(X, y, rcond=None)
    s2 = np.sum((y - X @ coef) ** 2) / (record.n_samples - 4)
    cov = s2 * np.linalg.inv(X.T @ X)
    z = np.array([-1.2, 0.5, 1.3])
    value, sd = post.curve_sd("f2", z)
    basis = np.column_stack([z, z**3])
    assert np.allclose(value, basis @ coef[1:3], rtol=1e-8)
    assert np.allclose(sd, np.sqrt(np.einsum("ij,jk,ik->i", basis, cov[1:3, 1:3], basis)), rtol=1e-6)
    v1, sd1 = post.curve_sd("f1", z)
    assert np.allclose(sd1, np.sqrt(cov[0, 0]) * np.abs(z), rtol=1e-6)
    stats = post.scalar_stats()
    assert stats["names"] == ["offset"]
    assert stats["sd"]["offset"] == pytest.approx(np.sqrt(cov[3, 3]), rel=1e-6)
    assert post.effective_parameters == pytest.approx(4.0, abs=1e-9)
    assert post.noise_variance == pytest.approx(s2, rel=1e-6)


def test_a_free_gain_gives_the_linear_posterior_of_the_same_regression(record):
    """A free gain on the force side divides the curves: the gradient-trained basis fit and the
    least-squares parametric fit are the same regression, and their posteriors agree."""
    ref = cc.CharacteristicCurves.from_method(method="parametric", basis="f1=z; f2=z, z**3",
                                              free_gain=True).fit(record).model_
    model = _gradient_fit(record, ref.template, {"f1": Basis("z"), "f2": Basis("z, z**3")})
    z = np.linspace(-1.5, 1.5, 7)
    for kind in ("gauss", "hac"):
        mine, theirs = model.posterior.with_kind(kind), ref.posterior.with_kind(kind)
        for name in ("f1", "f2"):
            (v, sd), (v_ref, sd_ref) = mine.curve_sd(name, z), theirs.curve_sd(name, z)
            assert np.allclose(v, v_ref, rtol=1e-7, atol=1e-12)
            assert np.allclose(sd, sd_ref, rtol=1e-4, atol=1e-12), (kind, name)
        a, b = mine.scalar_stats(), theirs.scalar_stats()
        assert a["names"] == b["names"] == ["gain", "offset"]
        for k in a["names"]:
            assert a["mean"][k] == pytest.approx(b["mean"][k], rel=1e-7, abs=1e-12)
            assert a["sd"][k] == pytest.approx(b["sd"][k], rel=1e-4)


@pytest.fixture(scope="module")
def nn(short):
    return cc.CharacteristicCurves.from_method(method="nn-cc+sym", free_gain=True, random_state=0,
                                               threads=1).fit(short).model_


def test_the_band_of_a_network_is_its_jacobian_through_the_posterior(nn):
    """The curves' Jacobian (gain, members and gauge included) against central differences of the
    reported values, and the band is sqrt(J cov J^T) averaged over the members plus their spread."""
    post = nn.posterior
    grids = {"f1": np.linspace(-1.0, 1.0, 5), "f2": np.array([-1.5, 0.0, 0.7])}
    th = post._thetas[0].clone()
    value, J = post.mapping.report_jacobian(th, grids)
    h = 1e-6
    Jn = np.zeros_like(J)
    for p in range(th.numel()):
        e = th.clone()
        e[p] += h
        up = post.mapping.report(e.unsqueeze(0), grids).numpy()
        e[p] -= 2 * h
        Jn[:, p] = (up - post.mapping.report(e.unsqueeze(0), grids).numpy()) / (2 * h)
    assert np.allclose(value, post.mapping.report(th.unsqueeze(0), grids).numpy(), rtol=1e-12, atol=1e-14)
    assert np.allclose(J, Jn, rtol=1e-5, atol=1e-6 * np.abs(J).max())
    z = np.linspace(*nn.curves["f1"].domain, 9)
    v, sd = post.curve_sd("f1", z)
    assert np.allclose(v, nn.curves["f1"](z), rtol=1e-9, atol=1e-12)
    assert bool(np.all(sd > 0)) and post.kind == "hac"


def test_a_network_posterior_on_white_residuals_is_the_evidence_laplace(nn):
    """Noise on F with the derivatives given: the HAC covariance and MacKay's s^2 H^-1 nearly agree,
    and f2, anchored at 0 by the gauge, has no width there."""
    post = nn.posterior
    z = np.linspace(*nn.curves["f1"].domain, 50)
    _, sd_h = post.curve_sd("f1", z)
    _, sd_g = post.with_kind("gauss").curve_sd("f1", z)
    assert 0.75 < float(np.median(sd_h / sd_g)) < 1.33
    _, sd0 = post.curve_sd("f2", np.array([0.0]))
    assert sd0[0] == 0.0
    value, lo, hi = nn.curve_band("f1", np.array([0.5]), level=0.9)
    assert lo[0] < value[0] < hi[0]


def test_a_dependent_direction_is_named_and_does_not_narrow_the_curve(record):
    """f1 = a z + b (2 z): the record cannot split a from b. The warning names f1; the curve itself
    is determined, and its band is the band of f1 = c z."""
    tpl = cc.fit(record, method="poly-cc").template
    twin = _gradient_fit(record, tpl, {"f1": Basis("z, 2*z"), "f2": Basis("z, z**3")})
    one = _gradient_fit(record, tpl, {"f1": Basis("z"), "f2": Basis("z, z**3")})
    lines = [w for w in twin.info.get("warnings", []) if w.startswith("uncertainty:")]
    assert len(lines) == 1 and "the weights of f1" in lines[0] and "does not determine" in lines[0]
    z = np.array([-1.0, 0.4])
    assert np.allclose(twin.posterior.curve_sd("f1", z)[1], one.posterior.curve_sd("f1", z)[1], rtol=1e-5)


def test_a_changed_network_has_no_posterior(short):
    model = cc.fit(short, method="nn-cc", random_state=0)
    assert model.posterior is not None and uncertainty_summary(model)["method"].startswith("laplace (gauss-newton")
    model.curves["f1"].shift += 0.1
    assert posterior_bands(model) == {} and uncertainty_summary(model) is None


def test_cli_bands_of_an_nn_cc_fit_are_the_posterior(tmp_path, short):
    path = tmp_path / "rec.csv"
    short.to_csv(path)
    out = tmp_path / "fit"
    assert main(["fit", str(path), "--method", "nn-cc", "--out", str(out), "--bands", "--quiet"]) == 0
    result = json.loads((out / "result.json").read_text())
    assert result["bands"]["f1"]["kind"] == "posterior (hac)"
    unc = result["uncertainty"]
    assert unc["method"] == "laplace (gauss-newton, evidence decays)" and unc["covariance"] == "hac"
    assert len(unc["curves"]["f2"]["sd"]) == 51 and unc["warnings"] == []


@pytest.fixture(scope="module")
def oe():
    clean = get_system("duffing").simulate(t_end=20.0, n_points=500)
    measured = cc.corrupt(clean, 40, on="state", seed=2)
    model = cc.CharacteristicCurves.from_method(method="parametric", basis="f1=z; f2=z, z**3", free_gain=True,
                                                objective="output-error", threads=1).fit(measured).model_
    return model, float(np.var(measured.x - clean.x))


def test_an_output_error_fit_has_the_posterior_of_its_shooting_problem(oe):
    """The gain's sd against the Schur complement of the shooting problem's Gauss-Newton matrix
    (decay and continuity rows included), formed here from its Jacobian; the noise variance
    against the noise added; f2(0) = 0 has no width."""
    model, noise = oe
    post = model.posterior
    assert model.info["objective"] == "output-error" and post is not None
    assert post.label.startswith("laplace (gauss-newton of output error")
    sub, th = post.mapping.problem, post._thetas
    r, J = (a[0].numpy() for a in sub.residuals_jacobian(th))
    nd, ns = sub.n_data, sub.n_shared
    H = J.T @ J
    Jd = J[:nd]
    gamma = np.trace(np.linalg.solve(H, Jd.T @ Jd))
    s2 = float(r[:nd] @ r[:nd]) / (nd - gamma)
    Hss, Hsi, Hii = H[:ns, :ns], H[:ns, ns:], H[ns:, ns:]
    schur = Hss - Hsi @ np.linalg.solve(Hii, Hsi.T)
    g = sub.gain_index
    stats = post.with_kind("gauss").scalar_stats()
    assert stats["sd"]["gain"] == pytest.approx(np.sqrt(s2 * np.linalg.inv(schur)[g, g]), rel=1e-6)
    assert post.noise_variance == pytest.approx(noise, rel=0.25)
    assert post.curve_sd("f2", np.array([0.0]))[1][0] == 0.0
    value, lo, hi = model.curve_band("f1", np.array([0.3]))
    assert lo[0] < value[0] < hi[0] and uncertainty_summary(model)["covariance"] == "hac"


def test_the_output_error_jacobian_is_exact(oe):
    model, _ = oe
    post = model.posterior
    grids = {"f1": np.array([-0.8, 0.2]), "f2": np.array([-1.1, 1.4])}
    th = post._thetas[0].clone()
    value, J = post.mapping.report_jacobian(th, grids)
    h = 1e-6
    Jn = np.zeros_like(J)
    for p in range(th.numel()):
        e = th.clone()
        e[p] += h
        up = post.mapping.report(e.unsqueeze(0), grids).numpy()
        e[p] -= 2 * h
        Jn[:, p] = (up - post.mapping.report(e.unsqueeze(0), grids).numpy()) / (2 * h)
    assert np.allclose(J, Jn, rtol=1e-6, atol=1e-8)
    assert not J[:, post.mapping.problem.n_shared:].any()  # nothing reported moves with the initial states
    assert np.allclose(value[:2], model.curves["f1"](grids["f1"]), rtol=1e-9)


def test_the_simultaneous_band_widens_the_pointwise_one_as_a_sup_t_band(nn):
    """At one point the sup-t factor is the pointwise 95 % quantile 1.96 (to the draws' error); over a
    grid it lies between that and Bonferroni's bound."""
    post = nn.posterior
    one = post.simultaneous_factor({"f1": np.array([0.4])}, level=0.95)
    assert one == pytest.approx(1.96, abs=0.08)
    grid = {"f1": np.append(np.linspace(*nn.curves["f1"].domain, 99), 0.4)}
    many = post.simultaneous_factor(grid, level=0.95)
    # the same draws: the peak over a grid holding 0.4 is at least the value there; Bonferroni over
    # 100 points, the 1 - 0.05 / 200 quantile of N(0, 1), is 3.48
    assert one <= many < 3.48
    assert post.simultaneous_factor(grid, level=0.95) == many  # seeded draws: the same number each time
    assert post.simultaneous_factor({"f2": np.array([0.0])}) == 1.0  # only the gauge point: no width to cover
    for bad in ({"level": 1.5}, {"level": 0.0}, {"draws": 0}):
        with pytest.raises(ConfigError, match="simultaneous_factor needs 0 < level < 1 and draws >= 1"):
            post.simultaneous_factor(grid, **bad)


@pytest.mark.slow
def test_the_default_fit_of_a_record_of_x_only_has_the_output_error_posterior():
    """The default (parity tests, nn-cc+sym with a learned jump, output error) on 40 dB on x: the
    posterior of the output-error fit, with the jump's width known, and no stale warning of the
    equation-error stage."""
    clean = get_system("duffing").simulate(t_end=20.0, n_points=500)
    measured = cc.corrupt(clean, 40, on="state", seed=3)
    model = cc.fit(cc.Trajectory(t=measured.t, x=measured.x, F=measured.F), random_state=0)
    assert model.info["objective"] == "output-error"
    assert model.posterior.label.startswith("laplace (gauss-newton of output error")
    assert not [w for w in model.info.get("warnings", []) if w.startswith("uncertainty:")]
    truth = get_system("duffing").true_curves()
    z = np.linspace(*model.curves["f2"].domain, 100)
    value, lo, hi = model.curve_band("f2", z)
    assert np.mean((truth["f2"](z) >= lo) & (truth["f2"](z) <= hi)) > 0.8
