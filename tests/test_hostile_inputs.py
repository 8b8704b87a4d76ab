"""Issue 50 items 5 and 6: inputs that hang, eat memory or give a silent doubtful answer.

Each is refused with one line on stderr and exit code 2 (through ``charcurves.cli.main`` in
process), or ends in the documented bounded behaviour that the test asserts.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from charcurves._errors import DataError
from charcurves.cli import main
from charcurves.io import MAX_COLUMNS, read_csv_columns


def _run(capsys, *argv) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def _one_line_exit_2(capsys, *argv) -> str:
    code, _, err = _run(capsys, *argv)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2, err
    assert len(lines) == 1, err
    assert lines[0].startswith("charcurves: error: ")
    return lines[0]


def _csv(path, text: str) -> str:
    path.write_text(text, encoding="utf-8")
    return str(path)


# --- item 5: inputs that hang ---------------------------------------------------------------------------------

def test_a_csv_of_200000_columns_is_refused_naming_the_width(tmp_path, capsys):
    n = 200_000
    path = tmp_path / "wide.csv"
    path.write_text(",".join(f"c{i}" for i in range(n)) + "\n" + ",".join("1" for _ in range(n)) + "\n")
    line = _one_line_exit_2(capsys, "fit", path, "--out", tmp_path / "out")
    assert f"has {n} columns, more than the {MAX_COLUMNS} a record may have" in line
    assert "drop the others" in line
    assert not (tmp_path / "out").exists()


def test_duplicate_names_in_a_wide_header_are_found_in_linear_time(tmp_path):
    names = [f"c{i}" for i in range(MAX_COLUMNS - 1)] + ["c5"]
    path = _csv(tmp_path / "dup.csv", ",".join(names) + "\n" + ",".join("1" for _ in names) + "\n")
    with pytest.raises(DataError, match="column name 'c5' appears twice"):
        read_csv_columns(path)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes on this platform")
def test_a_named_pipe_is_refused_without_blocking(tmp_path, capsys):
    fifo = tmp_path / "record.csv"
    os.mkfifo(fifo)  # no writer: open() would block for ever
    line = _one_line_exit_2(capsys, "fit", fifo, "--out", tmp_path / "out")
    assert "is a named pipe (FIFO), not a regular file" in line
    assert "save the data to a CSV file first" in line


@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="no /dev/zero")
def test_a_device_is_refused_as_input(tmp_path, capsys):
    line = _one_line_exit_2(capsys, "fit", "/dev/zero", "--out", tmp_path / "out")
    assert "'/dev/zero' is a device, not a regular file" in line


# --- item 6: cells that float() reads but no one means as numbers -------------------------------------------

@pytest.mark.parametrize(("cell", "why"), [("1_5", "an underscore between digits"),
                                           ("\u0661\u0662", "characters other than ASCII digits"),
                                           ("\u0665.5", "characters other than ASCII digits")])
def test_underscore_and_arabic_indic_digits_are_not_numbers(tmp_path, capsys, cell, why):
    assert float(cell) > 0  # Python itself accepts them
    t = np.arange(30) * 0.1
    rows = [f"{ti:g},{np.sin(ti):.6f},{np.cos(ti):.6f}" for ti in t]
    rows[6] = f"{t[6]:g},{cell},0.5"
    path = _csv(tmp_path / "r.csv", "t,x,F\n" + "\n".join(rows) + "\n")
    line = _one_line_exit_2(capsys, "fit", path, "--out", tmp_path / "out")
    assert f"line 8 of {path!r}: {cell!r} is not a plain decimal number ({why})" in line
    with pytest.raises(DataError, match="not a plain decimal number"):
        read_csv_columns(path)


def test_underscores_and_unicode_in_the_header_are_still_names(tmp_path):
    path = _csv(tmp_path / "r.csv", "t,x_1,F\u00b2\n0,1.5,2\n0.1,1.25e-3,3\n")
    cols = read_csv_columns(path)
    assert list(cols) == ["t", "x_1", "F\u00b2"]
    assert cols["x_1"].tolist() == [1.5, 1.25e-3]


# --- item 6: offsets and time units --------------------------------------------------------------------------

def _duffing():
    from charcurves.systems import get_system

    return get_system("duffing").simulate()


def _write_record(path, t, x, F) -> str:
    lines = ["t,x,F"] + [f"{a!r},{b!r},{c!r}" for a, b, c in zip(map(float, t), map(float, x), map(float, F))]
    path.write_text("\n".join(lines) + "\n")
    return str(path)


def test_an_offset_that_swamps_the_motion_in_float64_is_refused(tmp_path, capsys):
    from charcurves.data import Trajectory

    tr = _duffing()
    with pytest.raises(DataError, match=r"^x is offset by 1e\+09, 1\.[0-9]+e\+09 times its motion \(standard deviation "
                                        r"0\.[0-9]+\): float64 keeps too few digits of the motion; subtract the offset "
                                        r"\(x - 1e\+09\) and fit again$"):
        Trajectory(t=tr.t, x=np.asarray(tr.x) + 1e9, F=tr.F)
    path = _write_record(tmp_path / "r.csv", tr.t, np.asarray(tr.x) + 1e9, tr.F)
    line = _one_line_exit_2(capsys, "fit", path, "--out", tmp_path / "out", "--method", "poly-cc")
    assert "x is offset by 1e+09" in line and "subtract the offset" in line
    assert not (tmp_path / "out").exists()


def test_a_moderate_offset_is_warned_and_none_without_one():
    tr = _duffing()
    assert tr.quality_warnings() == []
    centre = float(np.median(tr.x)) + 10.0
    (line,) = tr.replace(x=np.asarray(tr.x) + 10.0).quality_warnings()
    assert line.startswith(f"x is centred at {centre:.6g}, ")
    assert "the curves of x are anchored at x = 0, outside the data" in line
    assert f"subtract the offset (x - {centre:.6g})" in line
    assert tr.replace(x=np.asarray(tr.x) + 2.0).quality_warnings() == []  # 2 is within 5 standard deviations


def test_a_time_step_of_milliseconds_names_the_time_units(tmp_path, capsys):
    tr = _duffing()
    (line,) = tr.replace(t=np.asarray(tr.t) * 1000.0).quality_warnings()
    step = float(np.median(np.diff(np.asarray(tr.t) * 1000.0)))
    assert line == (f"the time step is {step:.6g} time units: if t is in milliseconds (or sample numbers), convert it "
                    "to seconds (t / 1000), since x', x'' and the curves are per unit of t")
    path = _write_record(tmp_path / "ms.csv", np.asarray(tr.t)[:300] * 1000.0, np.asarray(tr.x)[:300],
                         np.asarray(tr.F)[:300])
    code, _, err = _run(capsys, "fit", path, "--out", tmp_path / "out", "--method", "poly-cc", "--no-figure",
                        "--objective", "equation-error", "--quiet")
    assert code == 0
    assert f"charcurves: warning: the time step is {step:.6g} time units: if t is in milliseconds" in err
