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
    from .._errors import CharCurvesError

    # bit-identical results for the same inputs and seed: MKL's products may otherwise differ in
    # the last bit with the memory alignment of their operands (read when torch loads MKL)
    os.environ.setdefault("MKL_CBWR", "AUTO,STRICT")

    try:
        with sigterm_as_interrupt():
            return _run(argv)
    except (UsageError, CharCurvesError) as exc:
        print(f"charcurves: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        from ..experiments import SweepInterrupted

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


def _run(argv) -> int:
    from ._commands import cmd_benchmark, cmd_report, cmd_select, cmd_simulate, cmd_validate
    from ._fit import cmd_demo, cmd_fit
    from ._parser import build_parser

    parser = build_parser(_version())
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 2
    check_seed(getattr(args, "seed", None))
    handler = {"simulate": cmd_simulate, "fit": cmd_fit, "demo": cmd_demo, "validate": cmd_validate,
               "benchmark": cmd_benchmark, "select": cmd_select, "report": cmd_report}[args.command]
    return handler(args)
