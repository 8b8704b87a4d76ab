"""Writing outputs: one atomic writer for every file charcurves writes, the checks of a target, a folder lock."""

from __future__ import annotations

import contextlib
import errno
import os
import stat
import tempfile
from collections.abc import Iterator

from .._errors import ConfigError

__all__ = ["atomic_write_bytes", "current_umask", "make_temp_dir", "output_target", "check_output_file",
           "folder_lock", "FOLDER_LOCK_NAME", "special_file_kind"]

FOLDER_LOCK_NAME = ".charcurves.lock"
"""The lock file :func:`folder_lock` holds in an output folder while a command writes it (removed after)."""

_SPECIAL = ((stat.S_ISCHR, "character device"), (stat.S_ISBLK, "block device"), (stat.S_ISFIFO, "FIFO (named pipe)"),
            (stat.S_ISSOCK, "socket"))


def current_umask() -> int:
    """The process's umask (from /proc on Linux, else by setting and restoring it).

    Examples
    --------
    >>> import os
    >>> from charcurves.io import current_umask
    >>> mask = os.umask(0o027)
    >>> oct(current_umask())
    '0o27'
    >>> _ = os.umask(mask)
    """
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)  # no other way to read it; restored at once
    os.umask(mask)
    return mask


def make_temp_dir(parent: str | os.PathLike, prefix: str = ".tmp-") -> str:
    """``tempfile.mkdtemp`` in ``parent``, but with the permissions a plain ``mkdir`` gets
    (0777 & ~umask) instead of 0700, for a folder that is renamed into place.

    Examples
    --------
    >>> import os, stat, tempfile
    >>> from charcurves.io import current_umask, make_temp_dir
    >>> path = make_temp_dir(tempfile.mkdtemp(), prefix=".tmp-model-")
    >>> os.path.basename(path).startswith(".tmp-model-")
    True
    >>> stat.S_IMODE(os.stat(path).st_mode) == 0o777 & ~current_umask()
    True
    """
    path = tempfile.mkdtemp(dir=os.fspath(parent), prefix=prefix)
    os.chmod(path, 0o777 & ~current_umask())
    return path


def special_file_kind(mode: int) -> str | None:
    """"character device", "block device", "FIFO (named pipe)" or "socket" for such an ``st_mode``, else None."""
    return next((name for test, name in _SPECIAL if test(mode)), None)


def output_target(path: str | os.PathLike, label: str = "the output") -> str:
    """The regular file that writing ``path`` replaces: ``path`` itself, or, for a symbolic link,
    the file it points to (a link is written through and stays a link). A device, FIFO or socket is
    refused with one line (:class:`~charcurves.ConfigError`; a directory with ``IsADirectoryError``):
    charcurves only replaces regular files. ``label`` names the path in that line (``"--out"``).

    Examples
    --------
    >>> import os, tempfile
    >>> from charcurves import ConfigError
    >>> from charcurves.io import output_target
    >>> folder = os.path.realpath(tempfile.mkdtemp())
    >>> os.symlink("data.csv", os.path.join(folder, "link.csv"))
    >>> output_target(os.path.join(folder, "link.csv")) == os.path.join(folder, "data.csv")
    True
    >>> os.mkfifo(os.path.join(folder, "pipe"))
    >>> try:
    ...     output_target(os.path.join(folder, "pipe"), "--out")
    ... except ConfigError as exc:
    ...     print(str(exc).split(" is ")[1])
    a FIFO (named pipe), not a regular file; give a file path
    """
    p = os.fspath(path)
    target = os.path.realpath(p) if os.path.islink(p) else p
    try:
        st = os.stat(target)
    except FileNotFoundError:
        return target
    except OSError as exc:  # a loop of links, a component that is not a folder: the caller's write names it
        raise OSError(exc.errno, exc.strerror, p) from None
    if stat.S_ISDIR(st.st_mode):  # as open() would say (the CLI: "cannot write X (is a directory, ...)")
        raise IsADirectoryError(errno.EISDIR, "is a directory, not a file", p)
    kind = special_file_kind(st.st_mode)
    if kind is not None:
        where = "" if target == p else f" (the link points to {target!r})"
        raise ConfigError(f"{label} {p!r} is a {kind}{where}, not a regular file; give a file path")
    return target


def check_output_file(path: str | os.PathLike, option: str = "--out") -> None:
    """Refuse, before any work, an output file path that :func:`atomic_write_bytes` would refuse, or
    whose folder is missing or not writable; one line naming ``option``.

    Examples
    --------
    >>> from charcurves import ConfigError
    >>> from charcurves.io import check_output_file
    >>> try:
    ...     check_output_file("/dev/null")
    ... except ConfigError as exc:
    ...     print(exc)
    --out '/dev/null' is a character device, not a regular file; give a file path
    """
    target = output_target(path, option)
    folder = os.path.dirname(os.path.abspath(target))
    if os.path.isdir(folder) and not os.access(folder, os.W_OK | os.X_OK):
        raise ConfigError(f"{option} {os.fspath(path)!r}: the folder {folder!r} is not writable (permission denied); "
                          "give a writable path")


