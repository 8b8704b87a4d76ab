"""Issue 50, items 1 and 2: every number a user gives has a documented range checked before any work
(one table, charcurves._bounds.BOUNDS, read by the CLI and the API), and expressions that parse
but would blow up (deep nesting, huge literals, products of sums, non-finite columns) are refused
with one line. The option parser and the expression checker are also tried by hypothesis over
extreme values."""

from __future__ import annotations

import contextlib
import functools
import math
import os
import re
import signal

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from charcurves._bounds import BOUNDS, THREADS_PER_CORE, check_number, max_threads, range_text
from charcurves._errors import CharCurvesError, ConfigError, DataError
from charcurves.cli import main
from charcurves.cli._common import UsageError

CORES = THREADS_PER_CORE * max(1, os.cpu_count() or 1)


@pytest.fixture(scope="module")
def small_csv(tmp_path_factory):
    from charcurves.systems import get_system

    path = tmp_path_factory.mktemp("bounds") / "d.csv"
    get_system("duffing").simulate(t_end=20.0, n_points=400).to_csv(path)
    return str(path)


def _one_line(capsys, argv) -> str:
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count("\n") == 1 and err.startswith("charcurves: error: "), err
    assert "Traceback" not in err
    return err.strip()


# ---------------------------------------------------------------------- item 1: the cases of the issue
CASES = [  # (command line after the command, option named, range text)
    (["fit", "{csv}", "--threads", "100000"], "--threads", f"from 1 to {CORES} ({THREADS_PER_CORE} x the CPU count"),
    (["fit", "{csv}", "--snr=-1e308"], "--snr", "from -300 to 300 (dB;"),
    (["simulate", "duffing", "--snr=-1e308"], "--snr", "from -300 to 300 (dB;"),
    (["simulate", "duffing", "--snr=-7000"], "--snr", "got -7000;"),
    (["fit", "{csv}", "--refine-substeps", "99999999999999999999"], "--refine-substeps", "from 1 to 64 (RK4 steps"),
    (["fit", "{csv}", "--refine-substeps", "100000"], "--refine-substeps", "got 100000;"),
    (["fit", "{csv}", "--segment-length", "99999999999999999999"], "--segment-length", "from 16 to 100000"),
    (["fit", "{csv}", "--bands", "99999999999"], "--bands", "from 3 to 1000 (each member is one more fit"),
    (["fit", "{csv}", "--sr-populations", "99999999999"], "--sr-populations", "from 1 to 100"),
    (["fit", "{csv}", "--sr-generations", "99999999999"], "--sr-generations", "from 1 to 10000"),
    (["fit", "{csv}", "--sr-max-size", "1000"], "--sr-max-size", "from 3 to 100"),
    (["simulate", "duffing", "--t-end", "1e-300"], "--t-end", "from 0.001 to 100000"),
    (["select", "{csv}", "--members", "99999999999999"], "--members", "from 3 to 1000"),
    (["select", "{csv}", "--snr", "nan"], "--snr", "got 'nan'"),
    (["benchmark", "--workers", "100000"], "--workers", f"from 1 to {CORES}"),
    (["benchmark", "--realizations", "1e3"], "--realizations", "got '1e3'"),
    (["demo", "--threads", "0"], "--threads", "got 0;"),
    (["fit", "{csv}", "--seed", "1_000"], "--seed", "got '1_000'"),
    (["fit", "{csv}", "--bands-level", "1"], "--bands-level", "from 1e-06 to 0.999999"),
    (["fit", "{csv}", "--sample-rate", "1e400"], "--sample-rate", "got 1e400;"),
    (["fit", "{csv}", "--threads", "9" * 5000], "--threads", "(5000 characters)"),
    (["fit", "{csv}", "--rows", "1_0:50"], "--rows", "START:STOP with integers"),
]


