"""The bad-input matrix (issue 8), end to end through the CLI and the API.

Every row is one defect a user can feed charcurves. Through ``charcurves fit`` (in process, and a
few as real subprocesses) it must end with exit code 2 and exactly one stderr line that names the
problem and the fix; through the API (``Trajectory.from_csv`` then ``CharacteristicCurves.fit``) it
must raise the row's exception type from ``charcurves._errors`` with a one-line message holding the
same words. Nothing is written for a refused input. The CSV reader, the trajectory builder and the
basis parser are fuzzed with hypothesis.
"""

from __future__ import annotations

import builtins
import dataclasses
import os
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from charcurves._errors import ConfigError, DataError, IdentifiabilityError
from charcurves.cli import main
from charcurves.data import Trajectory
from charcurves.data._trajectory import MultiTrajectory
from charcurves.fitting import CharacteristicCurves


@dataclasses.dataclass(frozen=True)
class Bad:
    """One bad input: the file it reads, extra CLI arguments, the same for the API, and the words
    the one-line message must hold (lower case; the problem and the fix)."""

    id: str
    file: str
    args: tuple = ()
    needles: tuple = ()
    error: type = DataError
    csv_kw: dict | None = dataclasses.field(default_factory=dict)  # None: a CLI-only row (multi-DOF reader)
    est_kw: dict | None = dataclasses.field(default_factory=dict)  # None: a CLI-only row
    command: str = "fit"
    multi: bool = False  # the API reads the file as a MultiTrajectory (t,x1,x2,F1,F2)


NONFINITE = [
    Bad(f"{kind}-in-{col}", f"{kind}_{col}", (), (f"column '{col}'", "value at row 7", "remove or interpolate"))
    for col in ("t", "x", "v", "a", "F") for kind in ("nan", "inf", "-inf")
]

FILES = [
    Bad("empty-file", "empty", (), ("is empty", "header row")),
    Bad("blank-lines-only", "blank", (), ("is empty", "header row")),
    Bad("header-only", "header_only", (), ("header but no data rows", "measurements below")),
    Bad("no-header", "no_header", (), ("no header row", "add a header")),
    Bad("binary-random-bytes", "binary", (), ("looks binary", "export the data as csv")),
    Bad("binary-zip-like", "zip", (), ("looks binary", "export the data as csv")),
    Bad("directory", "directory", (), ("is a directory", "give the file's path")),
    Bad("missing-file", "missing", (), ("does not exist", "check the path")),
    Bad("no-permission", "no_permission", (), ("permission denied", "fix its permissions")),
    Bad("ragged-row-long", "ragged_long", (), ("line 4", "has 4 fields but the header has 3", "fix the ragged row")),
    Bad("ragged-row-short", "ragged_short", (), ("line 3", "has 2 fields but the header has 3", "fix the ragged row")),
    Bad("text-in-a-cell", "text_cell", (), ("line 5", "column 'x'", "'oops' is not a number", "fix or remove")),
    Bad("duplicate-column-names", "dup_names", (), ("column name 'x' appears twice", "unique column names")),
    Bad("unterminated-quote", "bad_quote", (), ("not valid csv", "export it again")),
]

COLUMNS = [
    Bad("missing-x-column", "pos_header", (), ("no column 'x'", "'pos'", "--x-col")),
    Bad("misspelled-force-column", "frc_header", (), ("no column 'f'", "did you mean 'force'", "--force-col")),
    Bad("misspelled-x-option", "position_header", ("--x-col", "postion"),
        ("no column 'postion'", "did you mean 'position'", "--x-col"), csv_kw={"x_col": "postion"}),
    Bad("wrong-case-force-option", "base", ("--force-col", "f"), ("no column 'f'", "did you mean 'f'", "--force-col"),
        csv_kw={"force_col": "f"}),
    Bad("missing-time-column", "time_header", (), ("no time column 't'", "did you mean 'time'", "--time-col",
                                                   "--sample-rate")),
]

TIME = [
    Bad("duplicated-time-stamp", "dup_t", (), ("time repeats at row 10", "strictly increasing", "drop duplicates")),
    Bad("time-goes-back", "back_t", (), ("time goes back at row 51", "strictly increasing", "sort the rows")),
    Bad("nonuniform-savgol", "nonuniform", ("--derivatives", "savgol"),
        ("'savgol' differentiator needs uniform sampling", "row 200", "resample", "--derivatives spline"),
        est_kw={"differentiator": "savgol"}),
    Bad("nonuniform-spectral", "nonuniform", ("--derivatives", "spectral"),
        ("'spectral' differentiator needs uniform sampling", "resample", "--derivatives spline"),
        est_kw={"differentiator": "spectral"}),
    Bad("given-derivatives-absent", "txf", ("--derivatives", "given"), ("needs v and a columns", "--derivatives spline"),
        est_kw={"differentiator": "given"}),
]

#: parametric has no default basis: its rows give the Duffing basis explicitly
_BASIS = "f1=z; f2=z, z**3"


def _method(m: str) -> tuple:
    return ("--method", m, "--basis", _BASIS) if m == "parametric" else ("--method", m)


def _method_kw(m: str) -> dict:
    return {"method": m, "basis": _BASIS} if m == "parametric" else {"method": m}


SHORT = [
    Bad(f"too-few-samples-{m}", "short20", _method(m), (f"method {m} needs at least 30 samples", "has 20",
                                                        "longer record"), est_kw=_method_kw(m))
    for m in ("nn-cc+sym", "nn-cc", "poly-cc", "sindy-cc", "sr", "parametric")
] + [
    Bad("one-sample", "one_row", (), ("at least 2 samples", "got 1", "longer record")),
    Bad("too-few-for-savgol-window", "short31", ("--derivatives", "savgol"),
        ("window=31 needs at least 62 samples", "has 31", "smaller window"), est_kw={"differentiator": "savgol"}),
    Bad("rows-select-too-few", "base", ("--rows", "10:20"), ("needs at least 30 samples", "has 10"),
        csv_kw={"rows": slice(10, 20)}),
]

