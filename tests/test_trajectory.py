"""Trajectory construction, the strict CSV reader, and the error messages for bad input."""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from charcurves._errors import CharCurvesError, DataError
from charcurves.data import MIN_SAMPLES, Trajectory
from charcurves.io._csv import read_csv_columns, write_csv_columns

SILVERBOX_RATE = 610.3515625  # Hz: 10 MHz / 2**14


def _record(n: int = 50, seed: int = 0):
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.01, 0.02, n))
    return t, rng.standard_normal(n), rng.standard_normal(n), rng.standard_normal(n), rng.standard_normal(n)


def _write(path: Path, text: str | bytes) -> Path:
    path.write_bytes(text.encode() if isinstance(text, str) else text)
    return path


def _raises(fn, *patterns: str) -> str:
    """Call ``fn``; it must raise DataError whose message matches every regex in ``patterns``."""
    with pytest.raises(DataError) as info:
        fn()
    msg = str(info.value)
    for pat in patterns:
        assert re.search(pat, msg), f"{pat!r} not in {msg!r}"
    return msg


# ------------------------------------------------------------------ the error type
def test_data_error_is_a_value_error():
    assert issubclass(DataError, ValueError)
    assert issubclass(DataError, CharCurvesError)
    assert MIN_SAMPLES == 30


# ------------------------------------------------------------------ from arrays
def test_from_arrays_values_dt_duration():
    t = np.arange(11) * 0.1
    x = np.sin(t)
    F = np.cos(t)
    tr = Trajectory.from_arrays(t, x, F, name="rec")
    np.testing.assert_array_equal(tr.t, t)
    np.testing.assert_array_equal(tr.x, x)
    np.testing.assert_array_equal(tr.F, F)
    assert tr.n_samples == 11
    assert tr.dt == pytest.approx(0.1, rel=1e-12)
    assert tr.duration == pytest.approx(1.0, rel=1e-12)
    assert tr.name == "rec"
    assert tr.v is None and tr.a is None
    assert not tr.has_derivatives
    assert tr.sampling_nonuniformity() < 1e-9


