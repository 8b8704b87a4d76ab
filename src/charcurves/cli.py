"""The ``charcurves`` command line: a thin layer over the public API.

Every user error ends with exit code 2 and one line on stderr naming the problem and the fix.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
import time

__all__ = ["main"]


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, exit 2, no usage dump
        raise _UsageError(f"{message} (see '{self.prog} --help')")


class _UsageError(Exception):
    pass


def _rows(text: str) -> slice:
    try:
        start, stop = text.split(":")
        return slice(int(start) if start.strip() else None, int(stop) if stop.strip() else None)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--rows must be START:STOP with integers, e.g. 100:5000, got {text!r}") from None


def _build_parser() -> argparse.ArgumentParser:
    from .fitting import METHODS
    from .systems import SYSTEM_NAMES

    p = _Parser(prog="charcurves", description="Equation discovery with characteristic curves.")
    p.add_argument("--version", action="version", version=f"charcurves {_version()}")
    sub = p.add_subparsers(dest="command", parser_class=_Parser)

    s = sub.add_parser("simulate", help="simulate a benchmark system to a CSV file (t,x,v,a,F; two-dof: "
                                        "t,x1,x2,v1,a1,v2,a2,F1,F2)")
    s.add_argument("system", choices=SYSTEM_NAMES)
    s.add_argument("--out", required=True, help="output CSV file")
    s.add_argument("--snr", type=float, default=None, help="noise level in dB (default: no noise)")
    s.add_argument("--noise-on", choices=["force", "state"], default="force")
    s.add_argument("--noise-reference", choices=["std", "rms"], default=None,
                   help="sigma of the clean signal: std (paper) or rms (authors' scripts, forcing)")
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--variant", default="paper", help="paper (default), scripts, or smooth (stick-slip)")
    s.add_argument("--t-end", type=float, default=40.0)
    s.add_argument("--n-points", type=int, default=1000)

    f = sub.add_parser("fit", help="identify the characteristic curves of a record")
    f.add_argument("csv", help="CSV file with a header row")
    f.add_argument("--out", required=True, help="output directory")
    f.add_argument("--family", default="separable",
                   help="separable (default), first-order, position-damping or two-dof (CSV t,x1,x2,F1,F2)")
    f.add_argument("--equation", default=None,
                   help="your own template instead of a family, e.g. \"x'' + a1*x' + f1(x) = F\" "
                        "(several equations separated by ';')")
    f.add_argument("--method", default="nn-cc+sym", help=f"one of: {', '.join(METHODS)}")
    f.add_argument("--sym", default=None, help="parity priors, e.g. f1=odd,f2=odd; auto: test the parity of "
                                               "unconstrained curves and impose what the data support")
    f.add_argument("--free-gain", action="store_true", help="learn the input gain g")
    f.add_argument("--gauge", default=None,
                   help="curve(s) anchored at 0, e.g. f1 (default: the family's, separable f2, two-dof f2,f4)")
    f.add_argument("--noisy-side", choices=["force", "acceleration"], default="force",
                   help="with --free-gain: which measured side carries the noise and is regressed on "
                        "(force: the paper's loss; acceleration: noise on the measured state)")
    f.add_argument("--preset", default="default", help="training preset: default or paper")
    f.add_argument("--seed", type=int, default=0)
    f.add_argument("--derivatives", default="auto", help="auto, given, savgol, spline, spectral or fd")
    f.add_argument("--jump", default="auto",
                   help="curves with a learned jump at 0, e.g. f1 (dry friction); auto (default): on the "
                        "velocity curve when the record has sticking phases; none: never")
    f.add_argument("--basis", default=None, help="parametric basis, e.g. \"f1=z; f2=z, z**3\"")
    f.add_argument("--sr-engine", default=None, help="symbolic-regression engine: operon (default) or pysr")
    f.add_argument("--sr-generations", type=int, default=None, help="SR generations (iterations)")
    f.add_argument("--sr-populations", type=int, default=None)
    f.add_argument("--sr-max-size", type=int, default=None, help="largest expression size (default 20)")
    f.add_argument("--keep-sticking", action="store_true", help="fit samples where x' = 0 over a run too")
    f.add_argument("--time-col", default="t")
    f.add_argument("--x-col", default="x")
    f.add_argument("--force-col", default="F")
    f.add_argument("--sample-rate", type=float, default=None, help="Hz, when the file has no time column")
    f.add_argument("--rows", type=_rows, default=None, help="START:STOP rows to use")
    f.add_argument("--truth", default=None,
                   help=f"benchmark system ({', '.join(SYSTEM_NAMES)}) to compare the curves with")
    f.add_argument("--truth-variant", default="paper")
    f.add_argument("--threads", type=int, default=None, help="torch threads (default: 1 per process)")
    f.add_argument("--device", default="cpu")
    f.add_argument("--no-figure", action="store_true")
    f.add_argument("--quiet", action="store_true")
    f.add_argument("--refine", default="auto",
                   help="output-error refinement of closed-form curves, gain and constant by free-run simulation: "
                        "output-error, none, or auto (default: for --free-gain fits of closed forms on estimated "
                        "derivatives, i.e. measured records)")
    f.add_argument("--refine-hold", default=None, help="input between samples in the free run: linear (default), zoh, "
                                                        "bandlimited")
    f.add_argument("--refine-substeps", type=int, default=None, help="RK4 steps per sample in the free run (default 4)")
    f.add_argument("--bands", type=int, default=None, metavar="N",
                   help="uncertainty bands of the curves from an ensemble of N refits (result.json, curves.png)")
    f.add_argument("--bands-kind", choices=["bootstrap", "seeds"], default="bootstrap",
                   help="ensemble of --bands: wild residual bootstrap of the forcing (default) or training seeds")
    f.add_argument("--bands-level", type=float, default=0.95, help="coverage level of --bands (default 0.95)")

    v = sub.add_parser("validate", help="free-run a saved model on a record; RMSE and a figure")
    v.add_argument("model", help="model directory (the model/ that fit writes)")
    v.add_argument("csv", help="CSV file with a header row")
    v.add_argument("--rows", type=_rows, action="append", default=None,
                   help="START:STOP rows of a test segment (repeat for several; default: the whole file)")
    v.add_argument("--time-col", default="t")
    v.add_argument("--x-col", default="x")
    v.add_argument("--force-col", default="F")
    v.add_argument("--sample-rate", type=float, default=None, help="Hz, when the file has no time column")
    v.add_argument("--hold", default=None, help="linear, zoh or bandlimited (default: the model's refinement's, "
                                                "else linear)")
    v.add_argument("--substeps", type=int, default=None, help="RK4 steps per sample (default: as refined, else 4)")
    v.add_argument("--out", default=None, help="directory for validation.json and validation.png")

    d = sub.add_parser("demo", help="simulate Duffing at 20 dB, fit NN-CC+sym, write results")
    d.add_argument("--out", default="charcurves-demo")
    d.add_argument("--seed", type=int, default=0)
    d.add_argument("--threads", type=int, default=None)

    sel = sub.add_parser("select", help="model selection: run the three validation loops on candidate families")
    sel.add_argument("csv", nargs="+", help="CSV records of one system (other initial conditions or forcings)")
    sel.add_argument("--families", default="separable,position-damping",
                     help="candidate families, simplest first (default separable,position-damping)")
    sel.add_argument("--method", default="nn-cc", help="fitting method for every family (default nn-cc)")
    sel.add_argument("--members", type=int, default=6, help="bootstrap members per record (default 6)")
    sel.add_argument("--snr", type=float, default=None, help="known SNR of the forcing in dB (default: estimated)")
    sel.add_argument("--all", action="store_true", help="test every family and run every loop (more figures)")
    sel.add_argument("--out", default=None, help="directory for selection.json and selection.csv")
    sel.add_argument("--seed", type=int, default=0)
    sel.add_argument("--derivatives", default="auto", help="auto, given, savgol, spline, spectral or fd")
    sel.add_argument("--threads", type=int, default=None, help="torch threads (default 1)")
    sel.add_argument("--time-col", default="t")
    sel.add_argument("--x-col", default="x")
    sel.add_argument("--force-col", default="F")
    sel.add_argument("--quiet", action="store_true")

    b = sub.add_parser("benchmark", help="run the paper's study (sweeps, tables, figures) into a report")
    b.add_argument("--out", required=True, help="output directory (results.sqlite there makes reruns resume)")
    b.add_argument("--systems", default="duffing,stick-slip", help="comma-separated: duffing,stick-slip")
    b.add_argument("--methods", default=None,
                   help=f"comma-separated methods (default: all twelve: {', '.join(METHODS)})")
    b.add_argument("--snr", default=None,
                   help="comma-separated SNR levels in dB (default 40,20,0; --full: 40..-20)")
    b.add_argument("--realizations", type=int, default=None,
                   help="noise realisations per level (default 2; --full: 10)")
    b.add_argument("--full", action="store_true", help="the paper's grid: 61 SNR levels x 10 realisations")
    b.add_argument("--preset", default="default", help="training preset of the neural methods: default or paper")
    b.add_argument("--executor", choices=["local", "ray"], default="local")
    b.add_argument("--workers", type=int, default=None, help="parallel workers (default: the CPU count)")
    b.add_argument("--forward-cases", type=int, default=None, help="validation cases per model (default 2; --full: 10)")
    b.add_argument("--skip", default="", help="side studies to leave out: forward,lyapunov,miw,sensitivity,appendix-f")
    b.add_argument("--retry-failed", action="store_true", help="also rerun jobs stored as failed")
    b.add_argument("--quiet", action="store_true")
    return p


def _version() -> str:
    from . import __version__

    return __version__


def _say(msg: str, quiet: bool = False) -> None:
    if not quiet:
        print(msg, flush=True)


def _progress_printer(enabled: bool):
    """A training callback printing at most every 2 s, starting 2 s in (short fits stay silent)."""
    if not enabled:
        return None
    last = [time.monotonic()]

    def report(phase, step, total, loss):
        now = time.monotonic()
        if now - last[0] >= 2.0:
            last[0] = now
            print(f"  [{phase}] {step}/{total}  loss {loss:.4g}  (Ctrl-C stops and keeps the best model so far)",
                  file=sys.stderr, flush=True)

    return report


@contextlib.contextmanager
def _sigint_deferred():
    """Hold Ctrl-C while results are written (so files are never left half-done); yields a flag
    that is true when one arrived, for the caller to honour afterwards."""
    import signal
    import threading

    hit = [False]
    if threading.current_thread() is not threading.main_thread():
        yield hit
        return

    def remember(signum, frame):
        hit[0] = True

    previous = signal.signal(signal.SIGINT, remember)
    try:
        yield hit
    finally:
        signal.signal(signal.SIGINT, previous)


def _check_out_dir(out_dir: str) -> None:
    """Refuse an --out that is a file or lies under one, before any work is done."""
    from ._errors import ConfigError

    path = os.path.abspath(out_dir)
    while not os.path.exists(path):
        path = os.path.dirname(path)
    if not os.path.isdir(path):
        what = "is a file" if path == os.path.abspath(out_dir) else f"lies under the file {path!r}"
        raise ConfigError(f"--out {out_dir!r} {what}, not a directory; give a directory path for the results")
    if not os.access(path, os.W_OK | os.X_OK):
        raise ConfigError(f"cannot create the output directory {out_dir!r} in {path!r} (permission denied); "
                          "give a writable --out path")


def _make_out_dir(out_dir: str) -> None:
    from ._errors import ConfigError

    _check_out_dir(out_dir)
    try:
        os.makedirs(out_dir, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"cannot create the output directory {out_dir!r} ({exc.strerror}); "
                          "give a writable --out path") from None


def _cmd_simulate(a) -> int:
    from .data import corrupt
    from .systems import get_system

    system = get_system(a.system, a.variant)
    if a.system == "two-dof":  # a multi-DOF record: t,x1,x2,v1,a1,v2,a2,F1,F2
        return _simulate_multi(system, a)
    traj = system.simulate(t_end=a.t_end, n_points=a.n_points)
    clean = traj
    if a.snr is not None:
        traj = corrupt(traj, a.snr, on=a.noise_on, seed=a.seed, reference=a.noise_reference)
    if a.noise_on == "state" and a.snr is not None:
        # keep the contract's columns: v and a are the clean derivatives, for reference
        traj = traj.replace(v=clean.v, a=clean.a)
        print("note: x is noisy; v and a are the clean derivatives for reference. Fit with "
              "--derivatives savgol|spline|spectral to estimate them from x.", file=sys.stderr)
    traj.to_csv(a.out)
    _say(f"wrote {a.out}: {a.system} ({a.variant}), {traj.n_samples} samples"
         + (f", SNR {a.snr:g} dB on {a.noise_on}" if a.snr is not None else ", no noise"))
    return 0


def _simulate_multi(system, a) -> int:
    """``charcurves simulate two-dof``: the multi-DOF record with optional noise on the forcings."""
    from ._errors import ConfigError
    from .systems import corrupt_forces

    if a.snr is not None and a.noise_on != "force":
        raise ConfigError("multi-DOF records take noise on the forcings only; drop --noise-on state")
    traj = system.simulate(t_end=a.t_end, n_points=a.n_points)
    if a.snr is not None:
        traj = corrupt_forces(traj, a.snr, seed=a.seed, reference=a.noise_reference or "std")
    traj.to_csv(a.out)
    _say(f"wrote {a.out}: {system.name} ({a.variant}), {traj.n_samples} samples"
         + (f", SNR {a.snr:g} dB on each forcing" if a.snr is not None else ", no noise"))
    return 0


def _fit_and_write(traj, out_dir, *, method, family="separable", sym=None, free_gain=False, gauge=None,
                   gain_on="force",
                   preset="default", seed=0, derivatives="auto", jump="auto", basis=None, keep_sticking=False,
                   truth=None, threads=None, device="cpu", figure=True, quiet=False, source=None,
                   sr_options=None, refine="none", refine_options=None, bands=None, bands_kind="bootstrap",
                   bands_level=0.95, equation=None):
    from .fitting import CharacteristicCurves

    est = CharacteristicCurves(
        family=family, method=method, symmetry=sym, free_gain=free_gain, gauge=gauge, gain_on=gain_on, preset=preset,
        derivatives=derivatives, jump=jump if jump in ("auto", "none", "") else [j for j in jump.split(",") if j.strip()],
        basis=basis, sr_options=sr_options, exclude_sticking=not keep_sticking, random_state=seed,
        threads=1 if threads is None else threads, device=device,
        progress=_progress_printer(not quiet), refine=refine, refine_options=refine_options, equation=equation,
    )
    _check_out_dir(out_dir)  # before the fit: a bad --out must not cost a long run
    t0 = time.perf_counter()
    if bands is not None:
        from .fitting import check_band_options

        check_band_options(bands, bands_level)  # before the fit: a bad option must not cost a long run
    model = est.fit(traj).model_
    if bands is not None and not model.info.get("interrupted"):
        from .fitting import fit_ensembles, resolved_estimator
        from .selection import attach_bands, curve_bands

        _say(f"uncertainty bands: {bands} {bands_kind} refits ...", quiet)
        try:
            ens = fit_ensembles(resolved_estimator(est, model), [traj], bands, kind=bands_kind, points=[model])[0]
        except KeyboardInterrupt:  # the main fit is finished: write it, with the bands marked skipped
            model.info["interrupted"] = True
            model.info["bands"] = "skipped: interrupted"
        else:
            attach_bands(model, curve_bands(ens, level=bands_level))
    if "symmetry_auto" in model.info:
        auto = model.info["symmetry_auto"]
        _say(f"--sym auto: imposed {', '.join(f'{k}={v}' for k, v in auto['applied'].items())} "
             f"(method {auto['method']}; tests in result.json under 'symmetry')", quiet)
    elapsed = time.perf_counter() - t0
    with _sigint_deferred() as late_interrupt:
        _make_out_dir(out_dir)
        _write_results(model, out_dir, method=model.method, family=family, free_gain=free_gain, truth=truth,
                       figure=figure, quiet=quiet, source=source, elapsed=elapsed)
    model.info["interrupted_while_writing"] = late_interrupt[0]
    return model


def _write_results(model, out_dir, *, method, family, free_gain, truth, figure, quiet, source, elapsed):
    from .metrics import curve_errors

    # result.json holds only what the inputs and the seed determine (bit-identical on reruns);
    # wall-clock times go to timing.json and summary.txt
    result = model.result_dict()
    result["interrupted"] = bool(model.info.get("interrupted", False))
    if source:
        result["source"] = source
    errors = None
    if truth is not None:
        errors = curve_errors(model, truth)
        result["curve_rmse"] = errors
    from .io._csv import atomic_write_bytes

    model.save(os.path.join(out_dir, "model"))
    atomic_write_bytes(os.path.join(out_dir, "result.json"), json.dumps(result, indent=1).encode())
    timing = {"fit_seconds": elapsed, **model.timings()}
    atomic_write_bytes(os.path.join(out_dir, "timing.json"), json.dumps(timing, indent=1).encode())
    if figure:
        import matplotlib

        matplotlib.use("Agg")
        from .report import plot_curves

        fig = plot_curves(model, truth, title=f"{method}: {model.template.equation}")
        fig.savefig(os.path.join(out_dir, "curves.png"), dpi=120)
        import matplotlib.pyplot as plt

        plt.close(fig)
    lines = [f"charcurves {_version()} — {method} on the {family} family: {model.template.equation}",
             f"fit time {elapsed:.2f} s, data loss {model.loss:.4g}, gain {model.gain:.6g}"
             + ("" if not free_gain else " (learned)") + f", free constant {model.offset:.4g}"]
    for name, c in model.curves.items():
        expr = c.expression()
        comp = c.components()
        extra = ""
        if "jump_height" in comp:
            extra = f"; jump at 0: height {comp['jump_height']:.4g}, width {comp['jump_width']:.3g}"
        lines.append(f"  {name}({c.argument}) on [{c.domain[0]:.4g}, {c.domain[1]:.4g}]"
                     + (f" = {expr}" if expr is not None else f" ({c.kind} curve)") + extra
                     + (f"; RMSE vs truth {errors[name]:.3e}" if errors and name in errors else ""))
    for name, value in result.get("scalars", {}).items():  # unknown scalars of user-written templates
        lines.append(f"  {name} = {value:.6g}")
    if "output_error" in model.info:
        from .fitting import summary_lines

        lines += summary_lines(model)
    skipped = _skipped_by_interrupt(model)
    if skipped:
        lines.append(f"interrupted: the fit finished, but Ctrl-C skipped {' and '.join(skipped)}")
    elif result["interrupted"]:
        lines.append("interrupted: these are the best curves reached before Ctrl-C, not a finished fit")
    lines.append(f"wrote {os.path.join(out_dir, 'result.json')}" + (", curves.png" if figure else "")
                 + ", timing.json, model/")
    text = "\n".join(lines)
    atomic_write_bytes(os.path.join(out_dir, "summary.txt"), (text + "\n").encode())
    _say(text, quiet)


def _cmd_fit(a) -> int:
    from .templates import read_record

    if a.gauge is not None and a.family == "separable" and not a.equation and a.gauge not in ("f1", "f2"):
        raise _UsageError(f"argument --gauge: invalid choice: {a.gauge!r} (the separable family anchors 'f1' or "
                          "'f2'; other families name their own curves) (see 'charcurves fit --help')")

    traj = read_record(a.csv, family=a.family, equation=a.equation, time_col=a.time_col, x_col=a.x_col,
                       force_col=a.force_col, sample_rate=a.sample_rate, rows=a.rows)
    truth = None
    if a.truth:
        from .systems import get_system

        truth = get_system(a.truth, a.truth_variant).true_curves()
    sr_options = {k: v for k, v in (("engine", a.sr_engine), ("generations", a.sr_generations),
                                    ("populations", a.sr_populations), ("max_size", a.sr_max_size)) if v is not None}
    model = _fit_and_write(traj, a.out, method=a.method, family=a.family, sym=a.sym, free_gain=a.free_gain, sr_options=sr_options,
                   gauge=a.gauge, gain_on=a.noisy_side, preset=a.preset, seed=a.seed, derivatives=a.derivatives, jump=a.jump,
                   basis=a.basis, keep_sticking=a.keep_sticking, truth=truth, threads=a.threads,
                   device=a.device, figure=not a.no_figure, quiet=a.quiet, source=os.path.abspath(a.csv),
                   refine=a.refine, refine_options={k: v for k, v in (("hold", a.refine_hold),
                                                                      ("substeps", a.refine_substeps)) if v is not None},
                   bands=a.bands, bands_kind=a.bands_kind, bands_level=a.bands_level, equation=a.equation)
    return _interrupted_exit(model, a.out)


def _cmd_select(a) -> int:
    from .selection._cli import run_select

    return run_select(a, say=_say, check_out=_make_out_dir)


def _cmd_validate(a) -> int:
    from .simulate import validate_cli

    for line in validate_cli(a.model, a.csv, rows=a.rows, time_col=a.time_col, x_col=a.x_col, force_col=a.force_col,
                             sample_rate=a.sample_rate, hold=a.hold, substeps=a.substeps, out_dir=a.out):
        _say(line)
    return 0


def _skipped_by_interrupt(model) -> list[str]:
    """The steps after a finished fit that Ctrl-C skipped (post-SR, bands); [] when the training itself
    was interrupted (then the curves are the best reached, and that is what is reported)."""
    if not model.info.get("interrupted") or "interrupted" in str(model.info.get("stopped_by", "")):
        return []
    return [label for key, label in (("post_sr", "post-SR"), ("refine", "the output-error refinement"),
                                     ("bands", "the uncertainty bands"))
            if model.info.get(key) == "skipped: interrupted"]


def _interrupted_exit(model, out_dir: str) -> int:
    """0, or 130 with one line when Ctrl-C stopped the fit (the best model so far was written)."""
    if model.info.pop("interrupted_while_writing", False) and not model.info.get("interrupted"):
        print(f"charcurves: interrupted while writing; the finished fit was written completely to {out_dir}",
              file=sys.stderr, flush=True)
        return 130
    if not model.info.get("interrupted"):
        return 0
    skipped = _skipped_by_interrupt(model)
    if skipped:
        print(f"charcurves: interrupted; the fit had finished and was written to {out_dir}, without "
              f"{' and '.join(skipped)} (result.json marked interrupted); rerun to compute them",
              file=sys.stderr, flush=True)
        return 130
    print(f"charcurves: interrupted; kept the best model so far in {os.path.join(out_dir, 'model')} "
          "(result.json marked interrupted); rerun to finish the fit", file=sys.stderr, flush=True)
    return 130


def _cmd_demo(a) -> int:
    from .data import corrupt
    from .systems import get_system

    t0 = time.perf_counter()
    system = get_system("duffing")
    traj = corrupt(system.simulate(), 20.0, on="force", seed=a.seed)
    _make_out_dir(a.out)
    traj.to_csv(os.path.join(a.out, "duffing_20dB.csv"))
    _say(f"simulated the Duffing oscillator (paper parameters), 20 dB noise on the forcing -> "
         f"{os.path.join(a.out, 'duffing_20dB.csv')}")
    model = _fit_and_write(traj, a.out, method="nn-cc+sym", sym="f1=odd,f2=odd", seed=a.seed,
                           truth=system.true_curves(), threads=a.threads)
    _say(f"demo finished in {time.perf_counter() - t0:.1f} s")
    return _interrupted_exit(model, a.out)


def _cmd_benchmark(a) -> int:
    from .experiments._benchmark import BENCHMARK_SECTIONS, SYSTEMS, parse_name_list, parse_snr_list, run_benchmark
    from .fitting import METHODS

    systems = parse_name_list(a.systems, SYSTEMS, "systems")
    methods = parse_name_list(a.methods, tuple(METHODS), "methods") if a.methods is not None else None
    snr = parse_snr_list(a.snr) if a.snr is not None else None
    skip = parse_name_list(a.skip, BENCHMARK_SECTIONS, "skip") if a.skip.strip() else ()
    for name, value in (("--realizations", a.realizations), ("--workers", a.workers)):
        if value is not None and value < 1:
            raise _UsageError(f"{name} must be a positive integer, got {value}")
    if a.forward_cases is not None and a.forward_cases < 0:
        raise _UsageError(f"--forward-cases must be 0 or more, got {a.forward_cases}")
    res = run_benchmark(a.out, systems=systems, methods=methods, snr_db=snr, realizations=a.realizations,
                        full=a.full, preset=a.preset, executor=a.executor, workers=a.workers,
                        forward_cases=a.forward_cases, skip=skip, progress=not a.quiet,
                        retry_failed=a.retry_failed)
    _say(f"benchmark: {res}", a.quiet)
    return 0


def main(argv: list[str] | None = None) -> int:
    from ._errors import CharCurvesError

    # bit-identical results for the same inputs and seed: MKL's products may otherwise differ in
    # the last bit with the memory alignment of their operands (read when torch loads MKL)
    os.environ.setdefault("MKL_CBWR", "AUTO,STRICT")

    try:
        parser = _build_parser()
        args = parser.parse_args(argv)
        if args.command is None:
            parser.print_help()
            return 2
        handler = {"simulate": _cmd_simulate, "fit": _cmd_fit, "demo": _cmd_demo, "validate": _cmd_validate,
                   "benchmark": _cmd_benchmark, "select": _cmd_select}[args.command]
        return handler(args)
    except _UsageError as exc:
        print(f"charcurves: error: {exc}", file=sys.stderr)
        return 2
    except CharCurvesError as exc:
        print(f"charcurves: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        from .experiments._sweep import SweepInterrupted

        if isinstance(exc, SweepInterrupted):  # benchmark: finished rows are stored, a rerun resumes
            print(f"charcurves: {exc}", file=sys.stderr)
            return 130
        print("charcurves: interrupted before a model was trained; nothing was kept", file=sys.stderr)
        return 130
    except OSError as exc:  # writing outputs: a full disk, a read-only or vanished directory
        target = getattr(exc, "filename2", None) or exc.filename  # os.replace names the target second
        where = f" {target!r}" if target else ""
        print(f"charcurves: error: cannot write{where} ({exc.strerror or exc}); check the path, its permissions "
              "and the free disk space", file=sys.stderr)
        return 2