IDENTIFIABILITY = [
    Bad(f"constant-x-{m}", "const_x", _method(m),
        ("no excitation", "x' of f1 is constant", "cannot be identified", "excite it"),
        IdentifiabilityError, est_kw=_method_kw(m))
    for m in ("nn-cc+sym", "nn-cc", "poly-cc", "parametric", "sindy-cc", "sr")
] + [
    Bad("constant-x-estimated-derivatives", "const_x_txf", (), ("no excitation", "cannot be identified"),
        IdentifiabilityError),
    Bad("everything-constant", "all_const", (), ("no excitation", "cannot be identified"), IdentifiabilityError),
    Bad("constant-force-free-gain", "const_F", ("--free-gain",),
        ("forcing f is constant", "gain g cannot be told apart", "not identifiable", "drop --free-gain"),
        IdentifiabilityError, est_kw={"free_gain": True}),
    Bad("constant-force-sindy", "const_F", ("--method", "sindy"), ("forcing f is constant", "not identifiable"),
        IdentifiabilityError, est_kw={"method": "sindy"}),
    Bad("constant-force-parametric-free-gain", "const_F", (*_method("parametric"), "--free-gain"),
        ("forcing f is constant", "not identifiable"), IdentifiabilityError,
        est_kw={**_method_kw("parametric"), "free_gain": True}),
    Bad("one-sided-velocity-odd-f1", "one_sided_v", ("--sym", "f1=odd"),
        ("an odd prior on f1", "both sides of 0", "neither checked nor used", "use --method nn-cc"),
        IdentifiabilityError, est_kw={"symmetry": "f1=odd"}),
    Bad("one-sided-velocity-sym-method", "one_sided_v", ("--method", "sindy-cc+sym"),
        ("an odd prior on f1", "neither checked nor used", "drop it"), IdentifiabilityError,
        est_kw={"method": "sindy-cc+sym"}),
    Bad("one-sided-velocity-poly", "one_sided_v", ("--method", "poly-cc", "--sym", "f1=odd"),
        ("an odd prior on f1", "leave out --sym"), IdentifiabilityError,
        est_kw={"method": "poly-cc", "symmetry": "f1=odd"}),
    Bad("one-sided-x-even-f2", "positive_x", ("--sym", "f1=odd,f2=even"),
        ("an even prior on f2", "argument x on both sides", "--sym f1=odd,f2=none"), IdentifiabilityError,
        est_kw={"symmetry": "f1=odd,f2=even"}),
]

NAMES = [
    Bad("unknown-method", "base", ("--method", "nn-xx"), ("unknown method 'nn-xx'", "choose one of", "nn-cc+sym"),
        ConfigError, est_kw={"method": "nn-xx"}),
    Bad("unknown-family", "base", ("--family", "quadruple"), ("unknown family 'quadruple'", "separable"),
        ConfigError, est_kw={"family": "quadruple"}),
    Bad("unknown-symmetry", "base", ("--sym", "f1=weird"), ("unknown symmetry 'weird'", "odd, even"),
        ConfigError, est_kw={"symmetry": "f1=weird"}),
    Bad("symmetry-for-unknown-curve", "base", ("--sym", "f3=odd"), ("unknown curve 'f3'", "f1, f2"),
        ConfigError, est_kw={"symmetry": "f3=odd"}),
    Bad("symmetry-on-method-without-prior", "base", ("--method", "nn-cc", "--sym", "f1=odd"),
        ("has no symmetry prior", "use nn-cc+sym"), ConfigError, est_kw={"method": "nn-cc", "symmetry": "f1=odd"}),
    Bad("unknown-preset", "base", ("--preset", "turbo"), ("unknown preset 'turbo'", "default, paper"),
        ConfigError, est_kw={"preset": "turbo"}),
    Bad("unknown-differentiator", "base", ("--derivatives", "magic"), ("unknown differentiator 'magic'", "savgol"),
        ConfigError, est_kw={"differentiator": "magic"}),
    Bad("jump-on-unknown-curve", "base", ("--jump", "f7"), ("unknown curve 'f7'", "f1, f2"),
        ConfigError, est_kw={"jump": ["f7"]}),
    Bad("jump-on-non-neural-method", "base", ("--method", "poly-cc", "--jump", "f1"),
        ("--jump applies to neural curves", "poly-cc"), ConfigError, est_kw={"method": "poly-cc", "jump": ["f1"]}),
    Bad("unknown-sr-engine", "base", ("--method", "sr", "--sr-engine", "gplearn"), ("unknown sr engine 'gplearn'",
                                                                                    "operon"),
        ConfigError, est_kw={"method": "sr", "sr_options": {"engine": "gplearn"}}),
    # checked before the network is trained (post-SR runs after it)
    Bad("unknown-sr-operator", "base", ("--method", "nn-cc+sym+post-sr", "--sr-operators", "add,mul,atan"),
        ("unknown operator(s) ['atan']", "give auto or names from", "sqrtabs"), ConfigError,
        est_kw={"method": "nn-cc+sym+post-sr", "sr_options": {"operators": "add,mul,atan"}}),
    Bad("sr-operators-without-binary", "base", ("--method", "sr", "--sr-operators", "tanh,abs"),
        ("have no binary operator", "include at least 'add'"), ConfigError,
        est_kw={"method": "sr", "sr_options": {"operators": "tanh,abs"}}),
    Bad("basis-for-unknown-curve", "base", ("--method", "parametric", "--basis", "f1=z; f3=z"),
        ("unknown curve(s) ['f3']", "f1, f2"), ConfigError, est_kw={"method": "parametric", "basis": "f1=z; f3=z"}),
    Bad("basis-unknown-symbol", "base", ("--method", "parametric", "--basis", "f1=y; f2=z"),
        ("'y' is not allowed", "use z, numbers"), ConfigError, est_kw={"method": "parametric", "basis": "f1=y; f2=z"}),
    Bad("basis-code-injection", "base", ("--method", "parametric", "--basis", "f1=__import__('os').system('x'); f2=z"),
        ("'__import__' is not allowed", "use z, numbers"), ConfigError,
        est_kw={"method": "parametric", "basis": "f1=__import__('os').system('x'); f2=z"}),
    Bad("basis-exponent-bomb", "base", ("--method", "parametric", "--basis", "f1=9**9**9*z; f2=z"),
        ("'9**9**9*z' nests a power in an exponent", "plain closed form"), ConfigError,
        est_kw={"method": "parametric", "basis": "f1=9**9**9*z; f2=z"}),
    Bad("parametric-without-basis", "base", ("--method", "parametric"),
        ("method 'parametric' needs a basis per curve", 'basis="f1=z, z**3; f2=z, z**3"',
         '--basis "f1=z, z**3; f2=z, z**3"', "DEFAULT_BASIS"), ConfigError, est_kw={"method": "parametric"}),
    Bad("parametric-empty-basis", "base", ("--method", "parametric", "--basis", " "),
        ("method 'parametric' needs a basis per curve", "--basis"), ConfigError,
        est_kw={"method": "parametric", "basis": " "}),
    Bad("basis-without-equals", "base", ("--method", "parametric", "--basis", "z, z**3"),
        ("has no '='", "f1=z; f2=z, z**3"), ConfigError, est_kw={"method": "parametric", "basis": "z, z**3"}),
    Bad("unknown-truth-system", "base", ("--truth", "pendulum"), ("unknown system 'pendulum'", "duffing"),
        ConfigError, est_kw=None),
    Bad("unknown-truth-variant", "base", ("--truth", "duffing", "--truth-variant", "odd"),
        ("unknown duffing variant 'odd'", "paper"), ConfigError, est_kw=None),
    Bad("unknown-gauge", "base", ("--gauge", "f3"), ("gauge", "'f3'", "f1", "f2"), ConfigError,
        est_kw={"gauge": "f3"}),
    Bad("unknown-noisy-side", "base", ("--noisy-side", "both"), ("invalid choice: 'both'", "--help"), ConfigError,
        est_kw={"gain_on": "both", "free_gain": True}),
    Bad("unknown-device", "base", ("--device", "tpu9"), ("unknown device 'tpu9'", "--device cpu"), ConfigError,
        est_kw={"device": "tpu9"}),
]