@pytest.mark.parametrize("argv, option, words", CASES, ids=[" ".join(c[0][::2])[:40] + c[1] for c in CASES])
def test_each_number_of_the_issue_is_refused_with_its_range(argv, option, words, small_csv, tmp_path, capsys):
    out = tmp_path / "out"
    err = _one_line(capsys, [a.format(csv=small_csv) for a in argv] + ["--out", str(out)])
    assert f"argument {option}: must be" in err or f"argument {option}: {option} must be" in err, err
    assert words in err, err
    assert not out.exists()


def test_the_help_text_states_each_range(capsys):
    with pytest.raises(SystemExit):
        main(["fit", "--help"])
    text = re.sub(r"\s+", " ", capsys.readouterr().out)
    for name in ("threads", "substeps", "segment_length", "bands", "sr_generations", "sr_populations", "sr_max_size",
                 "snr_db", "bands_level"):
        assert f"range {range_text(name)}" in text, name
    assert f"range 1 ... {CORES}: {THREADS_PER_CORE} x the CPU count" in text


# ---------------------------------------------------------------------- the same table in the API
def test_the_estimator_checks_the_same_ranges():
    from charcurves.fitting import CharacteristicCurves

    cases = [({"threads": 100000}, f"threads (--threads) must be an integer from 1 to {CORES}"),
             ({"snr_db": -1e308}, "snr_db (--snr) must be a number from -300 to 300"),
             ({"random_state": 2**32}, "the seed (random_state, --seed) must be an integer from 0 to 4294967295"),
             ({"free_gain": "False"}, "free_gain must be True or False, got 'False'"),
             ({"exclude_sticking": 1}, "exclude_sticking must be True or False, got 1"),
             ({"hidden": "16"}, "hidden must be a sequence of 1 to 16 layer widths"),
             ({"hidden": [16, 2.5]}, "got [16, 2.5]"),
             ({"hidden": [0]}, "integers from 1 to 4096")]
    for kwargs, words in cases:
        with pytest.raises(ConfigError) as info:
            CharacteristicCurves.from_method(**kwargs).check()
        assert words in str(info.value) and "\n" not in str(info.value), (kwargs, str(info.value))
    CharacteristicCurves.from_method(hidden=(16, 16), free_gain=np.bool_(True), threads=1).check()  # in range: accepted


def test_the_objects_that_take_the_numbers_check_them():
    from charcurves.data import corrupt
    from charcurves.fitting import OutputError, check_band_options
    from charcurves.selection import select_family
    from charcurves.symbolic import make_engine
    from charcurves.systems import get_system

    record = get_system("duffing").simulate(t_end=10.0, n_points=200)
    calls = [
        (lambda: OutputError(substeps=100000).check(), "substeps (--refine-substeps, validate --substeps) must be an "
                                                       "integer from 1 to 64"),
        (lambda: OutputError(segment_length=10**20).check(), "segment_length (--segment-length) must be an integer "
                                                             "from 16 to 100000"),
        (lambda: make_engine({"generations": 99999999999}), "sr option generations (--sr-generations) must be an "
                                                             "integer from 1 to 10000"),
        (lambda: make_engine({"populations": 10**11}), "sr option populations (--sr-populations)"),
        (lambda: check_band_options(10**11, 0.95), "the ensemble size (--bands) must be an integer from 3 to 1000"),
        (lambda: corrupt(record, -7000.0, seed=0), "snr_db (--snr) must be a number from -300 to 300"),
        (lambda: get_system("duffing").simulate(t_end=1e-300), "t_end (--t-end) must be a number from 0.001"),
        (lambda: select_family([record], ["separable"], n_members=10**9), "n_members (--members) must be an integer "
                                                                          "from 3 to 1000"),
        (lambda: select_family([record], ["separable"], snr_db=float("nan")), "snr_db (--snr) must be a number"),
    ]
    for call, words in calls:
        with pytest.raises(ConfigError) as info:
            call()
        assert words in str(info.value), str(info.value)
    assert corrupt(record, math.inf, seed=0) is not None  # inf stays "no noise"


