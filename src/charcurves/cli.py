"""The ``charcurves`` command line: a thin layer over the public API.

Every user error ends with exit code 2 and one line on stderr naming the problem and the fix.
"""

from __future__ import annotations

import argparse
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
    from .fitting._estimator import METHODS

    p = _Parser(prog="charcurves", description="Equation discovery with characteristic curves.")
    p.add_argument("--version", action="version", version=f"charcurves {_version()}")
    sub = p.add_subparsers(dest="command", parser_class=_Parser)

    s = sub.add_parser("simulate", help="simulate a benchmark system to a CSV file (t,x,v,a,F)")
    s.add_argument("system", choices=["duffing", "stick-slip"])
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
    f.add_argument("--family", default="separable")
    f.add_argument("--method", default="nn-cc+sym", help=f"one of: {', '.join(METHODS)}")
    f.add_argument("--sym", default=None, help="parity priors, e.g. f1=odd,f2=odd")
    f.add_argument("--free-gain", action="store_true", help="learn the input gain g")
    f.add_argument("--gauge", choices=["f1", "f2"], default="f2", help="curve anchored at 0 (default f2)")
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
    f.add_argument("--truth", default=None, help="benchmark system (duffing, stick-slip) to compare the curves with")
    f.add_argument("--truth-variant", default="paper")
    f.add_argument("--threads", type=int, default=None, help="torch threads (default: 1 per process)")
    f.add_argument("--device", default="cpu")
    f.add_argument("--no-figure", action="store_true")
    f.add_argument("--quiet", action="store_true")

    d = sub.add_parser("demo", help="simulate Duffing at 20 dB, fit NN-CC+sym, write results")
    d.add_argument("--out", default="charcurves-demo")
    d.add_argument("--seed", type=int, default=0)
    d.add_argument("--threads", type=int, default=None)
    return p


def _version() -> str:
    from . import __version__

    return __version__


def _say(msg: str, quiet: bool = False) -> None:
    if not quiet:
        print(msg, flush=True)


def _progress_printer(enabled: bool):
    if not enabled:
        return None
    last = [0.0]

    def report(phase, step, total, loss):
        now = time.monotonic()
        if now - last[0] >= 2.0:
            last[0] = now
            print(f"  [{phase}] {step}/{total}  loss {loss:.4g}", file=sys.stderr, flush=True)

    return report


def _cmd_simulate(a) -> int:
    from .data import corrupt
    from .systems import get_system

    system = get_system(a.system, a.variant)
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


def _fit_and_write(traj, out_dir, *, method, family="separable", sym=None, free_gain=False, gauge="f2",
                   gain_on="force",
                   preset="default", seed=0, derivatives="auto", jump="auto", basis=None, keep_sticking=False,
                   truth=None, threads=None, device="cpu", figure=True, quiet=False, source=None,
                   sr_options=None):
    from .fitting import CharacteristicCurves
    from .metrics import curve_errors

    est = CharacteristicCurves(
        family=family, method=method, symmetry=sym, free_gain=free_gain, gauge=gauge, gain_on=gain_on, preset=preset,
        derivatives=derivatives, jump=jump if jump in ("auto", "none", "") else [j for j in jump.split(",") if j.strip()],
        basis=basis, sr_options=sr_options, exclude_sticking=not keep_sticking, random_state=seed,
        threads=1 if threads is None else threads, device=device,
        progress=_progress_printer(not quiet and preset == "paper"),
    )
    t0 = time.perf_counter()
    model = est.fit(traj).model_
    elapsed = time.perf_counter() - t0
    os.makedirs(out_dir, exist_ok=True)
    result = model.result_dict()
    result["fit_seconds"] = elapsed
    if source:
        result["source"] = source
    errors = None
    if truth is not None:
        errors = curve_errors(model, truth)
        result["curve_rmse"] = errors
    from .io._csv import atomic_write_bytes

    atomic_write_bytes(os.path.join(out_dir, "result.json"), json.dumps(result, indent=1).encode())
    model.save(os.path.join(out_dir, "model"))
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
    lines.append(f"wrote {os.path.join(out_dir, 'result.json')}" + (", curves.png" if figure else "") + ", model/")
    text = "\n".join(lines)
    from .io._csv import atomic_write_bytes as _w

    _w(os.path.join(out_dir, "summary.txt"), (text + "\n").encode())
    _say(text, quiet)
    return model


def _cmd_fit(a) -> int:
    from .data import Trajectory

    traj = Trajectory.from_csv(a.csv, time_col=a.time_col, x_col=a.x_col, force_col=a.force_col,
                               sample_rate=a.sample_rate, rows=a.rows)
    truth = None
    if a.truth:
        from .systems import get_system

        truth = get_system(a.truth, a.truth_variant).true_curves()
    sr_options = {k: v for k, v in (("engine", a.sr_engine), ("generations", a.sr_generations),
                                    ("populations", a.sr_populations), ("max_size", a.sr_max_size)) if v is not None}
    _fit_and_write(traj, a.out, method=a.method, family=a.family, sym=a.sym, free_gain=a.free_gain, sr_options=sr_options,
                   gauge=a.gauge, gain_on=a.noisy_side, preset=a.preset, seed=a.seed, derivatives=a.derivatives, jump=a.jump,
                   basis=a.basis, keep_sticking=a.keep_sticking, truth=truth, threads=a.threads,
                   device=a.device, figure=not a.no_figure, quiet=a.quiet, source=os.path.abspath(a.csv))
    return 0


def _cmd_demo(a) -> int:
    from .data import corrupt
    from .systems import get_system

    t0 = time.perf_counter()
    system = get_system("duffing")
    traj = corrupt(system.simulate(), 20.0, on="force", seed=a.seed)
    os.makedirs(a.out, exist_ok=True)
    traj.to_csv(os.path.join(a.out, "duffing_20dB.csv"))
    _say(f"simulated the Duffing oscillator (paper parameters), 20 dB noise on the forcing -> "
         f"{os.path.join(a.out, 'duffing_20dB.csv')}")
    _fit_and_write(traj, a.out, method="nn-cc+sym", sym="f1=odd,f2=odd", seed=a.seed,
                   truth=system.true_curves(), threads=a.threads)
    _say(f"demo finished in {time.perf_counter() - t0:.1f} s")
    return 0


def main(argv: list[str] | None = None) -> int:
    from ._errors import CharCurvesError

    try:
        parser = _build_parser()
        args = parser.parse_args(argv)
        if args.command is None:
            parser.print_help()
            return 2
        handler = {"simulate": _cmd_simulate, "fit": _cmd_fit, "demo": _cmd_demo}[args.command]
        return handler(args)
    except _UsageError as exc:
        print(f"charcurves: error: {exc}", file=sys.stderr)
        return 2
    except CharCurvesError as exc:
        print(f"charcurves: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("charcurves: interrupted", file=sys.stderr)
        return 130