NUMBERS = [
    Bad("seed-not-integer", "base", ("--seed", "abc"), ("seed", "must be an integer from 0 to 4294967295", "got 'abc'"),
        ConfigError, est_kw={"random_state": "abc"}),
    Bad("seed-fraction", "base", ("--seed", "1.5"), ("seed", "must be an integer from 0 to 4294967295", "1.5"),
        ConfigError, est_kw={"random_state": 1.5}),
    Bad("seed-negative", "base", ("--seed", "-1"), ("seed", "must be an integer from 0 to 4294967295", "--seed 0"),
        ConfigError, est_kw={"random_state": -1}),
    Bad("threads-zero", "base", ("--threads", "0"), ("threads", "must be an integer from 1 to", "--threads 1"),
        ConfigError, est_kw={"threads": 0}),
    Bad("threads-negative", "base", ("--threads", "-2"), ("threads", "must be an integer from 1 to", "--threads 1"),
        ConfigError, est_kw={"threads": -2}),
    Bad("threads-not-integer", "base", ("--threads", "many"), ("threads", "must be an integer from 1 to", "'many'"),
        ConfigError,
        est_kw={"threads": "many"}),
    Bad("sample-rate-negative", "no_time", ("--sample-rate", "-5"), ("sample-rate", "must be a number from 1e-09 to "
                                                                     "1e+12", "--sample-rate 100"),
        csv_kw={"sample_rate": -5.0}),
    Bad("sample-rate-zero", "no_time", ("--sample-rate", "0"), ("sample-rate", "must be a number from 1e-09"),
        csv_kw={"sample_rate": 0.0}),
    Bad("sample-rate-nan", "no_time", ("--sample-rate", "nan"), ("sample-rate", "must be a number from 1e-09", "nan"),
        csv_kw={"sample_rate": float("nan")}),
    Bad("sample-rate-text", "no_time", ("--sample-rate", "fast"), ("sample-rate", "must be a number from", "'fast'"),
        csv_kw={"sample_rate": "fast"}),
    Bad("rows-not-a-range", "base", ("--rows", "abc"), ("--rows must be start:stop", "100:5000"), est_kw=None),
    Bad("rows-reversed", "base", ("--rows", "500:300"), ("rows 500:300 select 0 of 1000 rows", "wider start:stop"),
        csv_kw={"rows": slice(500, 300)}),
    Bad("sr-generations-negative", "base", ("--method", "sr", "--sr-generations", "-3"),
        ("sr-generations", "must be an integer from 1 to 10000", "-3"), ConfigError,
        est_kw={"method": "sr", "sr_options": {"generations": -3}}),
    Bad("sr-max-size-zero", "base", ("--method", "sr", "--sr-max-size", "0"),
        ("sr-max-size", "must be an integer from 3 to 100", "got 0"),
        ConfigError, est_kw={"method": "sr", "sr_options": {"max_size": 0}}),
    Bad("sr-populations-zero", "base", ("--method", "sr-cc", "--sr-populations", "0"),
        ("sr-populations", "must be an integer from 1 to 100", "got 0"), ConfigError,
        est_kw={"method": "sr-cc", "sr_options": {"populations": 0}}),
    Bad("out-is-a-file", "base", ("--out", "{file}"), ("is a file, not a directory", "give a directory path"),
        ConfigError, est_kw=None),
    Bad("out-under-a-file", "base", ("--out", "{file}/sub"), ("lies under the file", "give a directory path"),
        ConfigError, est_kw=None),
]

RECORDS = [  # issue 25: conflicting or impossible record options, huge values
    Bad("seed-beyond-32-bits", "base", ("--seed", "99999999999999999999"),
        ("argument --seed: must be an integer from 0 to 4294967295", "got 99999999999999999999", "--seed 0"),
        ConfigError, est_kw=None),
    Bad("seed-just-beyond-32-bits", "base", ("--seed", str(2**32)), ("32-bit range", "got 4294967296"),
        ConfigError, est_kw=None),
    Bad("sample-rate-with-a-time-column", "base", ("--sample-rate", "100"),
        ("the file has a time column 't'", "drop --sample-rate", "--time-col none"), csv_kw={"sample_rate": 100.0}),
    Bad("time-col-none-without-sample-rate", "base", ("--time-col", "none"),
        ("--time-col none", "give --sample-rate hz"), csv_kw={"time_col": None}),
    Bad("same-column-for-x-and-force", "base", ("--force-col", "x"),
        ("x and f are both read from column 'x'", "--force-col"), csv_kw={"force_col": "x"}),
    Bad("rows-beyond-the-file", "base", ("--rows", "900:5000"),
        ("rows 900:5000 go beyond the file, which has 1000 rows", "within 0:1000"), csv_kw={"rows": slice(900, 5000)}),
    Bad("rows-start-beyond-the-file", "base", ("--rows", "2000:"), ("rows 2000: go beyond", "has 1000 rows"),
        csv_kw={"rows": slice(2000, None)}),
    Bad("two-dof-rows-beyond-the-file", "two", (*("--family", "two-dof"), "--rows", "0:99999"),
        ("rows 0:99999 go beyond the file, which has 1500 rows",), csv_kw={"rows": slice(0, 99999)},
        est_kw={"family": "two-dof"}, multi=True),
    Bad("values-near-1e307", "huge", (), ("column 'x' has the value 4.00293e+305 at row 1", "beyond the 1e+100",
                                          "rescale the column")),
    Bad("huge-time-stamps", "huge_t", (), ("column 't' has the value", "rescale the column")),
]