def test_check_number_returns_the_value_and_names_the_label():
    assert check_number("bands", np.int64(8)) == 8 and type(check_number("bands", np.int64(8))) is int
    assert check_number("snr_db", 20) == 20.0
    with pytest.raises(ConfigError, match=r"^my label must be an integer from 3 to 1000 .*got True; give e\.g\. --bands 8$"):
        check_number("bands", True, label="my label")
    with pytest.raises(ConfigError, match="got an integer of 400 digits"):
        check_number("bands", 10**399)
    assert max_threads() == CORES


# ---------------------------------------------------------------------- names given twice, rows past the end
@pytest.mark.parametrize("args, words", [
    (["--method", "poly-cc", "--sym", "f1=odd,f1=even"], "symmetry names f1 twice"),
    (["--method", "parametric", "--basis", "f1=z; f1=z**3; f2=z"], "basis names f1 twice"),
    (["--method", "parametric", "--basis", "f1=z, z; f2=z"], "basis of f1 lists 'z' and 'z', the same function twice"),
])
def test_a_name_given_twice_is_refused(args, words, small_csv, tmp_path, capsys):
    err = _one_line(capsys, ["fit", small_csv, "--out", str(tmp_path / "o"), "--quiet", *args])
    assert words in err


def test_validate_refuses_rows_past_the_end(small_csv, tmp_path, capsys):
    import charcurves as cc
    from charcurves.data import Trajectory

    cc.fit(Trajectory.from_csv(small_csv), method="parametric", basis="f1=z; f2=z, z**3").save(str(tmp_path / "model"))
    err = _one_line(capsys, ["validate", str(tmp_path / "model"), small_csv, "--rows", "100:5000"])
    assert "--rows 100:5000 goes beyond the file, which has 400 rows; choose START:STOP within 0:400" in err


# ---------------------------------------------------------------------- item 2: expressions that blew up
_DEEP = "(" * 250 + "z" + ")" * 250  # beyond the 200 levels of parentheses Python parses
_NESTED_CALLS = "sin(" * 40 + "z" + ")" * 40
BASES = [
    ("f1=z; f2=exp(z**90)", "basis function 'exp(z**90)' of f2 is not finite on the record"),
    ("f1=1e308*z; f2=z", "basis function '1e308*z' of f1 exceeds 1e+100 in size"),
    ("f1=z/0; f2=z", "basis function 'z/0' has a value that is not a finite real number"),
    ("f1=z; f2=log(z)", "basis function 'log(z)' of f2 is not finite on the record"),
    ("f1=z; f2=sqrt(z)", "basis function 'sqrt(z)' of f2 is not finite on the record"),
    ("f1=z; f2=z*0", "basis function 'z*0' of f2 is 0 on every sample"),
    ("f1=z; f2=" + "+".join(["z"] * 900), "has 1800 parts, more than 1500"),
    ("f1=z; f2=" + "*".join(["(z+1)"] * 20), "expands to more than 10000 terms"),
    ("f1=z; f2=" + _NESTED_CALLS, "nests operations 40 deep, more than 30"),
    ("f1=z; f2=exp(exp(exp(exp(z))))", "basis function 'exp(exp(exp(exp(z))))' of f2 exceeds 1e+100 in size"),
    ("f1=z; f2=" + "9" * 5000 + "*z", "is longer than 2000 characters"),
    ("f1=z; f2=9**9**9**9*z", "nests a power in an exponent"),
]


@pytest.mark.parametrize("basis, words", BASES, ids=[b[:30] for b, _ in BASES])
def test_a_basis_that_blew_up_is_refused_with_one_line(basis, words, small_csv, tmp_path, capsys):
    err = _one_line(capsys, ["fit", small_csv, "--out", str(tmp_path / "o"), "--method", "parametric", "--quiet",
                             "--no-figure", "--basis", basis])
    assert words in err
    assert len(err) < 400  # the line quotes a short piece of a long expression, not all of it


