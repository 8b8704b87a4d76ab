"""The lack-of-fit term of the posterior bands (fitting._lack_of_fit, model._posterior_lack): a band
of a representation that cannot take the curve's shape covers the truth once the residual's binned
bias is added; a well-specified fit's band is left as it was."""

from __future__ import annotations

import numpy as np
import pytest

import charcurves as cc
from charcurves.fitting import lack_of_fit_bias
from charcurves.model import LackOfFitPosterior, StoredPosterior
from charcurves.systems import CurveSystem, get_system


def _tanh_record(seed: int):
    truth = {"f1": lambda v: 0.3 * np.asarray(v), "f2": lambda x: 1.5 * np.tanh(2.0 * np.asarray(x))}
    system = CurveSystem("separable", truth, forcing=((1.6, 1.0), (0.8, 1.9)), initial=(0.0, 0.0), name="tanh")
    clean = system.simulate(t_end=60.0, n_points=3000)
    return truth, clean, cc.corrupt(clean, 30, on="force", seed=seed)


def _inside(f, value, sd) -> float:
    return float(np.mean(np.abs(f - value) <= 1.959963984540054 * sd))


@pytest.fixture(scope="module")
def tanh_fit():
    truth, clean, record = _tanh_record(seed=3)
    model = cc.CharacteristicCurves.from_method(method="parametric", basis="f1=z; f2=z, z**3", random_state=0,
                                                threads=1).fit(record).model_
    z = np.linspace(float(clean.x.min()), float(clean.x.max()), 200)
    return truth, model, z


def test_a_cubic_for_a_tanh_spring_gets_a_band_that_covers(tanh_fit):
    truth, model, z = tanh_fit
    post = model.posterior
    assert isinstance(post, LackOfFitPosterior) and sorted(post.bias) == ["f2"]  # f1 = 0.3 v is in the basis
    assert model.info["lack_of_fit_p"]["f2"] < 1e-10 < 1e-3 < model.info["lack_of_fit_p"]["f1"]
    assert model.info["posterior"].startswith("laplace (least squares) + lack of fit (binned residual): the bands of f2")
    f = truth["f2"](z)
    plain = _inside(f, *post.inner.curve_sd("f2", z))
    wide = _inside(f, *post.curve_sd("f2", z))
    assert plain < 0.4  # the cubic's band is centred off the tanh: it holds the truth on few points
    assert wide > 0.9
    lo, hi = model.curve_band("f2", z)[1:]
    assert _inside(f, (lo + hi) / 2, (hi - lo) / 2 / 1.959963984540054) == pytest.approx(wide)


def test_the_bias_estimate_follows_the_true_bias(tanh_fit):
    truth, model, _ = tanh_fit
    c, b = model.posterior.bias["f2"]
    true_bias = np.abs(truth["f2"](c) - model.curves["f2"](c))
    assert np.corrcoef(b, true_bias)[0, 1] > 0.8
    assert 0.5 < np.sqrt(np.mean(b**2) / np.mean(true_bias**2)) < 2.0


def test_the_widened_posterior_is_saved_and_sampled_with_its_extra_direction(tanh_fit):
    _, model, z = tanh_fit
    stored = StoredPosterior.from_posterior(model.posterior, model)
    assert stored.rank == np.asarray(model.posterior.inner.curve_factor("f2", z)[1]).shape[1] + 1
    sd_stored, sd_fit = stored.curve_sd("f2", z)[1], model.posterior.curve_sd("f2", z)[1]
    assert np.max(np.abs(sd_stored - sd_fit)) < 0.02 * np.max(sd_fit)  # a spline between the stored grid's points
    assert "lack of fit" in stored.method


def test_a_well_specified_fit_keeps_its_band():
    record = cc.corrupt(get_system("duffing").simulate(), 20, on="force", seed=2)
    model = cc.CharacteristicCurves.from_method(method="parametric", basis="f1=z; f2=z, z**3", random_state=0,
                                                threads=1, free_gain=True).fit(record).model_
    p = model.info["lack_of_fit_p"]
    # the correct form: the residual is no function of either argument (p 0.18 and 0.77 here, where a misfitted
    # form gives p < 1e-10; the term is added below 1e-3)
    assert min(p.values()) > 0.05
    assert not isinstance(model.posterior, LackOfFitPosterior)
    assert "no lack-of-fit term" in model.info["posterior"]
    # forced on, the estimate's own noise would widen the spring's band (median factor 4.4 on this seed with the
    # hat functions, 3.0 with the bin means before issue 48), and far more where the gauge pins the curve (the
    # term is not added where the test finds nothing)
    c, b, _ = lack_of_fit_bias(model, record, curves=["f2"])["f2"]
    z = np.linspace(-1.5, 1.5, 100)
    wide = LackOfFitPosterior(model.posterior, {"f2": (c, b)})
    ratio = wide.curve_sd("f2", z)[1] / model.posterior.curve_sd("f2", z)[1]
    assert np.all(ratio >= 1.0) and 3.9 < np.median(ratio) < 4.9