SIMULATE = [
    Bad("simulate-too-many-points", "", ("duffing", "--n-points", "2000000000"),
        ("argument --n-points: must be an integer from 2 to 2000000", "got 2000000000"), est_kw=None,
        command="simulate"),
    Bad("simulate-two-dof-too-many-points", "", ("two-dof", "--n-points", "2000001"),
        ("argument --n-points: must be an integer from 2 to 2000000", "got 2000001"), est_kw=None, command="simulate"),
    Bad("simulate-endless-time", "", ("duffing", "--t-end", "1e12"),
        ("argument --t-end: must be a number from 0.001 to 100000", "about 1 s per 1000", "got 1e12"), est_kw=None,
        command="simulate"),
    Bad("simulate-seed-beyond-32-bits", "", ("duffing", "--snr", "20", "--seed", "99999999999999999999"),
        ("argument --seed: must be an integer from 0 to 4294967295",), est_kw=None, command="simulate"),
    Bad("simulate-unknown-system", "", ("triple-pendulum",), ("invalid choice: 'triple-pendulum'",), est_kw=None,
        command="simulate"),
    Bad("simulate-one-point", "", ("duffing", "--n-points", "1"), ("--n-points: must be an integer from 2", "got 1"),
        est_kw=None,
        command="simulate"),
    Bad("simulate-negative-duration", "", ("duffing", "--t-end", "-5"), ("--t-end: must be a number from 0.001",
                                                                       "got -5;"), est_kw=None,
        command="simulate"),
    Bad("simulate-snr-nan", "", ("duffing", "--snr", "nan"), ("--snr: must be a number from -300 to 300", "'nan'"),
        est_kw=None,
        command="simulate"),
    Bad("simulate-out-is-a-directory", "", ("duffing", "--out", "{dir}"), ("cannot write", "is a directory",
                                                                          "check the path"),
        est_kw=None, command="simulate"),
    Bad("simulate-unknown-variant", "", ("stick-slip", "--variant", "rough"), ("unknown stick-slip variant 'rough'",),
        est_kw=None, command="simulate"),
]

SEP = "x'' + f1(x') + f2(x) = F"
TEMPLATES = [
    Bad("equation-column-missing", "base", ("--equation", "x'' + f1(y') + f2(x) = F"), ("y'", "not a state", "x'"),
        ConfigError, est_kw={"equation": "x'' + f1(y') + f2(x) = F"}),
    Bad("equation-unknown-forcing", "base", ("--equation", "x'' + f1(x') + f2(x) = G"), ("'g' is not allowed",
                                                                                          "forcings f"),
        ConfigError, est_kw={"equation": "x'' + f1(x') + f2(x) = G"}),
    Bad("equation-second-refers-to-missing-state", "base", ("--equation", SEP + "; y'' + f3(y) = F"),
        ("equation 2", "'y'", "not a state"), ConfigError, est_kw={"equation": SEP + "; y'' + f3(y) = F"}),
    Bad("equation-empty-side", "base", ("--equation", "x'' + + ="), ("empty side", "x'' + f1(x) = f"), ConfigError,
        est_kw={"equation": "x'' + + ="}),
    Bad("equation-code-injection", "base", ("--equation", "__import__('os').system('x')"), ("exactly one '='",),
        ConfigError, est_kw={"equation": "__import__('os').system('x')"}),
    Bad("equation-exponent-bomb", "base", ("--equation", "x'' + 9**9**9*x' + f2(x) = F"), ("exponent", "too large"),
        ConfigError, est_kw={"equation": "x'' + 9**9**9*x' + f2(x) = F"}),
    Bad("equation-curve-with-two-arguments", "base", ("--equation", "x'' + f1(x') + f1(x) = F"),
        ("f1 is used with two arguments", "name the other one differently"), ConfigError,
        est_kw={"equation": "x'' + f1(x') + f1(x) = F"}),
    Bad("equation-and-family", "base", ("--equation", SEP, "--family", "two-dof"),
        ("either a family ('two-dof') or an equation, not both",), ConfigError,
        est_kw={"equation": SEP, "family": "two-dof"}),
    Bad("equation-basis-for-absent-curve", "base",
        ("--equation", "x'' + a1*x' + f2(x) = F", "--method", "parametric", "--basis", "f1=z; f2=z"),
        ("unknown curve(s) ['f1']", "the curves are f2"), ConfigError,
        est_kw={"equation": "x'' + a1*x' + f2(x) = F", "method": "parametric", "basis": "f1=z; f2=z"}),
    Bad("equation-unknown-gauge", "base", ("--equation", SEP, "--gauge", "f9"), ("gauge", "unknown curve 'f9'"),
        ConfigError, est_kw={"equation": SEP, "gauge": "f9"}),
    Bad("family-columns-missing", "base", ("--family", "two-dof"), ("no state column 'x1'", "t,x1,x2,f1,f2"),
        csv_kw=None),
]

# the other families and user-written equations pass the separable path's checks, in its words
_NO_EXCITATION = ("no excitation", "cannot be identified", "excite the system")
_CONST_FORCE = ("forcing f is constant", "gain g cannot be told apart", "not identifiable", "drop --free-gain")
_PD, _FO = ("--family", "position-damping"), ("--family", "first-order")
FAMILIES = [
    Bad(f"position-damping-constant-x-{m}", "const_x", (*_PD, *_method(m)),
        ("argument x of f1 is constant", *_NO_EXCITATION), IdentifiabilityError,
        est_kw={"family": "position-damping", **_method_kw(m)})
    for m in ("nn-cc", "poly-cc", "parametric", "sindy-cc")
] + [
    Bad(f"first-order-constant-x-{m}", "const_x", (*_FO, "--method", m),
        ("argument x of f1 is constant", *_NO_EXCITATION), IdentifiabilityError,
        est_kw={"family": "first-order", "method": m})
    for m in ("nn-cc", "poly-cc", "sindy")
] + [
    Bad("position-damping-everything-constant", "all_const", _PD, _NO_EXCITATION, IdentifiabilityError,
        est_kw={"family": "position-damping"}),
    Bad("position-damping-constant-force-free-gain", "const_F", (*_PD, "--free-gain"), _CONST_FORCE,
        IdentifiabilityError, est_kw={"family": "position-damping", "free_gain": True}),
    Bad("position-damping-constant-force-sindy", "const_F", (*_PD, "--method", "sindy"), _CONST_FORCE[:3],
        IdentifiabilityError, est_kw={"family": "position-damping", "method": "sindy"}),
    Bad("first-order-constant-force-free-gain", "const_F", (*_FO, *_method("parametric"), "--free-gain"),
        _CONST_FORCE, IdentifiabilityError, est_kw={"family": "first-order", **_method_kw("parametric"),
                                                    "free_gain": True}),
    Bad("position-damping-one-sided-odd-f1", "positive_x", (*_PD, "--method", "poly-cc", "--sym", "f1=odd"),
        ("an odd prior on f1", "argument x on both sides of 0", "neither checked nor used", "leave out --sym",
         "crosses 0"), IdentifiabilityError, est_kw={"family": "position-damping", "method": "poly-cc",
                                                     "symmetry": "f1=odd"}),
    Bad("position-damping-one-sided-sym-method", "positive_x", (*_PD, "--method", "nn-cc+sym"),
        ("an odd prior on f1", "neither checked nor used", "drop it (--sym f1=none,f2=odd)"), IdentifiabilityError,
        est_kw={"family": "position-damping", "method": "nn-cc+sym"}),
    Bad("first-order-one-sided-even-f2", "positive_x", (*_FO, "--method", "poly-cc", "--sym", "f1=odd,f2=even"),
        ("an odd prior on f1", "both sides of 0", "--sym f1=none,f2=even"), IdentifiabilityError,
        est_kw={"family": "first-order", "method": "poly-cc", "symmetry": "f1=odd,f2=even"}),
    Bad("position-damping-unknown-curve-symmetry", "base", (*_PD, "--sym", "f3=odd"), ("unknown curve 'f3'",),
        ConfigError, est_kw={"family": "position-damping", "symmetry": "f3=odd"}),
    Bad("position-damping-too-few-samples", "short20", (*_PD, "--method", "poly-cc"),
        ("needs at least 30 samples", "has 20"), est_kw={"family": "position-damping", "method": "poly-cc"}),
    Bad("position-damping-nan-in-x", "nan_x", _PD, ("column 'x'", "value at row 7", "remove or interpolate"),
        est_kw={"family": "position-damping"}),
]

