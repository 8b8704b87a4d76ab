"""The ``charcurves`` command line: a thin layer over the public API.

Every user error ends with exit code 2 and one line on stderr naming the problem and the fix.
Ctrl-C and SIGTERM stop a command the same way: a fit writes the best model so far (exit 130),
a sweep keeps every finished row (exit 130, a rerun resumes).
"""

from __future__ import annotations

import os
import sys

from ._common import UsageError, check_seed, sigterm_as_interrupt

__all__ = ["main"]


def _version() -> str:
    from .. import __version__

    return __version__


def main(argv: list[str] | None = None) -> int:
    import signal

    saved = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        code = _main(argv)
    finally:
        if argv is not None:  # called in a process that goes on: its handlers as they were
            for sig, handler in saved.items():
                if handler is not None:
                    signal.signal(sig, handler)
    if argv is None:  # the outputs are written: a signal while the interpreter shuts down ends it at once
        _quit_on_signal(code)
    if argv is None and "charcurves.symbolic" in sys.modules:
        from ..symbolic import searches_running

        if searches_running():  # a search Ctrl-C abandoned still runs in C++: end the program now, quietly
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(code)
    return code


def _quit_on_signal(code: int) -> None:
    """From here on, Ctrl-C or SIGTERM (a second signal close behind the first, say) exits at once with
    the command's code instead of a KeyboardInterrupt traceback from an exit handler, or exit 143."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return

    def quit_now(signum, frame):
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):
                pass
        os._exit(code)

    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, quit_now)


def _main(argv: list[str] | None) -> int:
    from .._errors import CharCurvesError

    # bit-identical results for the same inputs and seed: MKL's products may otherwise differ in
    # the last bit with the memory alignment of their operands (read when torch loads MKL)
    os.environ.setdefault("MKL_CBWR", "AUTO,STRICT")

    state: dict = {}
    try:
        with sigterm_as_interrupt():
            return _run(argv, state)
    except (UsageError, CharCurvesError) as exc:
        print(f"charcurves: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        if argv is None:  # the program ends now: a second signal must not kill it (exit 143) before it says why
            import signal

            for sig in (signal.SIGINT, signal.SIGTERM):
                signal.signal(sig, signal.SIG_IGN)
        from ..experiments import SweepInterrupted

        if isinstance(exc, SweepInterrupted):  # benchmark: finished rows are stored, a rerun resumes
            print(f"charcurves: {exc}", file=sys.stderr)
            return 130
        print(f"charcurves: {_interrupted_message(state.get('args'))}", file=sys.stderr)
        return 130
    except OSError as exc:  # writing outputs: a full disk, a read-only or vanished directory
        target = getattr(exc, "filename2", None) or exc.filename  # os.replace names the target second
        where = f" {target!r}" if target else ""
        print(f"charcurves: error: cannot write{where} ({exc.strerror or exc}); check the path, its permissions "
              "and the free disk space", file=sys.stderr)
        return 2


def _interrupted_message(args) -> str:
    """What an interrupt that ended a command outside its own handling kept."""
    command = getattr(args, "command", None)
    if command is None:
        return "interrupted before the command started; nothing was written"
    if command in ("fit", "demo"):
        return "interrupted before a model was trained; nothing was kept"
    if command == "benchmark":
        store = os.path.join(args.out, "results.sqlite")
        if os.path.isfile(store):
            return (f"interrupted; the rows finished so far are stored in {store}; rerun the same command to resume "
                    f"(or add --report-only to build the report from them)")
        return "interrupted before any job finished; nothing was kept"
    return f"interrupted; {command} did not finish and wrote nothing more"


def _run(argv, state: dict) -> int:
    from ._commands import cmd_benchmark, cmd_report, cmd_select, cmd_simulate, cmd_validate
    from ._fit import cmd_demo, cmd_fit
    from ._parser import build_parser

    parser = build_parser(_version())
    args = parser.parse_args(argv)
    state["args"] = args
    if args.command is None:
        parser.print_help()
        return 2
    check_seed(getattr(args, "seed", None))
    from ._applies import check_options_apply

    check_options_apply(args)  # an option that does not apply is an error, not ignored (issue 50)
    handler = {"simulate": cmd_simulate, "fit": cmd_fit, "demo": cmd_demo, "validate": cmd_validate,
               "benchmark": cmd_benchmark, "select": cmd_select, "report": cmd_report}[args.command]
    return handler(args)
