"""What every subcommand shares: the usage error, printing, the output folder, held signals, bounds."""

from __future__ import annotations

import contextlib
import os
import sys

#: Seeds are bounded to what every random generator charcurves seeds accepts: numpy's legacy
#: ``RandomState`` and several SR engines take 32-bit seeds, and the neural trainer derives
#: ``seed * 7919 + start`` for ``torch.Generator.manual_seed`` (64-bit), which stays in range.
MAX_SEED = 2**32 - 1


class UsageError(Exception):
    """A command-line mistake: exit code 2 with one line."""


def say(msg: str, quiet: bool = False) -> None:
    if not quiet:
        print(msg, flush=True)


def warn(msg: str) -> None:
    print(f"charcurves: warning: {msg}", file=sys.stderr, flush=True)


def check_seed(value, option: str = "--seed") -> None:
    """Refuse a seed outside 0 ... 2**32 - 1 (before any work is done)."""
    if value is None:
        return
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= MAX_SEED:
        raise UsageError(f"{option} must be a non-negative integer of at most 32 bits (0 ... {MAX_SEED}, the range "
                         f"every random generator charcurves seeds accepts), got {value}; e.g. {option} 0")


def check_out_dir(out_dir: str) -> None:
    """Refuse an --out that is a file or lies under one, before any work is done."""
    from .._errors import ConfigError

    path = os.path.abspath(out_dir)
    while not os.path.exists(path):
        path = os.path.dirname(path)
    if not os.path.isdir(path):
        what = "is a file" if path == os.path.abspath(out_dir) else f"lies under the file {path!r}"
        raise ConfigError(f"--out {out_dir!r} {what}, not a directory; give a directory path for the results")
    if not os.access(path, os.W_OK | os.X_OK):
        raise ConfigError(f"cannot create the output directory {out_dir!r} in {path!r} (permission denied); "
                          "give a writable --out path")


def make_out_dir(out_dir: str) -> None:
    from .._errors import ConfigError

    check_out_dir(out_dir)
    try:
        os.makedirs(out_dir, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"cannot create the output directory {out_dir!r} ({exc.strerror}); "
                          "give a writable --out path") from None


def _raise_interrupt(signum, frame):
    raise KeyboardInterrupt


@contextlib.contextmanager
def sigterm_as_interrupt():
    """SIGTERM (what schedulers and ``timeout`` send) stops the command like Ctrl-C: the fit keeps
    the best model so far and writes it, sweeps keep their finished rows. Main thread only."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


@contextlib.contextmanager
def first_interrupt_only():
    """While a fit runs: the first Ctrl-C or SIGTERM raises KeyboardInterrupt (training stops and
    keeps its best weights, later stages are skipped), a second one is held (one line says so) so
    that it cannot lose the model the first one kept while that model is finished and written; a
    third quits at once (exit 130) without writing it. Main thread only."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    count = [0]

    def handler(signum, frame):
        count[0] += 1
        if count[0] == 1:
            raise KeyboardInterrupt
        if count[0] == 2:
            print("charcurves: interrupted again; still keeping the best model so far (a third interrupt quits at "
                  "once, without writing it)", file=sys.stderr, flush=True)
            return
        print("charcurves: interrupted a third time; quit without writing the model", file=sys.stderr, flush=True)
        os._exit(130)

    previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, old in previous.items():  # after an interrupt, what is left is to say what was kept:
            signal.signal(sig, signal.SIG_IGN if count[0] else old)  # later signals wait (main() ends them)


@contextlib.contextmanager
def signals_deferred():
    """Hold Ctrl-C and SIGTERM while results are written (so files are never left half-done); yields
    a flag that is true when one arrived, for the caller to honour afterwards."""
    import signal
    import threading

    hit = [False]
    if threading.current_thread() is not threading.main_thread():
        yield hit
        return

    def remember(signum, frame):
        hit[0] = True

    previous = {sig: signal.signal(sig, remember) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield hit
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


#: What ``fit`` (and ``demo``) write in ``--out``: files, and the model folder with everything under it.
FIT_OUTPUTS = ("result.json", "timing.json", "summary.txt", "curves.png", "report.html", "model")


def _same_path(a: str, b: str) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return os.path.realpath(a) == os.path.realpath(b)


def refuse_inputs_among_outputs(inputs: dict[str, str], outputs: list[str], option: str = "--out") -> None:
    """Refuse, before any work, an input file (``{what: path}``) that is one of the ``outputs`` (or lies
    inside an output folder such as model/): the run would overwrite what it reads. One line."""
    from .._errors import ConfigError

    for what, path in inputs.items():
        if path is None or not os.path.exists(path):
            continue
        real = os.path.realpath(path)
        for out in outputs:
            inside = os.path.isdir(out) and real.startswith(os.path.realpath(out) + os.sep)
            if inside or _same_path(path, out):
                raise ConfigError(f"the {what} {path!r} is the output {out!r} of this command, which would overwrite it; "
                                  f"move the {what} out of the way or give another {option}")


_HELD: set[str] = set()  # the output folders this process holds (a nested holder of the same folder passes)


@contextlib.contextmanager
def held_out_dir(out_dir: str):
    """Create ``--out`` and hold it for this process for the whole run (a lock file in it, see
    :func:`charcurves.io.folder_lock`): a second ``fit`` writing the same folder at the same time is
    refused at once with one line naming this one's pid. A folder this call created is removed again
    when the run ends with an error before writing anything into it."""
    from ..io import folder_lock

    key = os.path.realpath(out_dir)
    if key in _HELD:
        yield
        return
    existed = os.path.isdir(out_dir)
    make_out_dir(out_dir)
    _HELD.add(key)
    try:
        with folder_lock(out_dir):
            yield
    except BaseException:
        if not existed:
            with contextlib.suppress(OSError):
                os.rmdir(out_dir)  # only when empty
        raise
    finally:
        _HELD.discard(key)