def test_from_arrays_lists_and_column_vectors_become_float_vectors():
    tr = Trajectory.from_arrays([0, 1, 2], [[1], [2], [3]], np.array([[4, 5, 6]]))
    assert tr.t.dtype == float and tr.t.shape == (3,)
    np.testing.assert_array_equal(tr.x, [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(tr.F, [4.0, 5.0, 6.0])


def test_derivatives_are_optional_and_kept():
    t, x, F, v, a = _record()
    only_v = Trajectory(t=t, x=x, F=F, v=v)
    assert not only_v.has_derivatives
    np.testing.assert_array_equal(only_v.v, v)
    both = Trajectory(t=t, x=x, F=F, v=v, a=a)
    assert both.has_derivatives
    np.testing.assert_array_equal(both.a, a)
    assert list(both.to_columns()) == ["t", "x", "v", "a", "F"]
    assert list(only_v.to_columns()) == ["t", "x", "v", "F"]


def test_arrays_are_read_only_and_caller_arrays_untouched():
    t, x, F, v, a = _record()
    base = np.concatenate([F, F])
    tr = Trajectory(t=t, x=x, F=base[: t.size], v=v, a=a)
    for key in ("t", "x", "F", "v", "a"):
        arr = getattr(tr, key)
        assert not arr.flags.writeable, key
        with pytest.raises(ValueError):
            arr[0] = 1.0
    # the caller's arrays stay writable and changing them does not change the record
    assert t.flags.writeable and x.flags.writeable and base.flags.writeable
    before = tr.F[0]
    base[0] = before + 100.0
    t[0] = -5.0
    assert tr.F[0] == before
    assert tr.t[0] != -5.0


def test_frozen_dataclass():
    t, x, F, _, _ = _record()
    tr = Trajectory(t=t, x=x, F=F)
    with pytest.raises(AttributeError):
        tr.x = x  # type: ignore[misc]


def test_slice_and_replace():
    t, x, F, v, a = _record(40)
    tr = Trajectory(t=t, x=x, F=F, v=v, a=a)
    s = tr.slice(slice(5, 15))
    assert s.n_samples == 10
    np.testing.assert_array_equal(s.t, t[5:15])
    np.testing.assert_array_equal(s.a, a[5:15])
    r = tr.replace(name="other")
    assert r.name == "other" and tr.name == "trajectory"
    np.testing.assert_array_equal(r.x, x)


# ------------------------------------------------------------------ from_dataframe
def test_from_dataframe_pandas_and_dict_agree():
    t, x, F, v, a = _record()
    df = pd.DataFrame({"t": t, "x": x, "F": F})
    from_df = Trajectory.from_dataframe(df, name="df")
    from_dict = Trajectory.from_dataframe({"t": t.tolist(), "x": x.tolist(), "F": F.tolist()})
    for tr in (from_df, from_dict):
        np.testing.assert_array_equal(tr.t, t)
        np.testing.assert_array_equal(tr.x, x)
        np.testing.assert_array_equal(tr.F, F)
        assert tr.v is None and tr.a is None
        assert tr.dt == pytest.approx(float(np.median(np.diff(t))), rel=1e-12)
        assert tr.duration == pytest.approx(t[-1] - t[0], rel=1e-12)
    assert from_df.name == "df"


def test_from_dataframe_uses_v_and_a_columns_when_present():
    t, x, F, v, a = _record()
    tr = Trajectory.from_dataframe(pd.DataFrame({"t": t, "x": x, "F": F, "v": v, "a": a}))
    assert tr.has_derivatives
    np.testing.assert_array_equal(tr.v, v)
    np.testing.assert_array_equal(tr.a, a)
    # renamed derivative columns
    tr2 = Trajectory.from_dataframe({"t": t, "x": x, "F": F, "vel": v, "acc": a}, v_col="vel", a_col="acc")
    np.testing.assert_array_equal(tr2.v, v)
    np.testing.assert_array_equal(tr2.a, a)
    # turned off
    tr3 = Trajectory.from_dataframe({"t": t, "x": x, "F": F, "v": v, "a": a}, v_col=None, a_col=None)
    assert tr3.v is None and tr3.a is None


def test_column_mapping_time_x_force():
    t, x, F, _, _ = _record()
    df = pd.DataFrame({"time": t, "disp": x, "u": F, "x": -x, "F": -F})
    tr = Trajectory.from_dataframe(df, time_col="time", x_col="disp", force_col="u")
    np.testing.assert_array_equal(tr.t, t)
    np.testing.assert_array_equal(tr.x, x)
    np.testing.assert_array_equal(tr.F, F)


def test_sample_rate_without_time_column():
    n, rate = 37, 250.0
    x = np.linspace(-1, 1, n)
    tr = Trajectory.from_dataframe({"x": x, "F": x**2}, time_col=None, sample_rate=rate)
    np.testing.assert_allclose(tr.t, np.arange(n) / rate, rtol=0, atol=0)
    assert tr.t[0] == 0.0
    assert tr.dt == pytest.approx(1 / rate, rel=1e-12)
    assert tr.duration == pytest.approx((n - 1) / rate, rel=1e-12)
    # a file with a time column and a sample rate: the conflict is refused (issue 25: it silently
    # replaced t); time_col=None (--time-col none) ignores the column
    with pytest.raises(DataError, match="the file has a time column 't' and a sample rate was given too; drop "
                                        "--sample-rate to use the file's times, or pass --time-col none"):
        Trajectory.from_dataframe({"t": np.arange(n) * 7.0, "x": x, "F": -x}, sample_rate=rate)
    tr2 = Trajectory.from_dataframe({"t": np.arange(n) * 7.0, "x": x, "F": -x}, sample_rate=rate, time_col=None)
    assert tr2.dt == pytest.approx(1 / rate, rel=1e-12)
    assert Trajectory.from_dataframe({"t": np.arange(n) * 7.0, "x": x, "F": -x}).dt == 7.0


def test_rows_selection_keeps_row_numbering_of_the_full_record():
    n, rate = 100, 50.0
    x = np.arange(n, dtype=float)
    v = 2 * x
    tr = Trajectory.from_dataframe({"x": x, "F": -x, "v": v}, sample_rate=rate, rows=slice(10, 30))
    assert tr.n_samples == 20
    np.testing.assert_array_equal(tr.x, x[10:30])
    np.testing.assert_array_equal(tr.F, -x[10:30])
    np.testing.assert_array_equal(tr.v, v[10:30])
    # t = row / rate with the row counted in the full file, so the selection starts at 10/rate
    assert tr.t[0] == pytest.approx(10 / rate, rel=1e-12)
    assert tr.t[-1] == pytest.approx(29 / rate, rel=1e-12)


def test_rows_selection_skips_bad_rows_outside_the_span():
    x = np.arange(20, dtype=float)
    x[0] = np.nan
    x[-1] = np.inf
    tr = Trajectory.from_dataframe({"x": x, "F": x}, sample_rate=1.0, rows=slice(1, 19))
    assert tr.n_samples == 18
    assert np.isfinite(tr.x).all()


# ------------------------------------------------------------------ CSV
def test_from_csv_reads_values_and_names_after_file(tmp_path):
    path = _write(tmp_path / "bench.csv", "t,x,F\n0,1.5,-2\n0.5,2.5,-3\n1.0,3.5,-4e-3\n")
    tr = Trajectory.from_csv(path)
    np.testing.assert_array_equal(tr.t, [0.0, 0.5, 1.0])
    np.testing.assert_array_equal(tr.x, [1.5, 2.5, 3.5])
    np.testing.assert_array_equal(tr.F, [-2.0, -3.0, -4e-3])
    assert tr.name == "bench"
    assert tr.dt == 0.5 and tr.duration == 1.0
    assert not tr.t.flags.writeable
    assert Trajectory.from_csv(str(path), name="given").name == "given"


@pytest.mark.parametrize("with_derivatives", [False, True])
def test_csv_round_trip_is_bit_exact(tmp_path, with_derivatives):
    rng = np.random.default_rng(7)
    n = 200
    t = np.cumsum(rng.uniform(1e-3, 2e-3, n)) + np.pi
    vals = [rng.standard_normal(n) * 10.0 ** rng.integers(-12, 12, n) for _ in range(4)]
    vals[0][3] = 5e-324  # subnormal
    vals[1][4] = -1e100  # the largest magnitude a Trajectory takes (MAX_MAGNITUDE)
    v, a = (vals[2], vals[3]) if with_derivatives else (None, None)
    tr = Trajectory(t=t, x=vals[0], F=vals[1], v=v, a=a)
    path = tmp_path / "sub" / "rt.csv"  # directory created by the writer
    tr.to_csv(path)
    header = path.read_text().splitlines()[0]
    assert header == ("t,x,v,a,F" if with_derivatives else "t,x,F")
    back = Trajectory.from_csv(path)
    for key in ("t", "x", "F", "v", "a"):
        orig, got = getattr(tr, key), getattr(back, key)
        if orig is None:
            assert got is None
        else:
            assert np.array_equal(orig.view(np.int64), got.view(np.int64)), key  # bit for bit
    assert back.has_derivatives == with_derivatives
    # the atomic writer leaves no temporary files behind
    assert sorted(os.listdir(path.parent)) == ["rt.csv"]


def test_csv_layer_round_trips_the_extremes_of_float64_bit_exactly(tmp_path):
    from charcurves.io import read_csv_columns, write_csv_columns

    cols = {"t": np.array([0.0, 1.0, 2.0]), "x": np.array([5e-324, -1.7976931348623157e308, 1e307])}
    write_csv_columns(tmp_path / "e.csv", cols)
    back = read_csv_columns(tmp_path / "e.csv")
    assert all(np.array_equal(cols[k].view(np.int64), back[k].view(np.int64)) for k in cols)


def test_values_beyond_max_magnitude_are_refused_by_name_not_as_nan(tmp_path):
    """Issue 25: x near 1e307 (finite) ended in "column 'x' has a NaN value at row 0" from the
    differentiator's overflow; the record is refused up front, naming the value and the fix."""
    from charcurves.data._trajectory import MAX_MAGNITUDE

    t = np.linspace(0, 10, 50)
    Trajectory(t=t, x=MAX_MAGNITUDE * np.sin(t), F=np.cos(t))  # the bound itself is accepted
    with pytest.raises(DataError) as info:
        Trajectory(t=t, x=1e307 * np.sin(t + 0.5), F=np.cos(t))
    assert str(info.value) == ("column 'x' has the value 4.79426e+306 at row 0, beyond the 1e+100 in magnitude "
                               "that charcurves computes with (its squares and cubes would overflow); rescale the "
                               "column, e.g. change its units")


def test_rows_beyond_the_file_and_the_same_column_twice_are_refused():
    cols = {"t": np.arange(100.0), "x": np.sin(np.arange(100.0)), "F": np.cos(np.arange(100.0))}
    with pytest.raises(DataError, match=r"^rows 90:500 go beyond the file, which has 100 rows; choose START:STOP "
                                        r"within 0:100$"):
        Trajectory.from_dataframe(cols, rows=slice(90, 500))
    assert Trajectory.from_dataframe(cols, rows=slice(90, 100)).n_samples == 10
    assert Trajectory.from_dataframe(cols, rows=slice(-10, None)).n_samples == 10
    with pytest.raises(DataError, match="x and F are both read from column 'x'; name the forcing with --force-col"):
        Trajectory.from_dataframe(cols, force_col="x")


def test_quality_warnings_flag_gaps_noise_and_a_zero_forcing_only():
    from charcurves.systems import get_system

    tr = get_system("duffing").simulate()
    assert tr.quality_warnings() == []
    t = np.array(tr.t)
    t[300:] += 9 * tr.dt  # a step of 10 median steps: not yet a gap
    assert tr.replace(t=t).quality_warnings() == []
    t[300:] += 1.1 * tr.dt
    (gap,) = tr.replace(t=t).quality_warnings()
    assert gap.startswith("the time step at row 300 is 11.1 times the median step")
    rng = np.random.default_rng(3)
    (noise,) = tr.replace(x=rng.normal(size=tr.n_samples)).quality_warnings()
    assert noise.startswith("x looks like white noise (lag-1 autocorrelation -0.0") or \
        noise.startswith("x looks like white noise (lag-1 autocorrelation 0.0")
    from charcurves.data import corrupt

    assert corrupt(tr, 0.0, on="state", seed=1).quality_warnings() == []  # noisy but a motion: no warning
    assert corrupt(tr, -10.0, on="state", seed=1).quality_warnings()[0].startswith("x looks like white noise")
    assert tr.replace(F=0 * tr.F).quality_warnings()[0].startswith("the forcing F is zero everywhere")
    assert tr.replace(F=tr.x).quality_warnings() == ["x and F hold identical values; check --x-col and --force-col"]


def test_csv_column_mapping_and_rows(tmp_path):
    lines = ["time,pos,force,other"] + [f"{i * 0.01},{i},{-i},{i % 3}" for i in range(60)]
    path = _write(tmp_path / "m.csv", "\n".join(lines) + "\n")
    tr = Trajectory.from_csv(path, time_col="time", x_col="pos", force_col="force", rows=slice(5, 45))
    assert tr.n_samples == 40
    np.testing.assert_array_equal(tr.x, np.arange(5, 45, dtype=float))
    np.testing.assert_array_equal(tr.F, -np.arange(5, 45, dtype=float))
    assert tr.t[0] == pytest.approx(0.05) and tr.dt == pytest.approx(0.01, rel=1e-9)


def test_csv_other_delimiters_and_spaces(tmp_path):
    expect = {"t": [0.0, 1.0], "x": [1.0, 3.0], "F": [2.0, 4.0]}
    for name, text in {
        "semi": "t;x;F\n0;1;2\n1;3;4\n",
        "tab": "t\tx\tF\n0\t1\t2\n1\t3\t4\n",
        "space_after_comma": "t, x, F\n0, 1, 2\n1, 3, 4\n",
        "crlf_bom": "\ufefft,x,F\r\n0,1,2\r\n1,3,4\r\n",
    }.items():
        got = read_csv_columns(_write(tmp_path / f"{name}.csv", text))
        assert {k: v.tolist() for k, v in got.items()} == expect, name


def test_silverbox_format_trailing_comma(tmp_path):
    text = '"V1","V2",\n0.0057756,0.0093978,\n0.0066102,0.012971,\n0.0071389,0.016203,\n'
    path = _write(tmp_path / "box.csv", text)
    cols = read_csv_columns(path)
    assert list(cols) == ["V1", "V2"]  # the empty trailing column is dropped
    tr = Trajectory.from_csv(path, sample_rate=SILVERBOX_RATE, x_col="V2", force_col="V1")
    np.testing.assert_array_equal(tr.x, [0.0093978, 0.012971, 0.016203])
    np.testing.assert_array_equal(tr.F, [0.0057756, 0.0066102, 0.0071389])
    assert tr.dt == pytest.approx(1 / SILVERBOX_RATE, rel=1e-12)
    assert tr.t[2] == pytest.approx(2 / SILVERBOX_RATE, rel=1e-12)


def test_empty_named_column_with_values_is_kept(tmp_path):
    cols = read_csv_columns(_write(tmp_path / "e.csv", "a,,c\n1,2,3\n4,5,6\n"))
    assert {k: v.tolist() for k, v in cols.items()} == {"a": [1.0, 4.0], "column2": [2.0, 5.0], "c": [3.0, 6.0]}


def test_real_silverbox_file(silverbox_csv):
    tr = Trajectory.from_csv(silverbox_csv, sample_rate=SILVERBOX_RATE, x_col="V2", force_col="V1",
                             rows=slice(40650, 105712))
    assert tr.n_samples == 65062
    assert tr.dt == pytest.approx(1 / SILVERBOX_RATE, rel=1e-12)
    assert tr.sampling_nonuniformity() < 1e-6
    assert tr.t[0] == pytest.approx(40650 / SILVERBOX_RATE, rel=1e-12)
    assert np.isfinite(tr.x).all() and np.isfinite(tr.F).all()
    assert tr.name == "SNLS80mV"


# ------------------------------------------------------------------ bad input: arrays
@pytest.mark.parametrize("bad, kind", [(np.nan, "NaN"), (np.inf, "infinite"), (-np.inf, "infinite")])
@pytest.mark.parametrize("col", ["t", "x", "F", "v", "a"])
def test_non_finite_value_names_column_row_and_fix(col, bad, kind):
    t, x, F, v, a = _record(20)
    cols = {"t": t.copy(), "x": x, "F": F, "v": v, "a": a}
    cols[col][7] = bad
    cols[col][12] = bad
    _raises(lambda: Trajectory(**cols), rf"column '{col}' has a{'n' if kind == 'infinite' else ''} {kind} value",
            r"at row 7\b", r"2 non-finite", r"remove or interpolate")


def test_non_finite_in_csv_names_row(tmp_path):
    path = _write(tmp_path / "n.csv", "t,x,F\n0,1,2\n1,nan,3\n2,4,5\n")
    _raises(lambda: Trajectory.from_csv(path), r"column 'x' has a NaN value at row 1", r"remove or interpolate")
    path = _write(tmp_path / "i.csv", "t,x,F\n0,1,2\n1,2,3\n2,4,-inf\n")
    _raises(lambda: Trajectory.from_csv(path), r"column 'F' has an infinite value at row 2", r"--rows")


@pytest.mark.parametrize("col", ["x", "F", "v", "a"])
def test_unequal_lengths(col):
    t, x, F, v, a = _record(20)
    cols = {"t": t, "x": x, "F": F, "v": v, "a": a}
    cols[col] = cols[col][:-3]
    _raises(lambda: Trajectory(**cols), rf"column '{col}' has 17 samples but 't' has 20", r"equal length")


def test_unequal_lengths_in_dict_with_sample_rate():
    _raises(lambda: Trajectory.from_dataframe({"x": np.zeros(10), "F": np.zeros(9)}, sample_rate=5.0),
            r"column 'F' has 9 samples but 't' has 10", r"equal length")


def test_duplicated_time_stamp():
    t = np.array([0.0, 0.1, 0.2, 0.2, 0.3])
    _raises(lambda: Trajectory(t=t, x=np.zeros(5), F=np.zeros(5)),
            r"time repeats at row 3", r"t=0\.2 after 0\.2", r"strictly increasing", r"drop duplicates")


def test_decreasing_time_stamp():
    t = np.array([0.0, 0.1, 0.2, 0.15, 0.3])
    _raises(lambda: Trajectory(t=t, x=np.zeros(5), F=np.zeros(5)),
            r"time goes back at row 3", r"t=0\.15 after 0\.2", r"sort the rows")


def test_too_few_samples_and_wrong_shape():
    _raises(lambda: Trajectory(t=[0.0], x=[1.0], F=[1.0]), r"at least 2 samples, got 1", r"longer record")
    _raises(lambda: Trajectory(t=np.zeros((3, 3)), x=np.zeros(3), F=np.zeros(3)),
            r"column 't' must be one-dimensional, got shape \(3, 3\)", r"single column")
    _raises(lambda: Trajectory(t=[0, 1], x=["a", "b"], F=[1, 2]), r"column 'x' is not numeric", r"numbers only")


def test_duplicate_column_names_in_dataframe():
    df = pd.DataFrame(np.arange(15.0).reshape(5, 3), columns=["t", "x", "x"])
    df["F"] = 1.0
    _raises(lambda: Trajectory.from_dataframe(df), r"column 'x' must be one-dimensional", r"duplicated column names")


def test_non_numeric_dataframe_column():
    df = pd.DataFrame({"t": [0.0, 1.0, 2.0], "x": ["1", "oops", "3"], "F": [0.0, 0.0, 0.0]})
    _raises(lambda: Trajectory.from_dataframe(df), r"column 'x' is not numeric", r"oops", r"numbers only")


# ------------------------------------------------------------------ bad input: mapping
def test_missing_column_lists_columns_and_flag():
    cols = {"t": [0, 1, 2], "pos": [0, 1, 2], "F": [0, 1, 2]}
    msg = _raises(lambda: Trajectory.from_dataframe(cols), r"no column 'x' for x", r"--x-col")
    assert "['t', 'pos', 'F']" in msg
    assert "did you mean" not in msg
    _raises(lambda: Trajectory.from_dataframe(cols, x_col="pos", force_col="u"),
            r"no column 'u' for force", r"--force-col", r"\['t', 'pos', 'F'\]")


def test_missing_column_did_you_mean_case_mismatch(tmp_path):
    path = _write(tmp_path / "c.csv", "T,X,Force\n0,1,2\n1,2,3\n")
    _raises(lambda: Trajectory.from_csv(path, force_col="Force"),
            r"no column 'x' for x \(did you mean 'X'\?\)", r"\['T', 'X', 'Force'\]", r"--x-col")
    _raises(lambda: Trajectory.from_csv(path, x_col="X", force_col="force"), r"did you mean 'Force'\?", r"--force-col")


def test_missing_time_column_suggests_time_col_or_sample_rate():
    _raises(lambda: Trajectory.from_dataframe({"x": [1, 2], "F": [1, 2]}),
            r"no time column 't' in \['x', 'F'\]", r"--time-col", r"--sample-rate")
    _raises(lambda: Trajectory.from_dataframe({"time": [0, 1], "x": [1, 2], "F": [1, 2]}, time_col="Time"),
            r"no time column 'Time'", r"--sample-rate")


@pytest.mark.parametrize("rate", [0, -1.0, np.nan, np.inf, "fast"])
def test_bad_sample_rate(rate):
    _raises(lambda: Trajectory.from_dataframe({"x": np.zeros(5), "F": np.zeros(5)}, sample_rate=rate),
            r"the sample rate \(--sample-rate\) must be a number from 1e-09 to 1e\+12 \(Hz;",
            r"got " + ("-1;" if rate == -1.0 else re.escape(repr(rate))), r"give e\.g\. --sample-rate 100")


@pytest.mark.parametrize("rows, n_sel", [(slice(5, 6), 1), (slice(8, 8), 0), (slice(9, 3), 0), (slice(9, None), 1)])
def test_rows_selecting_too_few(rows, n_sel):
    _raises(lambda: Trajectory.from_dataframe({"x": np.zeros(10), "F": np.zeros(10)}, sample_rate=1.0, rows=rows),
            rf"select {n_sel} of 10 rows", r"wider START:STOP")


def test_require_uniform():
    t = np.arange(50) * 0.01
    tr = Trajectory(t=t, x=np.zeros(50), F=np.zeros(50))
    tr.require_uniform("spectral differentiation")  # uniform: no error
    t2 = t.copy()
    t2[20:] += 0.005  # one step 1.5x the median
    tr2 = Trajectory(t=t2, x=np.zeros(50), F=np.zeros(50))
    assert tr2.sampling_nonuniformity() == pytest.approx(0.5, rel=1e-9)
    _raises(lambda: tr2.require_uniform("spectral differentiation"),
            r"spectral differentiation needs uniform sampling", r"time step at row 20",
            r"by 50 %", r"resample", r"--derivatives spline")
    tr2.require_uniform("lenient", tol=0.6)  # within a wider tolerance


def test_require_samples():
    t = np.arange(20) * 0.1
    tr = Trajectory(t=t, x=t, F=t)
    tr.require_samples(20, "the fit")
    _raises(lambda: tr.require_samples(MIN_SAMPLES, "the parametric fit"),
            rf"the parametric fit needs at least {MIN_SAMPLES} samples, the record has 20", r"longer record")


# ------------------------------------------------------------------ bad input: files
def test_empty_files(tmp_path):
    for name, text in {"empty": b"", "blank": b"\n \n\t\r\n"}.items():
        path = _write(tmp_path / f"{name}.csv", text)
        _raises(lambda: read_csv_columns(path), r"is empty", r"header row and data rows")
    path = _write(tmp_path / "commas.csv", ",,\n,,\n")
    _raises(lambda: read_csv_columns(path), r"has no rows", r"header row and data rows")


def test_header_only(tmp_path):
    path = _write(tmp_path / "h.csv", "t,x,F\n")
    _raises(lambda: Trajectory.from_csv(path), r"has a header but no data rows", r"give the measurements")


def test_numbers_without_header(tmp_path):
    path = _write(tmp_path / "n.csv", "0,1,2\n1,2,3\n")
    _raises(lambda: Trajectory.from_csv(path), r"has no header row", r"add a header such as t,x,F")
    path = _write(tmp_path / "n2.csv", "0.5,-1e3,nan\n1,2,3\n")
    _raises(lambda: read_csv_columns(path), r"no header row")


def test_binary_file(tmp_path):
    path = _write(tmp_path / "b.csv", b"t,x,F\n\x00\x01\x02\xff\xfe\n1,2,3\n")
    _raises(lambda: Trajectory.from_csv(path), r"looks binary", r"export the data as CSV")


def test_latin1_file_is_read(tmp_path):
    path = _write(tmp_path / "l.csv", "t,x,F \xb5N\n0,1,2\n1,2,3\n".encode("latin-1"))
    assert list(read_csv_columns(path)) == ["t", "x", "F \xb5N"]


def test_unreadable_paths(tmp_path):
    missing = tmp_path / "nope.csv"
    msg = _raises(lambda: Trajectory.from_csv(missing), r"does not exist", r"check the path")
    assert "nope.csv" in msg
    _raises(lambda: Trajectory.from_csv(tmp_path), r"is a directory, not a CSV file", r"give the file's path")


def test_permission_denied(tmp_path, monkeypatch):
    # permission bits are not enforced for root (CI runs as root), so the OS refusal is simulated
    import builtins

    path = _write(tmp_path / "p.csv", "t,x,F\n0,1,2\n1,2,3\n")
    real_open = builtins.open

    def refusing_open(file, *args, **kwargs):
        if str(file) == str(path):
            raise PermissionError(13, "Permission denied", str(file))
        return real_open(file, *args, **kwargs)

    monkeypatch.setattr(builtins, "open", refusing_open)
    _raises(lambda: read_csv_columns(path), r"permission denied", r"fix its permissions")


def test_ragged_row_names_line(tmp_path):
    path = _write(tmp_path / "r.csv", "t,x,F\n0,1,2\n1,2\n2,3,4\n")
    _raises(lambda: read_csv_columns(path), r"line 3 of .* has 2 fields but the header has 3", r"fix the ragged row")
    path = _write(tmp_path / "r2.csv", "t,x,F\n0,1,2\n1,2,3,4\n")
    _raises(lambda: read_csv_columns(path), r"line 3 of .* has 4 fields")


def test_line_numbers_count_blank_lines(tmp_path):
    # blank lines are skipped, but the reported line is the one in the file
    path = _write(tmp_path / "b.csv", "t,x,F\n\n0,1,2\n\n1,2\n")
    _raises(lambda: read_csv_columns(path), r"line 5 of .* has 2 fields")
    path = _write(tmp_path / "b2.csv", "\nt,x,F\n0,1,2\n\n1,2,abc\n")
    _raises(lambda: read_csv_columns(path), r"line 5 of .*column 'F': 'abc' is not a number")


def test_non_numeric_cell_names_line_and_column(tmp_path):
    path = _write(tmp_path / "c.csv", "t,x,F\n0,1,2\n1,2,3\n2,3.1.4,5\n")
    _raises(lambda: Trajectory.from_csv(path), r"line 4 of .*column 'x': '3\.1\.4' is not a number",
            r"fix or remove that row")
    long_cell = "y" * 50
    path = _write(tmp_path / "l.csv", f"t,x,F\n0,1,{long_cell}\n")
    msg = _raises(lambda: read_csv_columns(path), r"line 2 of .*column 'F': 'y{17}\.\.\.' is not a number")
    assert long_cell not in msg
    path = _write(tmp_path / "e.csv", "t,x,F\n0,1,2\n1,,3\n")
    _raises(lambda: read_csv_columns(path), r"line 3 of .*column 'x': '' is not a number")


def test_duplicate_column_names_in_csv(tmp_path):
    path = _write(tmp_path / "d.csv", "t,x,x\n0,1,2\n1,2,3\n")
    _raises(lambda: read_csv_columns(path), r"column name 'x' appears twice", r"unique column names")
    path = _write(tmp_path / "d2.csv", "t, x ,x\n0,1,2\n1,2,3\n")
    _raises(lambda: read_csv_columns(path), r"'x' appears twice")


def test_unterminated_quote_or_huge_field(tmp_path):
    path = _write(tmp_path / "q.csv", 't,x\n1,"' + "9" * 200_000 + "\n")
    _raises(lambda: read_csv_columns(path), r"not valid CSV", r"export it again as CSV")


def test_writer_rejects_nothing_and_reader_reads_it_back(tmp_path):
    path = tmp_path / "w.csv"
    write_csv_columns(path, {"a": np.array([1.0, 0.1]), "b": [3, -0.0]})
    assert path.read_text() == "a,b\n1,3\n0.10000000000000001,-0\n"
    back = read_csv_columns(path)
    assert back["a"][1] == 0.1 and np.signbit(back["b"][1])


# ------------------------------------------------------------------ fuzz
_cells = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.sampled_from(["", " ", "t", "x", "F", "V1", '"V2"', "nan", "1e5", "-", "1_0", "\u0661", "0x1", '"', "\r"]),
    st.text(max_size=4),
)
_csv_like = st.lists(
    st.tuples(st.lists(_cells, max_size=5), st.sampled_from([",", ";", "\t", " "]), st.booleans()),
    max_size=8,
).map(lambda rows: "\n".join(sep.join(cells) + (sep if trail else "") for cells, sep, trail in rows))


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.one_of(st.binary(max_size=200), st.text(max_size=200), _csv_like))
def test_fuzz_reader_parses_or_raises_data_error(tmp_path, data):
    path = tmp_path / "fuzz.csv"
    path.write_bytes(data if isinstance(data, bytes) else data.encode("utf-8", "surrogatepass"))
    try:
        out = read_csv_columns(path)
    except DataError as exc:
        assert str(exc)  # a message, never empty
        return
    assert isinstance(out, dict) and out
    lengths = {arr.shape for arr in out.values()}
    assert len(lengths) == 1
    (shape,) = lengths
    assert len(shape) == 1 and shape[0] >= 1
    for name, arr in out.items():
        assert isinstance(name, str) and name
        assert isinstance(arr, np.ndarray) and arr.dtype == np.float64