_TD = ("--family", "two-dof")
TWO_DOF = [
    Bad("two-dof-constant-states", "two_const", (*_TD, "--method", "poly-cc"),
        ("argument x1' of f1 is constant", *_NO_EXCITATION), IdentifiabilityError,
        est_kw={"family": "two-dof", "method": "poly-cc"}, multi=True),
    Bad("two-dof-masses-move-together", "two_together", (*_TD, "--method", "poly-cc"),
        ("argument x1 - x2 of f2 is constant", "the masses move together", *_NO_EXCITATION), IdentifiabilityError,
        est_kw={"family": "two-dof", "method": "poly-cc"}, multi=True),
    Bad("two-dof-constant-forces-free-gain", "two_const_F", (*_TD, "--method", "poly-cc", "--free-gain"),
        ("the forcings f1, f2 are constant", *_CONST_FORCE[1:]), IdentifiabilityError,
        est_kw={"family": "two-dof", "method": "poly-cc", "free_gain": True}, multi=True),
    Bad("two-dof-one-sided-odd-f1", "two_one_sided_v1", (*_TD, "--method", "poly-cc", "--sym", "f1=odd"),
        ("an odd prior on f1", "argument x1' on both sides of 0", "neither checked nor used", "leave out --sym"),
        IdentifiabilityError, est_kw={"family": "two-dof", "method": "poly-cc", "symmetry": "f1=odd"}, multi=True),
    Bad("two-dof-missing-x2-column", "two_no_x2", _TD, ("no state column 'x2'", "t,x1,x2,f1,f2"),
        csv_kw={"states": ("x1", "x2"), "forces": ("F1", "F2")}, est_kw={"family": "two-dof"}, multi=True),
    Bad("two-dof-nan-in-F2", "two_nan_F2", _TD, ("column 'f2'", "remove or interpolate"),
        est_kw={"family": "two-dof"}, multi=True),
    Bad("two-dof-given-derivatives-absent", "two_no_derivatives", (*_TD, "--derivatives", "given"),
        ("--derivatives given needs the derivative columns", "--derivatives spline"),
        est_kw={"family": "two-dof", "differentiator": "given"}, multi=True),
    Bad("two-dof-single-dof-record", "base", _TD, ("no state column 'x1'", "t,x1,x2,f1,f2"), csv_kw=None),
    Bad("two-dof-unknown-gauge", "two", (*_TD, "--gauge", "f9"), ("gauge", "unknown curve 'f9'"), ConfigError,
        est_kw={"family": "two-dof", "gauge": "f9"}, multi=True),
    Bad("two-dof-sr-is-separable-only", "two", (*_TD, "--method", "sr"), ("sr", "separable"), ConfigError,
        est_kw={"family": "two-dof", "method": "sr"}, multi=True),
]

_EQ = "x'' + f1(x') + a1*x + a2*x**3 = F"
EQUATIONS = [
    Bad("equation-empty", "base", ("--equation", ""), ("the equation is empty", "leave out --equation"), ConfigError,
        est_kw={"equation": ""}),
    Bad("equation-blank", "base", ("--equation", "  \t "), ("the equation is empty", "x'' + f1(x') + f2(x) = f"),
        ConfigError, est_kw={"equation": "  \t "}),
    Bad("equation-states-the-record-lacks", "base", ("--equation", "x1'' + f1(x1') + f2(x1 - x2) = F1",
                                                     "--method", "poly-cc"),
        ("x1", "multi-dof record", "t,x1,x2,f1,f2"), DataError,
        est_kw={"equation": "x1'' + f1(x1') + f2(x1 - x2) = F1", "method": "poly-cc"}),
    Bad("equation-forcing-the-record-lacks", "base", ("--equation", "x'' + f1(x') + f2(x) = F2", "--method", "poly-cc"),
        ("f2", "multi-dof record", "t,x1,x2,f1,f2"), DataError,
        est_kw={"equation": "x'' + f1(x') + f2(x) = F2", "method": "poly-cc"}),
    Bad("equation-derivative-the-record-lacks", "txf", ("--equation", _EQ, "--derivatives", "given"),
        ("--derivatives given needs the derivative columns", "--derivatives spline"), DataError,
        est_kw={"equation": _EQ, "differentiator": "given"}),
    Bad("equation-unknown-function", "base", ("--equation", "x'' + f1(x') + cosh2(x) = F"),
        ("'cosh2' is not allowed", "use states x"), ConfigError, est_kw={"equation": "x'' + f1(x') + cosh2(x) = F"}),
    Bad("equation-unknown-curve-name", "base", ("--equation", "x'' + g1(x') + f2(x) = F"),
        ("'g1' is not allowed", "curves f1, f2"), ConfigError, est_kw={"equation": "x'' + g1(x') + f2(x) = F"}),
    Bad("equation-two-curves-one-argument", "base", ("--equation", "x'' + f1(x) + f2(x) = F", "--method", "poly-cc"),
        ("f1(x) and f2(x) enter the template in the same way", "neither is identifiable", "merge them"),
        IdentifiabilityError, est_kw={"equation": "x'' + f1(x) + f2(x) = F", "method": "poly-cc"}),
    Bad("equation-scalar-a-curve-absorbs", "base", ("--equation", "x'' + a1*x + f1(x) + f2(x') = F"),
        ("a1*x can be absorbed by f1(x)", "a1 is not identifiable", "drop a1"), IdentifiabilityError,
        est_kw={"equation": "x'' + a1*x + f1(x) + f2(x') = F"}),
    Bad("equation-constant-signal", "const_x", ("--equation", _EQ, "--method", "poly-cc"),
        ("argument x' of f1 is constant", *_NO_EXCITATION), IdentifiabilityError,
        est_kw={"equation": _EQ, "method": "poly-cc"}),
    Bad("equation-constant-force-free-gain", "const_F", ("--equation", _EQ, "--method", "poly-cc", "--free-gain"),
        _CONST_FORCE, IdentifiabilityError, est_kw={"equation": _EQ, "method": "poly-cc", "free_gain": True}),
    Bad("equation-one-sided-odd", "positive_x", ("--equation", "x'' + a1*x' + f1(x) = F", "--method", "poly-cc",
                                                 "--sym", "f1=odd"),
        ("an odd prior on f1", "argument x on both sides of 0", "neither checked nor used", "leave out --sym"),
        IdentifiabilityError, est_kw={"equation": "x'' + a1*x' + f1(x) = F", "method": "poly-cc",
                                      "symmetry": "f1=odd"}),
    Bad("equation-basis-exponent-bomb", "base", ("--equation", _EQ, "--method", "parametric", "--basis", "f1=z**9**9"),
        ("nests a power in an exponent", "plain closed form"), ConfigError,
        est_kw={"equation": _EQ, "method": "parametric", "basis": "f1=z**9**9"}),
]

