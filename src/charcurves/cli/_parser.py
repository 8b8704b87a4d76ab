"""The argument parser of ``charcurves`` (one line per error, exit 2, no usage dump)."""

from __future__ import annotations

import argparse

from .._bounds import cli_number, range_text
from ._common import MAX_SEED, UsageError

__all__ = ["build_parser"]

_SEED_HELP = f"random seed, 0 ... {MAX_SEED} (default 0)"
_TIME_HELP = "time column (default t); none: ignore any time column and use --sample-rate"
_RATE_HELP = "Hz, for a file without a time column (with one: drop it, or pass --time-col none)"



def _bands_value(text: str):
    """``--bands``: "posterior" (the fit's own posterior) or the number of bootstrap refits."""
    import argparse

    if text.strip().lower() == "posterior":
        return "posterior"
    try:
        return cli_number("bands")(text)
    except argparse.ArgumentTypeError as exc:
        msg = str(exc)
        raise argparse.ArgumentTypeError("must be 'posterior' (the fit's own bands) or " + msg.removeprefix("must be ")
                                         ) from None


_bands_value.__name__ = "int"  # a number where it is one: the bounds' property tests cover --bands N

def ranged(name: str, text: str) -> str:
    """A help text with the option's range from the one table (charcurves._bounds.BOUNDS)."""
    return f"{text}; range {range_text(name)}"


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, exit 2, no usage dump
        raise UsageError(f"{message} (see '{self.prog} --help')")

    def _get_values(self, action, arg_strings):
        # `--opt=--`: argparse drops the "--" as the end-of-options marker and stores [] without calling
        # the option's type, so a number option would silently hold an empty list
        if action.option_strings and action.nargs is None and arg_strings == ["--"]:
            self.error(f"argument {'/'.join(action.option_strings)}: must be a value, got '--'")
        return super()._get_values(action, arg_strings)


def _rows(text: str) -> slice:
    import re

    parts = text.split(":")
    if len(parts) != 2 or len(text) > 41 or not all(re.fullmatch(r"\s*(-?[0-9]+)?\s*", p) for p in parts):
        shown = repr(text) if len(text) <= 41 else f"{text[:20]!r}... ({len(text)} characters)"
        raise argparse.ArgumentTypeError(f"--rows must be START:STOP with integers, e.g. 100:5000, got {shown}")
    start, stop = parts
    return slice(int(start) if start.strip() else None, int(stop) if stop.strip() else None)


