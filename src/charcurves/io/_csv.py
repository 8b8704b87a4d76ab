"""A strict CSV reader for measured records: every defect is named with its row and the fix."""

from __future__ import annotations

import csv
import errno
import io
import os
import tempfile

import numpy as np

from .._errors import DataError

__all__ = ["read_csv_columns", "write_csv_columns", "atomic_write_bytes"]


def _read_text(path: str | os.PathLike) -> str:
    p = os.fspath(path)
    try:
        with open(p, "rb") as fh:
            raw = fh.read()
    except FileNotFoundError:
        raise DataError(f"file {p!r} does not exist; check the path") from None
    except IsADirectoryError:
        raise DataError(f"{p!r} is a directory, not a CSV file; give the file's path") from None
    except PermissionError:
        raise DataError(f"file {p!r} cannot be read (permission denied); fix its permissions") from None
    except OSError as exc:
        raise DataError(f"file {p!r} cannot be read ({exc.strerror}); check the path") from None
    if not raw.strip():
        raise DataError(f"file {p!r} is empty; give a CSV file with a header row and data rows")
    if b"\x00" in raw[:65536]:
        raise DataError(f"file {p!r} looks binary, not a CSV text file; export the data as CSV")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        try:
            return raw.decode("latin-1")
        except UnicodeDecodeError:  # pragma: no cover - latin-1 decodes any byte
            raise DataError(f"file {p!r} is not text; export the data as CSV") from None


def read_csv_columns(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Read a CSV file with one header row into ``{column name: float array}``.

    Columns with an empty name and no values (a trailing comma on every line) are dropped.
    Raises :class:`DataError` for empty, binary or unreadable files, ragged rows and
    non-numeric cells, naming the row (1-based line number in the file) and column.
    """
    p = os.fspath(path)
    text = _read_text(p)
    sample = text[:4096]
    try:
        dialect = csv.Sniffer().sniff(sample, delimiters=",;\t ")
        delimiter = dialect.delimiter
    except csv.Error:
        delimiter = ","
    reader = csv.reader(io.StringIO(text), delimiter=delimiter, skipinitialspace=True)
    try:
        rows, line_nos = [], []
        for r in reader:
            if r and any(c.strip() for c in r):
                rows.append(r)
                line_nos.append(reader.line_num)  # 1-based, counts skipped blank lines
    except csv.Error as exc:
        raise DataError(f"file {p!r} is not valid CSV ({exc}); export it again as CSV") from None
    if not rows:
        raise DataError(f"file {p!r} has no rows; give a CSV file with a header row and data rows")
    header = [h.strip() for h in rows[0]]
    body = rows[1:]
    body_lines = line_nos[1:]
    if not body:
        raise DataError(f"file {p!r} has a header but no data rows; give the measurements below it")
    if all(_is_number(h) for h in header if h):
        raise DataError(
            f"file {p!r} has no header row (its first line is numbers); add a header such as t,x,F"
        )
    width = len(header)
    for i, r in enumerate(body):
        if len(r) != width:
            raise DataError(
                f"line {body_lines[i]} of {p!r} has {len(r)} fields but the header has {width}; "
                "fix the ragged row (every row needs one value per column)"
            )
    names: list[str] = []
    for j, h in enumerate(header):
        name = h if h else f"column{j + 1}"
        if name in names:
            raise DataError(f"column name {name!r} appears twice in {p!r}; give unique column names")
        names.append(name)
    out: dict[str, np.ndarray] = {}
    for j, name in enumerate(names):
        cells = [r[j].strip() for r in body]
        if not header[j] and all(c == "" for c in cells):
            continue  # the trailing empty column of "a,b," files
        try:
            out[name] = np.array(cells, dtype=float)
        except ValueError:
            for i, c in enumerate(cells):
                if not _is_number(c):
                    shown = c if len(c) <= 20 else c[:17] + "..."
                    raise DataError(
                        f"line {body_lines[i]} of {p!r}, column {name!r}: {shown!r} is not a number; "
                        "fix or remove that row"
                    ) from None
            raise  # pragma: no cover
    if not out:
        raise DataError(f"file {p!r} has no data columns; give a CSV with columns such as t,x,F")
    return out


def _is_number(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file and ``os.replace``."""
    p = os.fspath(path)
    if os.path.isdir(p):
        raise IsADirectoryError(errno.EISDIR, "is a directory, not a file", p)
    directory = os.path.dirname(os.path.abspath(p))
    os.makedirs(directory, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=directory, prefix=".tmp-", suffix=os.path.basename(p))
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, p)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def write_csv_columns(path: str | os.PathLike, columns: dict[str, np.ndarray]) -> None:
    """Write equal-length columns with a header, full float precision, atomically."""
    names = list(columns)
    data = np.column_stack([np.asarray(columns[k], dtype=float) for k in names])
    buf = io.StringIO()
    buf.write(",".join(names) + "\n")
    np.savetxt(buf, data, delimiter=",", fmt="%.17g")
    atomic_write_bytes(path, buf.getvalue().encode())