MATRIX = (NONFINITE + FILES + COLUMNS + TIME + SHORT + IDENTIFIABILITY + NAMES + TEMPLATES + FAMILIES + TWO_DOF
          + EQUATIONS + NUMBERS + RECORDS + SIMULATE)
API_ROWS = [b for b in MATRIX if b.est_kw is not None and b.csv_kw is not None and b.command == "fit"]


def test_the_matrix_is_large_and_ids_unique():
    assert len({b.id for b in MATRIX}) == len(MATRIX)
    assert len(MATRIX) >= 100 and len(API_ROWS) >= 80


# ---------------------------------------------------------------------- the files
def _write(path, columns: dict[str, np.ndarray]) -> str:
    np.savetxt(path, np.column_stack(list(columns.values())), delimiter=",", header=",".join(columns),
               comments="", fmt="%.17g")
    return str(path)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    from charcurves.systems import get_system

    d = tmp_path_factory.mktemp("bad")
    tr = get_system("duffing").simulate()
    t, x, v, a, F = (np.array(c) for c in (tr.t, tr.x, tr.v, tr.a, tr.F))
    full = {"t": t, "x": x, "v": v, "a": a, "F": F}
    out = {"base": _write(d / "base.csv", full), "txf": _write(d / "txf.csv", {"t": t, "x": x, "F": F})}
    for j, col in enumerate(full):
        for kind in ("nan", "inf", "-inf"):
            cols = {k: c.copy() for k, c in full.items()}
            cols[col][7] = float(kind)
            out[f"{kind}_{col}"] = _write(d / f"{kind}_{col}.csv", cols)
    texts = {
        "empty": "", "blank": "  \n\n\t\n", "header_only": "t,x,F\n", "no_header": "0,1,2\n0.1,1,2\n",
        "ragged_long": "t,x,F\n0,1,2\n0.1,1,2\n0.2,1,2,3\n", "ragged_short": "t,x,F\n0,1,2\n0.1,1\n",
        "text_cell": "t,x,F\n0,1,2\n0.1,1,2\n0.2,1,2\n0.3,oops,2\n", "dup_names": "t,x,x,F\n0,1,1,2\n",
        "bad_quote": 't,x\n1,"' + "9" * 200_000 + "\n",
    }
    for name, text in texts.items():
        (d / f"{name}.csv").write_text(text)
        out[name] = str(d / f"{name}.csv")
    (d / "binary.csv").write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR" + np.random.default_rng(0).bytes(400))
    (d / "zip.csv").write_bytes(b"PK\x03\x04\x14\x00\x00\x00\x08\x00" + bytes(range(256)))
    out["binary"], out["zip"] = str(d / "binary.csv"), str(d / "zip.csv")
    (d / "adir").mkdir()
    out["directory"], out["missing"] = str(d / "adir"), str(d / "nope.csv")
    out["no_permission"] = _write(d / "locked.csv", {"t": t, "x": x, "F": F})
    out["pos_header"] = _write(d / "pos.csv", {"t": t, "pos": x, "F": F})
    out["frc_header"] = _write(d / "frc.csv", {"t": t, "x": x, "Force": F})
    out["position_header"] = _write(d / "position.csv", {"t": t, "position": x, "F": F})
    out["time_header"] = _write(d / "time.csv", {"time": t, "x": x, "F": F})
    out["no_time"] = _write(d / "no_time.csv", {"x": x, "F": F})
    td = t.copy()
    td[10] = td[9]
    out["dup_t"] = _write(d / "dup_t.csv", {"t": td, "x": x, "F": F})
    tb = t.copy()
    tb[50], tb[51] = tb[51], tb[50]
    out["back_t"] = _write(d / "back_t.csv", {"t": tb, "x": x, "F": F})
    tn = t.copy()
    tn[200:] += 0.5 * (t[1] - t[0])  # one long step: 50 % off the median
    out["nonuniform"] = _write(d / "nonuniform.csv", {"t": tn, "x": x, "F": F})
    out["short20"] = _write(d / "short20.csv", {k: c[:20] for k, c in full.items()})
    out["short31"] = _write(d / "short31.csv", {"t": t[:31], "x": x[:31], "F": F[:31]})
    out["one_row"] = _write(d / "one_row.csv", {k: c[:1] for k, c in full.items()})
    zero = np.zeros_like(t)
    out["const_x"] = _write(d / "const_x.csv", {"t": t, "x": zero + 0.3, "v": zero, "a": zero, "F": F})
    out["const_x_txf"] = _write(d / "const_x_txf.csv", {"t": t, "x": zero + 0.3, "F": F})
    out["all_const"] = _write(d / "all_const.csv", {"t": t, "x": zero + 0.3, "v": zero, "a": zero, "F": zero})
    out["const_F"] = _write(d / "const_F.csv", {"t": t, "x": x, "v": v, "a": a, "F": zero + 1.0})
    vp = np.abs(v) + 0.01  # moving one way only
    out["one_sided_v"] = _write(d / "one_sided_v.csv", {"t": t, "x": np.cumsum(vp) * (t[1] - t[0]), "v": vp,
                                                         "a": a, "F": F})
    out["positive_x"] = _write(d / "positive_x.csv", {"t": t, "x": x + 2.0, "v": v, "a": a, "F": F})
    two = get_system("two-dof").simulate()
    tt = np.asarray(two.t)
    xs = {s: np.asarray(two.states[s]) for s in ("x1", "x2")}
    vs = {s: np.asarray(two.velocities[s]) for s in ("x1", "x2")}
    as_ = {s: np.asarray(two.accelerations[s]) for s in ("x1", "x2")}
    fs = {f: np.asarray(two.forces[f]) for f in ("F1", "F2")}
    z2 = np.zeros_like(tt)

    def two_dof(name, **change):
        cols = {"t": tt, "x1": xs["x1"], "x2": xs["x2"], "v1": vs["x1"], "a1": as_["x1"], "v2": vs["x2"],
                "a2": as_["x2"], "F1": fs["F1"], "F2": fs["F2"]}
        cols.update(change)
        out[name] = _write(d / f"{name}.csv", {k: c for k, c in cols.items() if c is not None})

    two_dof("two")
    two_dof("two_const", x1=z2 + 0.1, x2=z2 - 0.2, v1=z2, a1=z2, v2=z2, a2=z2)
    two_dof("two_together", x2=xs["x1"], v2=vs["x1"], a2=as_["x1"])
    two_dof("two_const_F", F1=z2 + 1.0, F2=z2 - 0.5)
    v1p = np.abs(vs["x1"]) + 0.01
    two_dof("two_one_sided_v1", v1=v1p)
    two_dof("two_no_x2", x2=None)
    f2_nan = fs["F2"].copy()
    f2_nan[7] = np.nan
    two_dof("two_nan_F2", F2=f2_nan)
    two_dof("two_no_derivatives", v1=None, a1=None, v2=None, a2=None)
    out["huge"] = _write(d / "huge.csv", {"t": t, "x": 1e307 * np.sin(t), "F": 1e307 * F})
    out["huge_t"] = _write(d / "huge_t.csv", {"t": t * 1e305, "x": x, "F": F})
    (d / "a_file").write_text("not a directory")
    out["{file}"], out["{dir}"] = str(d / "a_file"), str(d / "adir")
    return out


