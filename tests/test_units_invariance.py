"""Neural curves do not depend on the units or the offset of their argument (issue 46).

A network fed ``z / max|z|`` of a record resting far from 0 (a sensor that does not read 0 at rest)
sees a nearly constant input: nn-cc fitted Duffing shifted by 10 (20 dB on F, derivatives given) at
65 % / 90 % normalised RMSE on f1 / f2 against 1.2 % / 0.39 % unshifted. A range without 0 is now
mapped onto [-1, 1] by its midpoint and half width (:func:`charcurves.curves.neural_input_map`);
a range that contains 0, or a curve that keeps the point 0 (a parity prior, a jump), is scaled as
before, so those fits are unchanged to the last bit.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from charcurves.curves import Neural, NeuralCurve, NeuralFittedCurve, neural_input_map
from charcurves.data import Trajectory, corrupt
from charcurves.fitting import CharacteristicCurves, anchor_notes
from charcurves.systems import get_system

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import bench_units  # noqa: E402

#: the factor within which the shifted record's nRMSE must stay of the plain record's (seed 0:
#: measured 1.06 on f1 and 1.35 on f2; over seeds 1-3 the ratio spans 0.49-1.26, the fits' own spread)
SHIFT_FACTOR = 1.5


@pytest.fixture(scope="module")
def duffing():
    system = get_system("duffing")
    clean = system.simulate()
    return system, clean, corrupt(clean, 20.0, on="force", seed=0)


def _units(rec, c: float, d: float) -> Trajectory:
    """The record in new units: x -> c (x + d), and F (per unit mass) in the same length unit."""
    return Trajectory(t=rec.t, x=c * (np.asarray(rec.x) + d), v=c * np.asarray(rec.v), a=c * np.asarray(rec.a),
                      F=c * np.asarray(rec.F))


def _nrmse(model, system, clean, c: float, d: float) -> dict[str, float]:
    """RMSE against the true curves mapped into the new units (c f1(V / c), c f2(X / c - d)), up to a
    constant (the gauge), over the clean record's range, over the std of the truth there: the score of
    benchmarks/bench_units.py, the same function."""
    return bench_units.score(model, system, clean, c, d)


@pytest.fixture(scope="module")
def fits(duffing):
    system, clean, rec = duffing
    out = {}
    for key, (c, d) in {"plain": (1.0, 0.0), "shifted": (1.0, 10.0), "milli": (1e-3, 0.0)}.items():
        model = CharacteristicCurves.from_method("nn-cc", random_state=0, threads=1).fit(_units(rec, c, d)).model_
        out[key] = (model, _nrmse(model, system, clean, c, d))
    return out


def test_the_input_map_centres_only_a_range_without_0_and_keeps_0_for_a_prior():
    assert neural_input_map(np.array([-2.0, 0.5, 1.0])) == (0.0, 2.0)
    assert neural_input_map(np.array([0.0, 3.0])) == (0.0, 3.0)  # 0 on the edge: scaled as before
    assert neural_input_map(np.array([9.0, 10.5, 11.0])) == (10.0, 1.0)
    assert neural_input_map(np.array([-11.0, -9.0])) == (-10.0, 1.0)
    assert neural_input_map(np.array([9.0, 11.0]), anchored=True) == (0.0, 11.0)
    assert neural_input_map(np.array([5.0, 5.0])) == (0.0, 5.0)  # a constant: nothing to centre on
    z = np.array([9.0, 11.0])
    assert Neural().scaling(z, None) == (10.0, 1.0)
    assert Neural(symmetry="odd").scaling(z, None) == (0.0, 11.0)  # odd about 0 stays odd about 0
    assert Neural(jump=True).scaling(z, None) == (0.0, 11.0)  # the jump sits at 0
    assert Neural(jump="auto").scaling(z, None, jump=True) == (0.0, 11.0)  # as decided for the record
    assert Neural().scaling(z, None, jump=False) == (10.0, 1.0)


def test_nn_cc_on_an_offset_record_is_within_the_factor_of_the_plain_one(fits):
    """Before the input map: 65.4 % / 90.4 % (52.7x / 229x the plain record's), which fails here."""
    plain, shifted = fits["plain"][1], fits["shifted"][1]
    assert plain["f1"] < 0.02 and plain["f2"] < 0.006  # the plain fit: 1.24 % / 0.394 %
    for name in ("f1", "f2"):
        assert shifted[name] <= SHIFT_FACTOR * plain[name], (name, shifted[name], plain[name])
    model = fits["shifted"][0]
    lo, hi = model.curves["f2"].domain
    assert model.curves["f2"].in_center == 0.5 * (lo + hi) and model.curves["f2"].in_scale == 0.5 * (hi - lo)
    assert model.curves["f1"].in_center == 0.0  # x' crosses 0: scaled only
    assert model.info["self_check"]["loss_over_floor"][0] < 1.1  # measured 0.999 (before: 150)


def test_nn_cc_in_millimetres_gives_the_same_curves_in_the_new_units(fits):
    plain, milli = fits["plain"][1], fits["milli"][1]
    for name in ("f1", "f2"):
        assert milli[name] == pytest.approx(plain[name], rel=1e-6)
    m0, m3 = fits["plain"][0], fits["milli"][0]
    z = np.linspace(*m0.curves["f2"].domain, 7)
    np.testing.assert_allclose(m3.curves["f2"](1e-3 * z), 1e-3 * m0.curves["f2"](z), rtol=1e-6, atol=1e-12)


def test_a_record_that_crosses_0_keeps_its_model_file_keys(fits):
    """Same bytes where nothing changes: no centre is stored for a curve that was only scaled."""
    spec, _ = fits["plain"][0].curves["f2"].to_spec()
    assert "in_center" not in spec
    spec, _ = fits["shifted"][0].curves["f2"].to_spec()
    assert spec["in_center"] == fits["shifted"][0].curves["f2"].in_center


def test_the_centre_survives_save_and_load_and_an_old_file_reads_as_0(fits, tmp_path):
    from charcurves.model import FittedModel

    model = fits["shifted"][0]
    model.save(tmp_path / "m")
    back = FittedModel.load(tmp_path / "m")
    z = np.linspace(*model.curves["f2"].domain, 11)
    np.testing.assert_array_equal(back.curves["f2"](z), model.curves["f2"](z))
    spec = NeuralCurve(hidden=(4,))
    theta = np.random.default_rng(0).normal(size=(2, spec.n_params))
    curve = NeuralFittedCurve("f2", "x", (-1.0, 1.0), spec, theta, in_scale=1.0, out_scale=1.0)
    d, arrays = curve.to_spec()
    assert "in_center" not in d and NeuralFittedCurve.from_spec(d, arrays).in_center == 0.0
    moved = NeuralFittedCurve("f2", "x", (9.0, 11.0), spec, theta, in_scale=1.0, out_scale=1.0, in_center=10.0)
    np.testing.assert_array_equal(moved(np.array([10.5])), curve(np.array([0.5])))
    np.testing.assert_array_equal(moved.raw_torch(np.array([10.5])), curve.raw_torch(np.array([0.5])))


def test_the_default_fit_of_an_offset_record_says_what_it_imposed_and_where_it_anchored(duffing):
    """f2's range excludes 0: no parity is imposed on it (said on the priors line), f1 keeps its
    tested odd prior (the constant that f2's anchor at 0 moves out is not f1's size), and the anchor
    f2(0) = 0, outside the data, is named as a convention."""
    _, _, rec = duffing
    model = CharacteristicCurves(random_state=0, threads=1).fit(_units(rec, 1.0, 10.0)).model_
    assert model.info["priors"]["summary"] == "f1=odd (tested), f2=none (tested: one-sided range)"
    lo, hi = model.curves["f2"].domain
    assert anchor_notes(model) == [
        f"f2(x) is anchored at x = 0 (f2(0) = 0), outside its data [{lo:.4g}, {hi:.4g}]: its value there is "
        "extrapolated, so the constant it moves elsewhere is a convention; compare f2 up to a constant"]


def test_the_summary_names_an_anchor_outside_the_data(duffing, tmp_path):
    from charcurves.cli import main

    _, clean, _ = duffing
    path = tmp_path / "r.csv"
    rows = zip(map(float, clean.t), map(float, np.asarray(clean.x) + 10.0), map(float, clean.F))
    path.write_text("t,x,F\n" + "\n".join(f"{t!r},{x!r},{f!r}" for t, x, f in rows) + "\n")
    assert main(["fit", str(path), "--out", str(tmp_path / "out"), "--method", "poly-cc", "--quiet"]) == 0
    lines = (tmp_path / "out" / "summary.txt").read_text().splitlines()
    (note,) = [ln for ln in lines if ln.startswith("  note: ")]
    assert note.startswith("  note: f2(x) is anchored at x = 0 (f2(0) = 0), outside its data [")
    assert note.endswith("compare f2 up to a constant")


@pytest.mark.slow
def test_with_noise_on_x_nn_cc_on_an_offset_record_stays_near_the_limit(duffing):
    """40 dB on x only (derivatives estimated, output error): on x + 10 nn-cc measured 0.082 % / 0.152 %,
    the parametric fit on the true basis of the same record 0.041 % / 0.132 % (2.01x / 1.15x; 1.57x /
    1.22x with Nielsen's damping in the separable family, which the state-noise rerun took back);
    before the input map nn-cc was at 168 % / 93.6 %."""
    system, clean, _ = duffing
    rec = corrupt(clean, 40.0, on="state", seed=0)
    shifted = Trajectory(t=rec.t, x=np.asarray(rec.x) + 10.0, F=rec.F)
    nn = CharacteristicCurves.from_method("nn-cc", random_state=0, threads=1).fit(shifted).model_
    limit = CharacteristicCurves.from_method("parametric", basis="f1=z; f2=z, z**2, z**3", random_state=0,
                                             threads=1).fit(shifted).model_
    e_nn, e_lim = _nrmse(nn, system, clean, 1.0, 10.0), _nrmse(limit, system, clean, 1.0, 10.0)
    for name in ("f1", "f2"):
        assert e_nn[name] <= 2.5 * e_lim[name], (name, e_nn[name], e_lim[name])


def test_output_error_keeps_the_constant_that_an_anchor_outside_the_data_moves_into_b(duffing):
    """f1 odd (pinned) and f2 anchored at 0 outside its data: the free constant b carries f2's value at 0.
    Output error trains around the equation-error model's shifts; the gauge applied after it used to
    drop them, so b counted f2(0) twice (poly-cc, 40 dB on x, x + 10: data loss 2.2e17, b = 4.7e8)."""
    system, clean, _ = duffing
    rec = corrupt(clean, 40.0, on="state", seed=0)
    fit = CharacteristicCurves.from_method("poly-cc", symmetry="f1=odd", random_state=0, threads=1)
    plain = fit.fit(rec).model_
    shifted = fit.fit(Trajectory(t=rec.t, x=np.asarray(rec.x) + 10.0, F=rec.F)).model_
    assert shifted.info["output_error"]["status"] == "ok"
    assert shifted.loss < 1.1 * plain.loss  # measured 0.001729 and 0.001732
    assert shifted.offset == pytest.approx(system.f2(-10.0), rel=0.01)  # -990.63; the truth -990
    assert shifted.offset == pytest.approx(-shifted.curves["f2"].shift, rel=1e-3)
    from charcurves.fitting import scalar_lines

    # the posterior's constant maps the trained shifts the same way (it said -1.9e+03 on the default fit);
    # its sd is that of f2(0) extrapolated from x in [8.5, 11.4], which the coefficients' prior decides
    # (2.1e+02 with raw powers, 3.7e+02 since output error trains in units of the curve's largest value)
    (line,) = scalar_lines(shifted)
    head, sd = line.split(" (1 sd")[0].split(" ± ")
    assert head == "  free constant b = -9.9e+02" and 50.0 < float(sd) < 500.0, line


@pytest.mark.parametrize("method, kwargs", [("poly-cc", {}), ("parametric", {"basis": "f1=z; f2=z, z**2, z**3"})])
def test_output_error_in_other_units_lands_where_the_plain_record_does(method, kwargs):
    """Output error trains a curve on monomials in powers of z / max|z| and in units of its largest
    value (``charcurves.curves.trainable``): in raw powers a record in millimetres or in thousands had
    coefficients up to 1e30 apart, which the damping's floor and the weight decay froze. 40 dB on x,
    seed 0, the default objective (equation error, then output error): poly-cc in 1e-3 and 1e3 units
    ended at 7.8 % / 8.8 % on f1 against 0.03 % on the plain record, and parametric on 1e3 (x + 10)
    at 0.64 % against 0.04 % on x + 10. Now every case lands on its base case's curves (measured: the
    same normalised RMSE to 4 digits)."""
    system = get_system("duffing")
    clean = system.simulate()
    errs = {}
    for case in ("x", "1e-3x", "1e3x", "x+10", "1e3(x+10)"):
        c, d, k, free = bench_units.CASES[case]
        est = CharacteristicCurves.from_method(method, random_state=0, threads=1, free_gain=free, **kwargs)
        model = est.fit(bench_units.record(clean, "X40", c, d, k)).model_
        assert model.info["output_error"]["status"] == "ok"
        errs[case] = bench_units.score(model, system, clean, c, d)
    for case, base in (("1e-3x", "x"), ("1e3x", "x"), ("1e3(x+10)", "x+10")):
        for name in ("f1", "f2"):
            assert errs[case][name] == pytest.approx(errs[base][name], rel=0.02), (method, case, name, errs)
    assert max(e for row in errs.values() for e in row.values()) < 2e-3, errs  # every curve within 0.2 %


def test_sindy_cc_sym_threshold_is_relative_so_units_do_not_change_the_fit():
    """SINDy-CC's library is built on z / max|z| and its regression scaled by the RMS of its target
    (``SparseLibrary(rescaling="max-abs")``), so the l0 threshold, nu and tol are relative. Before, the
    threshold was in the record's units: in units 1e3 x, 20 dB on F, f2 was 218 % off (0.94 % on x), and
    at 40 dB on x both curves 92-94 %. ``rescaling="none"`` keeps the scripts' raw powers."""
    system = get_system("duffing")
    clean = system.simulate()
    for setting in ("F20", "X40"):
        errs = {}
        for case in ("x", "1e-3x", "1e3x"):
            c, d, k, _ = bench_units.CASES[case]
            model = CharacteristicCurves.from_method("sindy-cc+sym", random_state=0, threads=1).fit(
                bench_units.record(clean, setting, c, d, k)).model_
            errs[case] = bench_units.score(model, system, clean, c, d)
        for case in ("1e-3x", "1e3x"):
            for name in ("f1", "f2"):
                assert errs[case][name] == pytest.approx(errs["x"][name], rel=0.02), (setting, case, errs)
        assert max(errs["x"].values()) < (0.02 if setting == "F20" else 2e-3), errs  # 1.5 % / 0.1 % measured
    c, d, k, _ = bench_units.CASES["1e3x"]
    raw = CharacteristicCurves.from_method("sindy-cc+sym", random_state=0, threads=1, options={"rescaling": "none"}).fit(
        bench_units.record(clean, "F20", c, d, k)).model_
    assert bench_units.score(raw, system, clean, c, d)["f2"] > 0.5  # the raw threshold in units 1e3 x