_EQ = "x'' + a1*({}) + f1(x') = F"
EQUATIONS = [
    ("*".join(["(x+1)"] * 40), "expands to more than 10000 terms"),
    (_NESTED_CALLS.replace("z", "x"), "nests operations 42 deep, more than 30"),
    (_DEEP.replace("z", "x"), "cannot parse"),
    ("x*1e400", "not a finite real number"),
    ("x**99999999999", "the exponent 99999999999 is too large"),
    ("log(x)", "the a1 of the template is not finite on this record"),
]


@pytest.mark.parametrize("side, words", EQUATIONS, ids=[s[:30] for s, _ in EQUATIONS])
def test_an_equation_that_blew_up_is_refused_with_one_line(side, words, small_csv, tmp_path, capsys):
    err = _one_line(capsys, ["fit", small_csv, "--out", str(tmp_path / "o"), "--method", "poly-cc", "--quiet",
                             "--no-figure", "--equation", _EQ.format(side)])
    assert words in err
    assert len(err) < 400


def test_the_shape_check_accepts_what_fitted_curves_write():
    from charcurves.curves import expression_shape_problem

    poly = " + ".join(f"{k + 0.5}*z**{k}" for k in range(21))  # a degree-20 polynomial, written out
    assert expression_shape_problem(poly) is None
    assert expression_shape_problem("0.8*tanh(50*z) + (z + 1)**3 - sin(cos(z))/2") is None
    assert expression_shape_problem("*".join(["(z+1)"] * 13)) is None  # 8192 terms: at the edge, accepted
    assert expression_shape_problem("*".join(["(z+1)"] * 14)) == "expands to more than 10000 terms (about 1.64e+04)"


# ---------------------------------------------------------------------- property tests (hypothesis)
#: every numeric option of every command, with the arguments its command needs to parse
_NEEDS = {"fit": ["r.csv", "--out", "o"], "simulate": ["duffing", "--out", "o"], "validate": ["m", "r.csv"],
          "select": ["r.csv"], "benchmark": ["--out", "o"], "demo": []}
NUMERIC_OPTIONS = sorted({(opt.split()[0], opt.split()[1], name) for name, b in BOUNDS.items()
                          for opt in b.options if len(opt.split()) == 2 and opt != "benchmark --snr"}
                         | {(cmd, "--seed", "seed") for cmd in ("fit", "simulate", "select", "benchmark", "demo")})

_EXTREME_TEXT = st.one_of(
    st.integers(min_value=-10**30, max_value=10**30).map(str),
    st.sampled_from(["", " ", "nan", "-nan", "inf", "-inf", "1e308", "-1e308", "1e309", "1e-320", "0", "-0", "1_0",
                     "0x10", "1e3", "٣", "1.5", "+7", "--1", "9" * 4400, "1" * 41, "NaN", "Infinity", "1e", ".5"]),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.text(alphabet="0123456789.-+eE_ ", max_size=12),
)


def test_every_numeric_option_is_in_the_property_test():
    from charcurves.cli._parser import build_parser

    parser = build_parser("0")
    sub = next(a for a in parser._actions if a.dest == "command")
    found = {(cmd, act.option_strings[-1]) for cmd, p in sub.choices.items() for act in p._actions
             if act.type is not None and getattr(act.type, "__name__", "") in ("int", "float")}
    assert found == {(cmd, opt) for cmd, opt, _ in NUMERIC_OPTIONS}
    assert ("benchmark", "--snr") not in found  # a comma list: parse_snr_list checks each level (below)


@functools.lru_cache(maxsize=1)
def _parser():
    from charcurves.cli._parser import build_parser

    return build_parser("0")


@settings(max_examples=300, deadline=None)
@given(option=st.sampled_from(NUMERIC_OPTIONS), text=_EXTREME_TEXT)
@example(option=("benchmark", "--forward-cases", "forward_cases"), text="--")  # argparse stored [] for `=--`
def test_parsing_an_extreme_number_gives_a_value_in_range_or_one_line(option, text):
    command, flag, name = option
    bound = BOUNDS[name]
    try:
        args = _parser().parse_args([command, *_NEEDS[command], f"{flag}={text}"])
    except UsageError as exc:
        message = str(exc)
        assert "\n" not in message and f"argument {flag}: must be" in message, message
        assert len(message) < 400
        return
    value = getattr(args, flag.lstrip("-").replace("-", "_"))
    assert isinstance(value, int if bound.kind == "int" else float)
    assert bound.low <= value <= bound.upper() and math.isfinite(value)