@pytest.fixture
def locked(monkeypatch, files):
    """Permission denied on one file (chmod is no test as root: root reads any file)."""
    real_open = builtins.open

    def guarded(path, *args, **kwargs):
        if os.fspath(path) == files["no_permission"]:
            raise PermissionError(13, "Permission denied", os.fspath(path))
        return real_open(path, *args, **kwargs)

    monkeypatch.setattr(builtins, "open", guarded)


def _argv(bad: Bad, files, out_dir) -> list[str]:
    args = [files.get(a, a) for a in bad.args]
    args = [a.replace("{file}", files["{file}"]) for a in args]
    if bad.command == "simulate":
        if "--out" not in args:
            args += ["--out", str(out_dir / "sim.csv")]
        return ["simulate", *args]
    if "--out" not in args:
        args += ["--out", str(out_dir)]
    return ["fit", files[bad.file], *args, "--no-figure", "--quiet"]


# ---------------------------------------------------------------------- CLI, in process
@pytest.mark.parametrize("bad", MATRIX, ids=lambda b: b.id)
def test_cli_refuses_with_exit_2_and_one_line(bad, files, tmp_path, capsys, locked):
    out_dir = tmp_path / "out"
    code = main(_argv(bad, files, out_dir))
    captured = capsys.readouterr()
    err = captured.err
    assert code == 2, (code, err, captured.out[-500:])
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    line = lines[0].lower()
    assert line.startswith("charcurves: error: ")
    for needle in bad.needles:
        assert needle.lower() in line, (needle, err)
    assert "traceback" not in line
    assert not out_dir.exists(), "a refused input must not leave an output directory behind"


# ---------------------------------------------------------------------- the API
@pytest.mark.parametrize("bad", API_ROWS, ids=lambda b: b.id)
def test_api_raises_the_specific_error(bad, files, locked):
    reader = MultiTrajectory.from_csv if bad.multi else Trajectory.from_csv
    with pytest.raises(Exception) as info:
        traj = reader(files[bad.file], **bad.csv_kw)
        CharacteristicCurves.from_method(**{"threads": 1, **bad.est_kw}).fit(traj)
    exc = info.value
    assert type(exc) is bad.error, f"{type(exc).__name__}: {exc}"
    message = str(exc)
    assert "\n" not in message and message
    # argparse words belong to the CLI; the API message names the value instead
    for needle in bad.needles:
        if "invalid" in needle or "--help" in needle or needle.startswith("--seed:") or needle.startswith("--rows"):
            continue
        assert needle.lower() in message.lower(), (needle, message)


API_ONLY = [
    (lambda: CharacteristicCurves(threads=1).fit(np.zeros((100, 3))), DataError, "fit expects a trajectory"),
    (lambda: Trajectory(t=[0, 1, 2], x=[1, 2], F=[0, 0, 0]), DataError, "column 'x' has 2 samples but 't' has 3"),
    (lambda: Trajectory(t=np.zeros((3, 3)), x=np.zeros(3), F=np.zeros(3)), DataError, "must be one-dimensional"),
    (lambda: Trajectory(t=["a", "b"], x=[0, 1], F=[0, 1]), DataError, "column 't' is not numeric"),
    (lambda: CharacteristicCurves().set_params(learning_rate=1), ConfigError, "characteristiccurves has no parameter 'learning_rate'; valid: template"),
    (lambda: CharacteristicCurves.from_method(symmetry=3, threads=1).fit(None), ConfigError, "symmetry must be a string"),
    (lambda: CharacteristicCurves.from_method(gain="heavy", threads=1).fit(None), ConfigError, "gain must be a finite"),
    (lambda: CharacteristicCurves.from_method(gain=0.0, threads=1).fit(None), ConfigError, "gain must be a finite non-zero"),
]


@pytest.mark.parametrize("call,error,needle", API_ONLY, ids=[n for _, _, n in API_ONLY])
def test_api_only_inputs(call, error, needle):
    with pytest.raises(error) as info:
        call()
    assert type(info.value) is error and needle in str(info.value).lower() and "\n" not in str(info.value)


# ---------------------------------------------------------------------- real processes
# two in the fast tier (a fresh interpreter costs seconds on a loaded machine), the rest with -m slow
SUBPROCESS_ROWS = ["empty-file", "constant-x-nn-cc"] + [
    pytest.param(row, marks=pytest.mark.slow)
    for row in ("binary-random-bytes", "misspelled-force-column", "unknown-method", "seed-not-integer",
                "equation-column-missing", "out-is-a-file")]