def build_parser(version: str) -> argparse.ArgumentParser:
    from .._method_table import METHODS
    from ..systems import MAX_SIMULATE_POINTS, MAX_SIMULATE_SPAN
    from ..systems import SYSTEM_NAMES

    p = _Parser(prog="charcurves", description="Equation discovery with characteristic curves.")
    p.add_argument("--version", action="version", version=f"charcurves {version}")
    sub = p.add_subparsers(dest="command", parser_class=_Parser)

    s = sub.add_parser("simulate", help="simulate a benchmark system to a CSV file (t,x,v,a,F; two-dof: "
                                        "t,x1,x2,v1,a1,v2,a2,F1,F2)")
    s.add_argument("system", choices=SYSTEM_NAMES, help="which system: " + ", ".join(SYSTEM_NAMES))
    s.add_argument("--out", required=True, help="output CSV file")
    s.add_argument("--snr", type=cli_number("snr_db"), default=None, help=ranged("snr_db", "noise level in dB (default: no noise)"))
    s.add_argument("--noise-on", choices=["force", "state"], default=None,
                   help="where the noise goes: the forcing F (default, the paper) or the position x (appendix F)")
    s.add_argument("--noise-reference", choices=["std", "rms"], default=None,
                   help="sigma of the clean signal: std (paper) or rms (authors' scripts, forcing)")
    s.add_argument("--seed", type=cli_number("seed"), default=None, help=_SEED_HELP + "; the noise's (with --snr)")
    s.add_argument("--variant", default="paper", help="paper (default), scripts, or smooth (stick-slip)")
    s.add_argument("--t-end", type=cli_number("t_end"), default=40.0,
                   help=f"end time (default 40; at most {MAX_SIMULATE_SPAN:g}: about 1 s of integration per 1000)")
    s.add_argument("--n-points", type=cli_number("n_points"), default=1000,
                   help=f"samples (default 1000; at most {MAX_SIMULATE_POINTS:,}, a CSV of about 0.25 GB)")

    f = sub.add_parser("fit", help="identify the characteristic curves of a record")
    f.add_argument("csv", nargs="+", help="CSV file with a header row (several: one joint fit, the curves shared, "
                                          "each record's own initial state; result.json 'records')")
    f.add_argument("--out", required=True, help="output directory")
    f.add_argument("--family", default="separable",
                   help="separable (default), first-order, position-damping or two-dof (CSV t,x1,x2,F1,F2)")
    f.add_argument("--equation", default=None,
                   help="your own template instead of a family, e.g. \"x'' + a1*x' + f1(x) = F\" "
                        "(several equations separated by ';')")
    f.add_argument("--measured", default=None,
                   help="with --equation of state equations: the measured states and their columns, e.g. x2=x; "
                        "every other state is hidden (fitted by output error from seeded starts)")
    f.add_argument("--start", default="growing", choices=("growing", "linear"),
                   help="with --measured: how the hidden-state fit starts (default growing)")
    f.add_argument("--post-sr", action="store_true",
                   help="with --measured: distil each learned curve into a closed form and refit its constants by "
                        "output error (result.json 'post_sr'; the --sr-* options apply)")
    f.add_argument("--method", default=None,
                   help=f"one of: {', '.join(METHODS)} (default: nn-cc with the parity priors the record supports, "
                        "tested first; nn-cc+sym with --sym)")
    f.add_argument("--sym", default=None, help="parity priors, e.g. f1=odd,f2=odd; auto: test the parity of "
                                               "unconstrained curves and impose what the data support "
                                               "(default: tested by fast poly-cc fits when --method is not given)")
    f.add_argument("--free-gain", action="store_true", help="learn the input gain g")
    f.add_argument("--gauge", default=None,
                   help="curve(s) anchored at 0, e.g. f1 (default: the family's, separable f2, two-dof f2,f4)")
    f.add_argument("--noisy-side", choices=["force", "acceleration"], default=None,
                   help="with --free-gain: which measured side carries the noise and is regressed on "
                        "(force: the paper's loss; acceleration: noise on the measured state)")
    f.add_argument("--preset", default="default", help="training preset: default or paper")
    f.add_argument("--seed", type=cli_number("seed"), default=0, help=_SEED_HELP)
    f.add_argument("--derivatives", default="auto",
                   help="auto (the record's v, a columns when present, else spectral), given, savgol, spline, spectral, "
                        "kalman, tvr or fd")
    f.add_argument("--jump", default="auto",
                   help="curves with a learned jump at 0, e.g. f1 (dry friction); auto (default): on the "
                        "velocity curve when the record has sticking phases; none: never")
    f.add_argument("--basis", default=None, help="parametric basis, e.g. \"f1=z; f2=z, z**3\"")
    f.add_argument("--sr-engine", default=None, help="symbolic-regression engine: operon (default) or pysr")
    f.add_argument("--sr-generations", type=cli_number("sr_generations"), default=None,
                   help=ranged("sr_generations", "SR generations (iterations)"))
    f.add_argument("--sr-populations", type=cli_number("sr_populations"), default=None,
                   help=ranged("sr_populations", "symbolic regression: independent populations (PySR islands; Operon restarts; default 1)"))
    f.add_argument("--sr-max-size", type=cli_number("sr_max_size"), default=None,
                   help=ranged("sr_max_size", "largest expression size (default 20)"))
    f.add_argument("--sr-operators", default=None,
                   help="operators of post-SR and SR, comma-separated (e.g. add,sub,mul,abs,tanh; any of "
                        "charcurves.symbolic.OPERATORS) or auto (default: post-SR searches + - * and then "
                        "+ - * abs tanh sin cos exp sqrtabs per curve; SR + - *, tanh with sticking)")
    f.add_argument("--keep-sticking", action="store_true", help="fit samples where x' = 0 over a run too")
    f.add_argument("--time-col", default="t", help=_TIME_HELP)
    f.add_argument("--x-col", default="x", help="the position column (default x)")
    f.add_argument("--force-col", default="F", help="the forcing column (default F)")
    f.add_argument("--sample-rate", type=cli_number("sample_rate"), default=None, help=_RATE_HELP)
    f.add_argument("--rows", type=_rows, default=None, help="START:STOP rows to use")
    f.add_argument("--long-record", action="store_true",
                   help="fit a record of more than 5,000,000 samples all the same (refused without it; from "
                        "1,000,000 a warning says the cost)")
    f.add_argument("--truth", default=None,
                   help=f"benchmark system ({', '.join(SYSTEM_NAMES)}) to compare the curves with")
    f.add_argument("--truth-variant", default=None, help="parameter set of --truth (default paper)")
    f.add_argument("--threads", type=cli_number("threads"), default=None,
                   help=ranged("threads", "torch threads (default: 1 per process)"))
    f.add_argument("--device", default="cpu", help="torch device of the neural fits: cpu (default) or cuda")
    f.add_argument("--no-figure", action="store_true", help="do not draw curves.png")
    f.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    f.add_argument("--objective", default=None, choices=["auto", "equation-error", "output-error"],
                   help="auto (default): equation error, then output error (the curves refitted to the free-run "
                        "simulation of the measured x) when the record has no derivative columns; equation-error; "
                        "output-error")
    f.add_argument("--refine", default=None,
                   help="older name of --objective (none = equation-error)")
    f.add_argument("--refine-hold", default=None, help="output error: the input between samples in the free run: "
                                                        "linear (default), zoh, bandlimited")
    f.add_argument("--refine-substeps", type=cli_number("substeps"), default=None,
                   help=ranged("substeps", "output error: RK4 steps per sample (default: chosen from the record's "
                                           "samples per period)"))
    f.add_argument("--segment-length", type=cli_number("segment_length"), default=None,
                   help=ranged("segment_length", "output error: samples per shooting segment (default 64)"))
    f.add_argument("--snr", type=cli_number("snr_db"), default=None,
                   help=ranged("snr_db", "known SNR of the forcing in dB, for the self-check's noise floor (default: "
                                         "estimated)"))
    f.add_argument("--bands", type=_bands_value, nargs="?", const="posterior", default=None, metavar="posterior|N",
                   help=ranged("bands", "uncertainty bands of the curves (result.json, curves.png): the fit's posterior "
                                        "(--bands or --bands posterior; poly-cc, parametric, sindy-cc, nn-cc, nn-cc+sym, "
                                        "by equation or output error) or an "
                                        "ensemble of N bootstrap refits (--bands N)"))
    f.add_argument("--bands-kind", choices=["bootstrap", "seeds"], default=None,
                   help="ensemble of --bands: wild residual bootstrap of the forcing (default) or training seeds")
    f.add_argument("--bands-level", type=cli_number("bands_level"), default=None,
                   help=ranged("bands_level", "coverage level of --bands (default 0.95)"))
    f.add_argument("--report", action="store_true",
                   help="also write report.html: one self-contained page with the equation, curves, diagnostics, "
                        "settings and versions (as 'charcurves report')")

    r = sub.add_parser("report", help="write the one-page HTML report of a fit (equation, curves, diagnostics, "
                                      "settings, versions)")
    r.add_argument("model", help="the folder 'fit --out' wrote (or its model/ folder)")
    r.add_argument("--out", default=None,
                   help="HTML file to write (default: report.html in the fit folder)")
    r.add_argument("--truth", default=None,
                   help=f"benchmark system ({', '.join(SYSTEM_NAMES)}) whose true curves to draw and compare with")
    r.add_argument("--truth-variant", default=None, help="variant of --truth (default paper)")

    v = sub.add_parser("validate", help="free-run a saved model on a record; RMSE and a figure")
    v.add_argument("model", help="model directory (the model/ that fit writes)")
    v.add_argument("csv", help="CSV file with a header row")
    v.add_argument("--rows", type=_rows, action="append", default=None,
                   help="START:STOP rows of a test segment (repeat for several; default: the whole file)")
    v.add_argument("--time-col", default="t", help=_TIME_HELP)
    v.add_argument("--x-col", default="x", help="the position column (default x)")
    v.add_argument("--force-col", default="F", help="the forcing column (default F)")
    v.add_argument("--sample-rate", type=cli_number("sample_rate"), default=None, help=_RATE_HELP)
    v.add_argument("--hold", default=None, help="linear, zoh or bandlimited (default: the model's refinement's, "
                                                "else linear)")
    v.add_argument("--substeps", type=cli_number("substeps"), default=None,
                   help=ranged("substeps", "RK4 steps per sample (default: as refined, else 4)"))
    v.add_argument("--init-window", type=cli_number("init_window"), default=None,
                   help="samples at the start of each span that only fit the initial state (velocity included); "
                        "the RMSE is counted after them, as the nonlinear benchmarks do (default: the state fitted "
                        "to the first 128 samples, the RMSE over all)")
    v.add_argument("--start", default=None, choices=("window", "first-samples", "fitted"),
                   help="a model with hidden states: where its free run starts (default window: the whole state "
                        "fitted to the first 128 samples; first-samples: the measured states from the first 8 "
                        "samples, hidden ones at their fitted values; fitted: the training record's state)")
    v.add_argument("--out", default=None, help="directory for validation.json and validation.png")

    d = sub.add_parser("demo", help="simulate Duffing at 20 dB, fit NN-CC+sym, write results")
    d.add_argument("--out", default="charcurves-demo", help="output directory (default charcurves-demo)")
    d.add_argument("--seed", type=cli_number("seed"), default=0, help=_SEED_HELP)
    d.add_argument("--threads", type=cli_number("threads"), default=None, help=ranged("threads", "torch threads (default 1)"))

    sel = sub.add_parser("select", help="model selection: run the three validation loops on candidate families")
    sel.add_argument("csv", nargs="+", help="CSV records of one system (other initial conditions or forcings)")
    sel.add_argument("--families", default="separable,position-damping",
                     help="candidate families, simplest first (default separable,position-damping)")
    sel.add_argument("--method", default="nn-cc", help="fitting method for every family (default nn-cc)")
    sel.add_argument("--members", type=cli_number("members"), default=6,
                     help=ranged("members", "bootstrap members per record (default 6)"))
    sel.add_argument("--snr", type=cli_number("snr_db"), default=None,
                     help=ranged("snr_db", "known SNR of the forcing in dB (default: estimated)"))
    sel.add_argument("--all", action="store_true", help="test every family and run every loop (more figures)")
    sel.add_argument("--out", default=None, help="directory for selection.json and selection.csv")
    sel.add_argument("--seed", type=cli_number("seed"), default=0, help=_SEED_HELP)
    sel.add_argument("--derivatives", default="auto", help="auto, given, savgol, spline, spectral or fd")
    sel.add_argument("--threads", type=cli_number("threads"), default=None, help=ranged("threads", "torch threads (default 1)"))
    sel.add_argument("--time-col", default="t", help="the time column (default t)")
    sel.add_argument("--x-col", default="x", help="the position column (default x)")
    sel.add_argument("--force-col", default="F", help="the forcing column (default F)")
    sel.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    sel.add_argument("--address", default=None,
                     help="a Ray cluster (e.g. auto or ray://head:10001; default: RAY_ADDRESS if set): every "
                          "family's ensembles are fitted there at once, one task per family")

    b = sub.add_parser("benchmark", help="run the paper's study (sweeps, tables, figures) into a report")
    b.add_argument("--out", required=True, help="output directory (results.sqlite there makes reruns resume)")
    b.add_argument("--systems", default="duffing,stick-slip", help="comma-separated: duffing,stick-slip")
    b.add_argument("--methods", default=None,
                   help=f"comma-separated methods (default: all: {', '.join(METHODS)})")
    b.add_argument("--snr", default=None,
                   help="comma-separated SNR levels in dB (default 40,20,0; --full: 40..-20)")
    b.add_argument("--realizations", type=cli_number("realizations"), default=None,
                   help=ranged("realizations", "noise realisations per level (default 2; --full: 10)"))
    b.add_argument("--full", action="store_true", help="the paper's grid: 61 SNR levels x 10 realisations")
    b.add_argument("--preset", default="default", help="training preset of the neural methods: default or paper")
    b.add_argument("--executor", choices=["local", "ray"], default=None,
                   help="local processes (default) or ray (default when --address or RAY_ADDRESS is given)")
    b.add_argument("--address", default=None,
                   help="Ray cluster to run on, e.g. auto or ray://head:10001 (default: $RAY_ADDRESS when set); "
                        "see docs/cluster.md")
    b.add_argument("--seed", type=cli_number("seed"), default=0, help=f"base seed of every dataset, fit and validation case, "
                                                       f"0 ... {MAX_SEED} (default 0)")
    b.add_argument("--workers", type=cli_number("workers"), default=None,
                   help=ranged("workers", "parallel workers (default: the CPU count)"))
    b.add_argument("--forward-cases", type=cli_number("forward_cases"), default=None,
                   help=ranged("forward_cases", "validation cases per model (default 2; --full: 10)"))
    b.add_argument("--skip", default="", help="side studies to leave out: forward,lyapunov,miw,sensitivity,appendix-f")
    b.add_argument("--retry-failed", action="store_true", help="also rerun jobs stored as failed")
    b.add_argument("--variant", choices=["paper", "scripts"], default="paper",
                   help="systems' parameters: paper (the paper's text, default) or scripts (the authors' scripts, "
                        "with which Tables 2 and 3 were made: Duffing -1.05/1.02, stick-slip 0.3 with tanh(500 v))")
    b.add_argument("--noise-on", choices=["force", "state"], default="force",
                   help="force: the paper's main study (default); state: Appendix F alone, noise on x, the paper's "
                        "protocol (Savitzky-Golay + equation error) beside the default (output error)")
    b.add_argument("--report-only", action="store_true",
                   help="run nothing: rebuild report.md/.html and figures/ from the files in --out (results.csv, "
                        "run.json, extras.json, appendix_f.csv)")
    b.add_argument("--real", default=None,
                   help="a real benchmark instead of the paper's study: silverbox or bouc-wen (generated from its "
                        "definition); fits the estimation record, free-runs the tests after their initialisation "
                        "window; real.json, real.md")
    b.add_argument("--data-dir", default=None,
                   help="with --real: the folder that holds <benchmark>/ (e.g. silverbox/SNLS80mV.csv); default "
                        "$CHARCURVES_DATA_DIR, else the nonlinear-benchmarks package when installed")
    b.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    return p