def _fsync_folder(folder: str) -> None:
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return  # a folder that cannot be opened for reading (Windows): the rename is all there is
    try:
        os.fsync(fd)
    except OSError as exc:
        if exc.errno not in (errno.EINVAL, errno.ENOTSUP, errno.EBADF):  # not supported by the file system
            raise
    finally:
        os.close(fd)


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file and ``os.replace``; the file gets the
    permissions a plain ``open`` would give (0666 & ~umask, or those of the file it replaces), not
    the temporary file's 0600.

    Only a regular file is ever replaced: a symbolic link is written through (the file it points to
    is replaced in its own folder; the link stays), a directory, device, FIFO or socket is refused
    (:func:`output_target`). Every step is checked up to the last close, the folder's included: a
    full disk or a failing ``fsync``/``close`` raises ``OSError`` naming ``path``, and the target is
    left as it was.

    Examples
    --------
    >>> import os, pathlib, stat, tempfile
    >>> from charcurves.io import atomic_write_bytes, current_umask
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "result.json"
    >>> atomic_write_bytes(path, b'{"ok": true}')
    >>> path.read_bytes(), stat.S_IMODE(path.stat().st_mode) == 0o666 & ~current_umask()
    (b'{"ok": true}', True)
    """
    p = os.fspath(path)
    if os.path.isdir(p):
        raise IsADirectoryError(errno.EISDIR, "is a directory, not a file", p)
    target = output_target(p)
    directory = os.path.dirname(os.path.abspath(target))
    os.makedirs(directory, exist_ok=True)
    try:
        mode = stat.S_IMODE(os.stat(target).st_mode)
    except FileNotFoundError:
        mode = 0o666 & ~current_umask()
    fd, tmp = tempfile.mkstemp(dir=directory, prefix=".tmp-", suffix=os.path.basename(target))
    try:
        try:
            with os.fdopen(fd, "wb") as fh:
                os.fchmod(fh.fileno(), mode)
                fh.write(data)
                fh.flush()
                os.fsync(fh.fileno())
            # the close above is checked too (an error there leaves the with block raising)
            os.replace(tmp, target)
            _fsync_folder(directory)
        except OSError as exc:
            if exc.filename is not None or exc.errno is None:
                raise
            raise OSError(exc.errno, exc.strerror, p) from None  # name the file the user asked for
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _holder_pid(path: str) -> str:
    try:
        with open(path, encoding="ascii", errors="replace") as fh:
            text = fh.read(32).strip()
    except OSError:
        return "unknown"
    return text if text.isdigit() else "unknown"


@contextlib.contextmanager
def folder_lock(folder: str | os.PathLike, option: str = "--out") -> Iterator[None]:
    """Hold the output ``folder`` for one writer: an exclusive ``flock`` on ``folder/.charcurves.lock``
    (which holds the writer's pid and is removed afterwards). A second writer does not wait: it is
    refused at once with one line naming the holder's pid (:class:`~charcurves.ConfigError`). The
    folder is created if needed. Where ``fcntl`` is missing (Windows) nothing is locked.

    Examples
    --------
    >>> import os, tempfile
    >>> from charcurves import ConfigError
    >>> from charcurves.io import folder_lock
    >>> out = os.path.join(tempfile.mkdtemp(), "out")
    >>> with folder_lock(out):
    ...     try:
    ...         with folder_lock(out):
    ...             pass
    ...     except ConfigError as exc:
    ...         print(str(exc).split(" (")[0])
    --out '...out' is being written by another charcurves process
    >>> os.listdir(out)
    []
    """
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows
        os.makedirs(folder, exist_ok=True)
        yield
        return
    d = os.fspath(folder)
    os.makedirs(d, exist_ok=True)
    path = os.path.join(d, FOLDER_LOCK_NAME)
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666 & ~current_umask())
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            os.close(fd)
            if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise
            raise ConfigError(f"{option} {d!r} is being written by another charcurves process (pid "
                              f"{_holder_pid(path)}, holding {FOLDER_LOCK_NAME}); wait for it to finish or give "
                              "another output folder") from None
        try:
            same = os.stat(path).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)  # the previous holder removed the file after we opened it: lock the new one
    try:
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        yield
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(path)  # while still holding the lock, so no one else can hold this file
        os.close(fd)