def test_the_constants_keep_their_sds_under_the_widened_band(tanh_fit):
    from charcurves.model import constant_sds_of

    _, model, _ = tanh_fit
    sds = constant_sds_of(model, "f2")  # the constants' posterior is the plain one: the term is about the band
    assert sds is not None and len(sds) == 2 and all(0 < v < np.inf for v in sds.values())


@pytest.fixture(scope="module")
def stop_record():
    """A one-sided stop spring (kink at 0.4) and a linear damper: the best polynomial spring is off by a
    constant at 0, which the gauge f2(0) = 0 (or a spring basis without a constant) hands to f1."""
    truth = {"f1": lambda v: 0.3 * np.asarray(v),
             "f2": lambda x: np.asarray(x) + 3.0 * np.maximum(np.asarray(x) - 0.4, 0.0)}
    system = CurveSystem("separable", truth, forcing=((0.8, 1.0), (0.4, 1.8)), initial=(0.0, 0.0), name="stop")
    clean = system.simulate(t_end=60.0, n_points=3000)
    return truth, clean, cc.corrupt(clean, 30, on="force", seed=3)


@pytest.mark.parametrize("kw, offset", [({"method": "poly-cc"}, 0.022), ({"method": "parametric", "basis": "f1=1, z; f2=z, z**3"}, -0.54)])
def test_a_curve_that_carries_the_constant_gets_its_offset_in_the_band(stop_record, kw, offset):
    # issue 48: the bias estimate held every curve at 0 at z = 0 and dropped the residual's constant, so f1's
    # offset (the true f1 is 0.3 v, the fit's f1 is shifted by the spring's misfit at 0) was missed: its test
    # passed (p 0.08 for poly-cc, 1.0 for the parametric fit) and its band held none of the truth
    truth, clean, record = stop_record
    model = cc.CharacteristicCurves.from_method(random_state=0, threads=1, **kw).fit(record).model_
    z = np.linspace(float(clean.v.min()), float(clean.v.max()), 200)
    f = truth["f1"](z)
    true_offset = float(truth["f1"](0.0) - model.curves["f1"](np.array([0.0]))[0])
    assert true_offset == pytest.approx(offset, abs=0.1 * abs(offset))  # the misfit this test is about
    post = model.posterior
    assert isinstance(post, LackOfFitPosterior) and "f1" in post.bias
    assert model.info["lack_of_fit_p"]["f1"] < 1e-6
    assert _inside(f, *post.inner.curve_sd("f1", z)) < 0.05  # the plain band is centred off by the offset
    assert _inside(f, *post.curve_sd("f1", z)) > 0.95
    c, b, _ = lack_of_fit_bias(model, record)["f1"]
    assert np.interp(0.0, c, b) == pytest.approx(true_offset, rel=0.25)  # signed: truth minus fit
    # the spring's gauge holds: its bias is 0 at 0, where the band of the anchored curve has no width
    c2, b2, _ = lack_of_fit_bias(model, record)["f2"]
    assert abs(np.interp(0.0, c2, b2)) < 1e-12


def test_an_output_error_fit_gets_no_lack_of_fit_term():
    """The binned test reads the equation residual; on an output-error fit of a noisy x it holds the
    estimated derivatives' errors, which passed for misfit (poly-cc on Duffing at 40 dB on x: bands
    8 times wider than the plain ones, which already cover)."""
    system = get_system("duffing")
    record = cc.corrupt(system.simulate(), 40, on="state", seed=0)
    model = cc.CharacteristicCurves.from_method(method="poly-cc", random_state=0, threads=1).fit(record).model_
    assert model.info["objective"] == "output-error"
    assert not isinstance(model.posterior, LackOfFitPosterior)
    assert model.info["posterior"].endswith("no lack-of-fit term (an output-error fit)")
    z = np.linspace(*model.curves["f2"].domain, 200)
    _, lo, hi = model.curve_band("f2", z, level=0.95)
    inside = np.mean((system.true_curves()["f2"](z) >= lo) & (system.true_curves()["f2"](z) <= hi))
    assert inside > 0.9


