"""Several records in one fit: shared curves, per-record states, segments within records, bad input."""

from __future__ import annotations

import numpy as np
import pytest

import charcurves as cc
from charcurves._errors import ConfigError, DataError
from charcurves.fitting import RecordSet
from charcurves.objectives._output_error import _segments
from charcurves.objectives._records import record_segments
from charcurves.systems import get_system

PARAM = dict(method="parametric", basis="f1=z; f2=z, z**3")


def _records(step_b: int = 301):
    s = get_system("duffing")
    a = cc.corrupt(s.simulate(t_end=20.0, n_points=501), 30, on="state", seed=0)
    b = cc.corrupt(s.simulate(t_end=12.0, n_points=step_b), 30, on="state", seed=1)
    return a, b


def test_segments_never_cross_a_record_boundary():
    bounds = ((0, 501), (501, 802), (802, 900))
    L, starts, contiguous = record_segments(bounds, 64, 400, _segments)
    assert L == 64
    ends = starts + L - 1
    for s, e in zip(starts, ends):
        inside = [a <= s and e < b for a, b in bounds]
        assert sum(inside) == 1, (s, e)
    # no continuity across a join: the pair (last of record k, first of record k + 1) is not contiguous
    first_of = [int(np.searchsorted(starts, a)) for a, _ in bounds]
    assert all(not contiguous[i - 1] for i in first_of[1:])
    assert contiguous.sum() == len(starts) - len(bounds)


def test_joint_output_error_fit_shares_the_curves_and_keeps_states_per_record():
    a, b = _records()
    est = cc.CharacteristicCurves.from_method(**PARAM, objective=cc.OutputError(segment_length=32, substeps=1, max_iter=10))
    model = est.fit([a, b]).model_
    oe = model.info["output_error"]
    assert oe["status"] == "ok" and oe["records"] == 2
    assert oe["segments"] == 500 // 31 + 300 // 31  # 16 + 9 segments of 32 samples, none across the join
    assert len(oe["record_initial_states"]) == 2
    # each record's own initial state: the second record starts where the system starts (x0 = 0.5)
    assert abs(oe["record_initial_states"][1][0] - 0.5) < 0.05
    np.testing.assert_allclose(model.curves["f2"].coefficients, [-1.0, 1.0], atol=0.02)
    np.testing.assert_allclose(model.curves["f1"].coefficients, [0.3], atol=0.01)
    recs = model.info["records"]
    assert [r["n_samples"] for r in recs] == [501, 301]
    for r in recs:  # each record's free run stays near the noise (30 dB on x: std about 0.03 of x's)
        assert 0 < r["free_run_rmse"] < 0.05
        assert 0 < r["loss_equation_error"] < 0.01
    # the curves' range is the union of the records' (their smoothed states, as a fit of each alone has)
    alone = [cc.CharacteristicCurves.from_method(**PARAM, objective="equation-error").fit(r).model_ for r in (a, b)]
    for name in ("f1", "f2"):
        lo = min(m.curves[name].domain[0] for m in alone)
        hi = max(m.curves[name].domain[1] for m in alone)
        assert model.curves[name].domain == pytest.approx((lo, hi), abs=1e-12)


def test_one_record_in_a_list_is_the_plain_fit():
    a, _ = _records()
    one = cc.CharacteristicCurves.from_method(**PARAM, objective="equation-error").fit(a).model_
    listed = cc.CharacteristicCurves.from_method(**PARAM, objective="equation-error").fit([a]).model_
    np.testing.assert_array_equal(one.curves["f2"].coefficients, listed.curves["f2"].coefficients)
    assert "records" not in listed.info


def test_records_of_different_rates_fit_by_equation_error_and_output_error_says_why_not():
    a, _ = _records()
    b = cc.corrupt(get_system("duffing").simulate(t_end=12.0, n_points=601), 30, on="state", seed=1)  # dt 0.02
    ee = cc.CharacteristicCurves.from_method(**PARAM, objective="equation-error").fit([a, b]).model_
    assert [round(r["dt"], 4) for r in ee.info["records"]] == [0.04, 0.02]
    np.testing.assert_allclose(ee.curves["f2"].coefficients, [-1.0, 1.0], atol=0.05)
    auto = cc.CharacteristicCurves.from_method(**PARAM).fit([a, b]).model_
    assert auto.info["output_error"]["status"].startswith("not run: output error of several records needs one "
                                                          "sampling step, got 0.04, 0.02")
    with pytest.raises(DataError, match="needs one sampling step"):
        cc.CharacteristicCurves.from_method(**PARAM, objective="output-error").fit([a, b])