@pytest.mark.parametrize("row_id", SUBPROCESS_ROWS)
def test_real_process_exit_code_and_stderr(row_id, files, tmp_path):
    bad = next(b for b in MATRIX if b.id == row_id)
    env = dict(os.environ, OMP_NUM_THREADS="1")
    r = subprocess.run([sys.executable, "-m", "charcurves", *_argv(bad, files, tmp_path / "o")],
                       capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 2, r.stderr
    assert r.stdout == ""
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("charcurves: error: "), r.stderr
    assert all(n.lower() in lines[0].lower() for n in bad.needles), r.stderr


# ---------------------------------------------------------------------- seeds and clusters, every command
def _command_argv(command: str, files, out_dir, *extra) -> list[str]:
    return {"fit": ["fit", files["base"], "--out", str(out_dir), "--no-figure", "--quiet"],
            "simulate": ["simulate", "duffing", "--out", str(out_dir / "sim.csv")],
            "demo": ["demo", "--out", str(out_dir)],
            "select": ["select", files["base"], "--out", str(out_dir), "--quiet"],
            "benchmark": ["benchmark", "--out", str(out_dir), "--quiet"]}[command] + list(extra)


@pytest.mark.parametrize("seed", ["99999999999999999999", str(2**32), "-1"])
@pytest.mark.parametrize("command", ["fit", "simulate", "demo", "select", "benchmark"])
def test_every_command_bounds_its_seed_before_any_work(command, seed, files, tmp_path, capsys):
    out_dir = tmp_path / "out"
    code = main(_command_argv(command, files, out_dir, "--seed", seed))
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count("\n") == 1 and err.startswith("charcurves: error: argument --seed: must be an integer from 0 to "
                                                    "4294967295 (the 32-bit range "), err
    assert f"got {seed}; give e.g. --seed 0" in err
    assert not out_dir.exists()


def test_benchmark_address_with_a_local_executor_is_refused(tmp_path, capsys):
    out_dir = tmp_path / "b"
    code = main(["benchmark", "--out", str(out_dir), "--executor", "local", "--address", "ray://head:10001"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert "--address names a ray cluster but --executor is local; drop --executor local" in err.lower()
    assert not out_dir.exists()


# ---------------------------------------------------------------------- fuzzing
_names = st.sampled_from(["t", "x", "F", "v", "a", "T", "pos", "", " x", "t"])
_values = st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=64), st.integers(-3, 3))


@st.composite
def _records(draw):
    names = draw(st.lists(_names, min_size=1, max_size=5))
    n = draw(st.integers(0, 40))
    rows = []
    for i in range(n):
        width = len(names) if draw(st.integers(0, 9)) else draw(st.integers(0, 6))  # now and then ragged
        row = []
        for j in range(width):
            if names[j % len(names)].strip() == "t" and draw(st.booleans()):
                row.append(repr(float(i) * draw(st.sampled_from([0.01, 0.0, -0.01, 1e300]))))
            else:
                row.append(repr(draw(_values)) if draw(st.integers(0, 19)) else draw(st.sampled_from(["", "x", "1,2"])))
        rows.append(",".join(row))
    return ",".join(names) + "\n" + "\n".join(rows)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(text=_records(), sample_rate=st.one_of(st.none(), st.sampled_from([0.0, -1.0, 100.0, float("nan")])))
def test_fuzz_trajectory_from_csv_builds_or_raises_data_error(tmp_path, text, sample_rate):
    path = tmp_path / "fuzz.csv"
    path.write_text(text)
    try:
        traj = Trajectory.from_csv(path, sample_rate=sample_rate)
    except DataError as exc:
        assert str(exc) and "\n" not in str(exc)
        return
    assert traj.n_samples >= 2 and np.all(np.diff(traj.t) > 0)
    assert np.isfinite(traj.x).all() and np.isfinite(traj.F).all()


_tokens = st.sampled_from(["z", "z", "1", "2.5", "1e3", "+", "-", "*", "/", "**", "(", ")", ",", "sin", "tanh",
                           "exp", "Abs", "sign", "pi", "__import__", "'os'", ".", "system", "lambda", ":", "[", "]",
                           "_", "eval", "open", "x", "f1=", "f2=", ";", "=", " ", "#", "\\", "\n", '"', "__class__",
                           "import", "os", "1j", "0x1f", "..."])


@pytest.fixture(scope="module")
def small_record():
    from charcurves.systems import get_system

    return get_system("duffing").simulate(n_points=200)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(parts=st.lists(_tokens, max_size=14))
def test_fuzz_basis_option_fits_or_raises_config_error(parts, small_record):
    """Random token soup as --basis: a parametric fit or a one-line ConfigError, never a hang or
    another exception (the text is token-checked before sympy sees it; exponent bombs are refused)."""
    text = "".join(parts)
    try:
        model = CharacteristicCurves.from_method(method="parametric", basis=text, threads=1).fit(small_record).model_
    except ConfigError as exc:
        assert str(exc) and "\n" not in str(exc)
        return
    assert set(model.curves) == {"f1", "f2"}


_eq_atoms = st.sampled_from(["x''", "x'", "x", "x1''", "x1'", "x2", "y'", "y", "F", "F1", "F2", "G", "t", "f1(x')",
                             "f2(x)", "f3(y)", "f1(x1')", "f2(x1 - x2)", "a1*x'", "2.5", "0", "sin(x)", "z"])
_eq_ops = st.sampled_from([" + ", " - ", "*", " = ", "; ", "(", ")", "**2", ""])


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(parts=st.lists(st.tuples(_eq_atoms, _eq_ops), min_size=1, max_size=7))
def test_fuzz_equation_against_a_record_fits_or_raises_a_charcurves_error(parts, small_record):
    """User-written templates naming states, forcings and curves the record may not have: a fit or
    one line from charcurves' own errors (which column or name is wrong), never a library traceback."""
    from charcurves._errors import CharCurvesError

    text = "".join(a + o for a, o in parts)
    try:
        model = CharacteristicCurves.from_method(method="poly-cc", equation=text, threads=1).fit(small_record).model_
    except CharCurvesError as exc:
        assert str(exc) and "\n" not in str(exc)
        return
    assert model.curves and all(np.isfinite(c(np.zeros(3))).all() for c in model.curves.values())


def test_a_one_sided_prior_on_a_smoothed_record_says_the_smoothing_did_it():
    """Appendix F's Duffing record at -20 dB, realisation 3 (noise on x, ten times the signal): the
    measured x spans [-24, 34] and the clean one [-1.50, 1.45], but the spectral differentiator keeps
    only the slow part, [0.062, 1.80]; the error names the smoothed record, not the user's."""
    from charcurves.data import corrupt
    from charcurves.experiments import Sweep
    from charcurves.systems import get_system

    job = next(j for j in Sweep(systems=["duffing"], methods=["nn-cc+sym"], snr_db=[-20], realizations=4,
                                noise_on="state").jobs() if j.realization == 3)
    record = corrupt(get_system("duffing").simulate(job.t_end, job.n_points), -20, on="state", seed=job.noise_seed)
    assert record.x.min() < -20 and record.x.max() > 30
    with pytest.raises(IdentifiabilityError, match=r"^an odd prior on f2 .* but the record as the differentiator "
                                                    r"smoothed it covers only \[0\.0623, 1\.8\].*crosses 0 \(a record "
                                                    r"whose noise swamps the signal smooths to its slow part\)$"):
        CharacteristicCurves.from_method(method="nn-cc+sym", threads=1).fit(record)
