"""Property tests of the option parsers added since the last hostile pass (issue 50, item 5):
``--measured`` and ``--sr-operators`` take any text and give a usable value or one line."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from charcurves import ConfigError
from charcurves.symbolic import OPERATORS
from charcurves.templates import parse_measured

_PIECES = st.sampled_from(["x1", "x2", "x", "y", "=", ",", " ", "", "x1=x", "x2=x", "x2=y", "==", "é", "\t", "x1'",
                           "F", "1", "x2=x,x2=y"])
_TEXT = st.one_of(st.lists(_PIECES, max_size=8).map("".join), st.text(max_size=30))


def test_a_state_given_twice_in_measured_is_refused():
    """Before: the last column won silently (x2 measured as y)."""
    with pytest.raises(ConfigError, match=r"^--measured 'x2=x,x2=y' names the state x2 twice; give each state one "
                                          r"column$"):
        parse_measured("x2=x,x2=y")
    assert parse_measured("x2=x, x1=y") == {"x2": "x", "x1": "y"}


@settings(max_examples=300, deadline=None)
@given(text=_TEXT)
def test_measured_text_gives_state_column_pairs_or_one_line(text):
    try:
        out = parse_measured(text)
    except ConfigError as exc:
        assert "\n" not in str(exc) and len(str(exc)) < 300 + len(repr(text))
        return
    pairs = [p.strip() for p in text.split(",") if p.strip()]
    assert len(out) == len(pairs) >= 1  # every pair kept, none overwritten
    assert all(k.strip() == k and v.strip() == v and k and v and "=" not in k for k, v in out.items())


_OPERATOR_TEXT = st.lists(st.one_of(st.sampled_from(OPERATORS), st.sampled_from(["ADD", " Mul ", "", "gamma", "x" * 50,
                                                                                 ";", "tanh(", "+"])),
                          max_size=6).map(",".join)


@settings(max_examples=300, deadline=None)
@given(text=_OPERATOR_TEXT)
def test_sr_operators_give_known_unique_names_with_a_binary_one_or_one_line(text):
    from charcurves.symbolic._engine import check_operators

    try:
        ops = check_operators(text)
    except ConfigError as exc:
        assert "\n" not in str(exc) and len(str(exc)) < 400 + len(text)
        return
    assert set(ops) <= set(OPERATORS) and len(set(ops)) == len(ops)
    assert set(ops) & {"add", "sub", "mul", "div", "pow"}


TANKS = "x1' = g*F - f1(x1); x2' = f1(x1) - f2(x2)"


@pytest.mark.parametrize("extra, flag", [(["--bands", "4"], "--bands"),
                                         (["--sym", "f1=odd"], "--sym"), (["--objective", "equation-error"], "--objective"),
                                         (["--long-record"], "--long-record"), (["--x-col", "F"], "--x-col"),
                                         (["--truth", "duffing"], "--truth"),
                                         (["--family", "first-order"], "--family")])
def test_an_option_a_hidden_state_fit_does_not_use_is_refused(tmp_path, capsys, extra, flag):
    """Before: ``--measured`` ran its own fit and dropped these without a word (``--bands 4`` gave no bands)."""
    from charcurves.cli import main

    csv = tmp_path / "r.csv"
    csv.write_text("t,x,F\n0,0,0\n1,1,1\n")
    capsys.readouterr()
    assert main(["fit", str(csv), "--out", str(tmp_path / "o"), "--equation", TANKS, "--measured", "x2=x", *extra]) == 2
    err = capsys.readouterr().err
    assert err == (f"charcurves: error: {flag} does not apply here: a hidden-state fit (--measured) takes the record, "
                   f"--equation, --free-gain, --start, --method poly-cc or nn-cc, --post-sr, --seed, --time-col and "
                   f"--rows only; drop {flag} (see 'charcurves fit --help')\n")
    assert not (tmp_path / "o").exists()


def test_start_without_measured_is_refused(tmp_path, capsys):
    from charcurves.cli import main

    capsys.readouterr()
    assert main(["fit", str(tmp_path / "r.csv"), "--out", str(tmp_path / "o"), "--start", "linear"]) == 2
    assert capsys.readouterr().err.startswith("charcurves: error: --start does not apply here: it chooses the starts "
                                              "of a hidden-state fit, and --measured is not given; ")


def _one_line(capsys, argv) -> str:
    from charcurves.cli import main

    capsys.readouterr()
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    return err.strip()


def test_a_record_given_twice_to_fit_is_refused(tmp_path, capsys):
    """Before: fitted as two independent records of the same samples (exit 0)."""
    csv = tmp_path / "r.csv"
    csv.write_text("t,x,F\n0,0,0\n1,1,1\n")
    line = _one_line(capsys, ["fit", str(csv), str(tmp_path / "." / "r.csv"), "--out", str(tmp_path / "o")])
    assert line == (f"charcurves: error: the record {str(tmp_path / '.' / 'r.csv')!r} is given twice (also as "
                    f"{str(csv)!r}); give each record once")


@pytest.mark.parametrize("extra, flag", [(["--systems", "duffing"], "--systems"), (["--methods", "poly-cc"], "--methods"),
                                         (["--snr", "20"], "--snr"), (["--workers", "2"], "--workers"),
                                         (["--preset", "paper"], "--preset"), (["--report-only"], "--report-only")])
def test_an_option_of_the_paper_study_is_refused_with_real(tmp_path, capsys, extra, flag):
    """Before: ``benchmark --real silverbox --systems duffing`` dropped --systems without a word."""
    line = _one_line(capsys, ["benchmark", "--real", "silverbox", "--data-dir", str(tmp_path), "--out",
                              str(tmp_path / "o"), *extra])
    assert line == (f"charcurves: error: {flag} does not apply to --real (a real benchmark runs its own fit and test, "
                    f"with --data-dir, --seed and --out only); drop {flag}")


def test_bands_kind_with_posterior_bands_is_refused(tmp_path, capsys):
    """Before: ``--bands posterior --bands-kind seeds`` ran and ignored --bands-kind."""
    line = _one_line(capsys, ["fit", str(tmp_path / "r.csv"), "--out", str(tmp_path / "o"), "--bands", "posterior",
                              "--bands-kind", "seeds"])
    assert line == ("charcurves: error: --bands-kind does not apply here: it chooses the refits of --bands N, and "
                    "--bands posterior refits nothing; drop --bands-kind or give --bands 8 (see 'charcurves fit --help')")


@pytest.mark.parametrize("text", ["", ",,,", " ; "])
def test_no_sr_operators_at_all_says_so(text):
    """Before: "operators () have no binary operator"."""
    from charcurves.symbolic._engine import check_operators

    with pytest.raises(ConfigError, match=r"^no operators given; give auto or names from add, sub, mul, div, pow, .*"
                                          r"\(e\.g\. add,sub,mul,tanh\)$"):
        check_operators(text)


def test_a_named_pipe_in_place_of_the_silverbox_record_is_named_as_such(tmp_path):
    """Before: "no Silverbox record at ..." although a FIFO was there (never opened: it would block)."""
    import os

    from charcurves.datasets import silverbox

    (tmp_path / "silverbox").mkdir()
    os.mkfifo(tmp_path / "silverbox" / "SNLS80mV.csv")
    with pytest.raises(ConfigError, match=r"SNLS80mV\.csv is not a regular file \(a folder, named pipe or device\); "
                                          r"save the benchmark's SNLS80mV\.csv there as a file$"):
        silverbox(data_dir=str(tmp_path))