def test_record_set_splits_changes_back_per_record():
    a, b = _records()
    rs = RecordSet([a, b])
    x = np.arange(rs.n_samples, dtype=float)
    rs2 = rs.replace(x=x)
    np.testing.assert_array_equal(rs2.records[1].x, x[501:])
    assert np.all(np.diff(rs.joined.t) > 0) and rs.bounds == ((0, 501), (501, 802))


@pytest.mark.parametrize("records, error, message", [
    ([], ConfigError, "empty list of records"),
    (["a.csv"], ConfigError, "record 0 of the list is a str, not a Trajectory"),
    (None, None, "record 1 of the list is a ndarray"),
])
def test_bad_lists_are_refused_with_the_fix(records, error, message):
    a, _ = _records()
    if records is None:
        records, error = [a, np.zeros(3)], ConfigError
    with pytest.raises(error, match=message):
        cc.CharacteristicCurves.from_method(**PARAM).fit(records)


def test_records_with_different_columns_are_refused():
    a, b = _records()
    clean = get_system("duffing").simulate(t_end=12.0, n_points=301)  # has v and a columns
    with pytest.raises(DataError, match=r"record 1 \(duffing\) has the columns x, F, v, a but record 0 "
                                        r"\(duffing\) has x, F; give every record the same columns"):
        cc.CharacteristicCurves.from_method(**PARAM).fit([a, clean])


def _csvs(tmp_path):
    a, b = _records()
    a.to_csv(tmp_path / "a.csv")
    b.to_csv(tmp_path / "b.csv")
    get_system("duffing").simulate(t_end=12.0, n_points=301).to_csv(tmp_path / "c.csv")  # with v, a columns
    return tmp_path / "a.csv", tmp_path / "b.csv", tmp_path / "c.csv"


def test_cli_fits_several_csv_files_into_one_result(tmp_path, capsys):
    import json

    from charcurves.cli import main

    a, b, _ = _csvs(tmp_path)
    code = main(["fit", str(a), str(b), "--out", str(tmp_path / "o"), "--method", "parametric", "--basis",
                 "f1=z; f2=z, z**3", "--no-figure", "--quiet"])
    assert code == 0
    doc = json.loads((tmp_path / "o" / "result.json").read_text())
    assert [r["source"] for r in doc["records"]] == ["../a.csv", "../b.csv"]
    assert [r["n_samples"] for r in doc["records"]] == [501, 301]
    assert all(0 < r["free_run_rmse"] < 0.05 for r in doc["records"])
    summary = (tmp_path / "o" / "summary.txt").read_text()
    assert "record 1 (../b.csv): 301 samples, step 0.04" in summary


def test_cli_refuses_records_with_different_columns_in_one_line(tmp_path, capsys):
    from charcurves.cli import main

    a, _, c = _csvs(tmp_path)
    code = main(["fit", str(a), str(c), "--out", str(tmp_path / "o"), "--method", "parametric", "--no-figure"])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert err.startswith("charcurves: error: record 1 (c) has the columns x, F, v, a but record 0 (a) has x, F")


def test_three_amplitudes_joint_fit_covers_the_union_and_beats_each_record_outside_its_range():
    # the Duffing target of benchmarks/bench_records.py at small size: forcing 0.5x, 1x, 1.5x of A = 0.5
    # (the 0.5x record stays in one well, x > 0), cubic poly-cc curves by equation error
    truth = get_system("duffing").true_curves()
    recs = [cc.corrupt(get_system("duffing", A=A).simulate(t_end=40.0, n_points=500), 30, seed=k)
            for k, A in enumerate((0.25, 0.5, 0.75))]
    kw = dict(method="poly-cc", options={"degree": 3})
    joint = cc.CharacteristicCurves.from_method(**kw).fit(recs).model_
    pooled = cc.CharacteristicCurves.from_method(**PARAM).fit(recs).model_
    alone = [cc.CharacteristicCurves.from_method(**kw).fit(r).model_ for r in recs]

    def rmse(curve, name, z):
        return float(np.sqrt(np.mean((curve(z) - truth[name](z)) ** 2)))

    for name in ("f1", "f2"):
        lo = min(m.curves[name].domain[0] for m in alone)
        hi = max(m.curves[name].domain[1] for m in alone)
        assert joint.curves[name].domain == pytest.approx((lo, hi), abs=1e-12)
        z = np.linspace(lo, hi, 400)
        for k in (0, 1):  # the records whose range is not the union's
            a, b = alone[k].curves[name].domain
            out = z[(z < a) | (z > b)]
            assert out.size > 50
            assert rmse(joint.curves[name], name, out) < 0.5 * rmse(alone[k].curves[name], name, out)
    z = np.linspace(*joint.curves["f2"].domain, 400)
    assert rmse(joint.curves["f2"], "f2", z) < 1.2 * rmse(pooled.curves["f2"], "f2", z)