@settings(max_examples=100, deadline=None)
@given(levels=st.lists(_EXTREME_TEXT, min_size=1, max_size=3))
def test_benchmark_snr_levels_are_in_range_or_one_line(levels):
    from charcurves.experiments._benchmark import parse_snr_list

    try:
        out = parse_snr_list(",".join(levels))
    except ConfigError as exc:
        assert "\n" not in str(exc) and "--snr" in str(exc)
        return
    assert all(v == math.inf or -300 <= v <= 300 for v in out)


@contextlib.contextmanager
def _hang_guard(seconds: int):
    """Fail (not wait) when one example hangs: a guard against hangs, far above the milliseconds taken."""
    def fail(signum, frame):
        raise AssertionError(f"no answer within {seconds} s")

    previous = signal.signal(signal.SIGALRM, fail)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


_atoms = st.one_of(st.just("z"), st.sampled_from(["0", "1", "2", "0.5", "1e308", "1e-308", "9" * 40, "10**30", "pi"]),
                   st.integers(-10**6, 10**6).map(str))


def _combine(children):
    binary = st.tuples(children, st.sampled_from(["+", "-", "*", "/", "**"]), children).map(
        lambda t: f"({t[0]}){t[1]}({t[2]})")
    call = st.tuples(st.sampled_from(["exp", "log", "sin", "tanh", "sqrt", "cosh", "Abs"]), children).map(
        lambda t: f"{t[0]}({t[1]})")
    chain = st.tuples(children, st.sampled_from(["+", "*"]), st.integers(2, 40)).map(
        lambda t: t[1].join([f"({t[0]})"] * t[2]))
    return st.one_of(binary, call, chain)


_expressions = st.recursive(_atoms, _combine, max_leaves=12)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(text=_expressions)
def test_an_expression_is_refused_with_one_line_or_evaluates_on_a_grid(text):
    import torch

    from charcurves.curves import Basis
    from charcurves.train._linear_fit import MAX_COLUMN, _check_columns

    class _Template:
        arguments = {"f1": "x"}

    grid = np.linspace(-2.0, 2.0, 101)
    basis = Basis([text])
    with _hang_guard(20):
        try:
            basis.check()
        except ConfigError as exc:
            assert "\n" not in str(exc) and len(str(exc)) < 400, str(exc)
            return
        with torch.no_grad():
            phi = basis.features(torch.as_tensor(grid, dtype=torch.float64)).double().numpy()
        assert phi.shape == (grid.size, 1)
        try:
            _check_columns(basis, "f1", _Template(), phi, grid)
        except ConfigError as exc:
            assert "\n" not in str(exc) and str(exc).startswith("basis function "), str(exc)
            return
        assert np.isfinite(phi).all() and np.abs(phi).max() <= MAX_COLUMN


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(text=st.recursive(_atoms, _combine, max_leaves=6))
def test_an_equation_side_is_refused_with_one_line_or_built(text):
    from charcurves.templates import EquationTemplate

    with _hang_guard(20):
        try:
            EquationTemplate(_EQ.format(text.replace("z", "x")))
        except (CharCurvesError, DataError) as exc:
            assert "\n" not in str(exc) and len(str(exc)) < 500, str(exc)


def test_the_docs_page_shows_the_table_the_code_checks():
    from pathlib import Path

    from charcurves._bounds import markdown_table

    page = (Path(__file__).resolve().parents[1] / "docs" / "options.md").read_text(encoding="utf-8")
    assert markdown_table() in page
    assert "options.md" in (Path(__file__).resolve().parents[1] / "mkdocs.yml").read_text(encoding="utf-8")