def _power_pendulum_records(seeds):
    """The zoo's sep-power-pendulum (benchmarks/zoo.py): a power-law damper 0.05 v + 0.2 sign(v)|v|^1.5, which an
    odd library of powers takes only approximately, and a pendulum spring 2 sin(x); 25 dB on F."""
    truth = {"f1": lambda v: 0.05 * np.asarray(v) + 0.2 * np.sign(v) * np.abs(v) ** 1.5,
             "f2": lambda x: 2.0 * np.sin(np.asarray(x))}
    system = CurveSystem("separable", truth, forcing=((1.0, 1.1), (0.5, 2.0)), initial=(0.0, 0.0), name="power")
    clean = system.simulate(t_end=40.0, n_points=1000)
    return truth, clean, [cc.corrupt(clean, 25, on="force", seed=s) for s in seeds]


def test_a_sparse_fit_gets_a_band_for_the_bias_below_the_test():
    """issue 48: sindy-cc+sym keeps all ten odd powers here (nothing pruned), and the odd polynomial's bias
    near v = 0 is about the size of its narrow band but below what the binned test detects (p 0.002-0.9 on
    these seeds), so the band of the rule before (the term only where p < 1e-3) was the plain one and held
    0.71 of the grid; a sparse fit's curves whose test passes now get the coarse, shrunk estimate."""
    pytest.importorskip("pysindy")
    from charcurves.fitting import LACK_OF_FIT_LEVEL

    truth, clean, records = _power_pendulum_records(range(8))
    z = np.linspace(float(clean.v.min()), float(clean.v.max()), 200)
    f = truth["f1"](z)
    old, new, hw_plain, hw_new = [], [], [], []
    for record in records:
        model = cc.CharacteristicCurves.from_method(method="sindy-cc+sym", random_state=0, threads=1,
                                                    objective="equation-error").fit(record).model_
        assert model.info["n_active_terms"] == 10
        post = model.posterior
        assert isinstance(post, LackOfFitPosterior) and "f1" in post.bias
        assert "a sparse regression's fit" in model.info["posterior"]
        est = {c: (zc, b) for c, (zc, b, p) in lack_of_fit_bias(model, record).items() if p < LACK_OF_FIT_LEVEL}
        before = LackOfFitPosterior(post.inner, est) if est else post.inner
        old.append(_inside(f, *before.curve_sd("f1", z)))
        new.append(_inside(f, *post.curve_sd("f1", z)))
        hw_plain.append(float(np.mean(post.inner.curve_sd("f1", z)[1])))
        hw_new.append(float(np.mean(post.curve_sd("f1", z)[1])))
    assert np.mean(old) < 0.75  # measured 0.711: the truth lay outside the old band on 29 % of the grid
    assert np.mean(new) > 0.9  # measured 0.924
    # and not by an unbounded band: twice the plain width (measured 2.09: the plain band alone is 1), a
    # half-width of 2 % of the damper's spread (measured 0.0208), each within 15 % of the measurement
    ratio = np.mean(hw_new) / np.mean(hw_plain)
    assert 1.8 < ratio < 2.4, ratio
    assert 0.018 < 1.96 * np.mean(hw_new) / np.std(f) < 0.024


def test_a_well_specified_sparse_fit_is_widened_little():
    """Duffing's curves are in sindy-cc+sym's library: the coarse, shrunk term widens their bands by a
    little (the estimate's noise, 0.25 of its variance out), and the band still has the truth."""
    pytest.importorskip("pysindy")
    system = get_system("duffing")
    record = cc.corrupt(system.simulate(), 20, on="force", seed=2)
    model = cc.CharacteristicCurves.from_method(method="sindy-cc+sym", random_state=0, threads=1,
                                                objective="equation-error").fit(record).model_
    post = model.posterior
    inner = post.inner if isinstance(post, LackOfFitPosterior) else post
    from types import SimpleNamespace

    from charcurves.fitting import sparse_fit

    assert sparse_fit(model) and not sparse_fit(SimpleNamespace(info={**model.info, "post_sr": {}}))  # distilled
    for name in ("f1", "f2"):
        z = np.linspace(*model.curves[name].domain, 200)
        ratio = post.curve_sd(name, z)[1] / np.maximum(inner.curve_sd(name, z)[1], 1e-300)
        assert np.median(ratio) < 2.0, name
        assert _inside(system.true_curves()[name](z), *post.curve_sd(name, z)) > 0.9, name
