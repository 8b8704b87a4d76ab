"""A strict CSV reader for measured records: every defect is named with its row and the fix."""

from __future__ import annotations

import csv
import io
import json
import math
import os
import stat
from typing import Any

import numpy as np

from .._errors import DataError
from ._files import atomic_write_bytes, current_umask, make_temp_dir

#: columns a record's CSV may have: a record has a handful (t, x, v, a, F per degree of freedom);
#: a header wider than this is refused before its cells are read (issue 50: 200 000 columns hung)
MAX_COLUMNS = 1000

__all__ = ["MAX_COLUMNS", "read_csv_columns", "write_csv_columns", "json_bytes", "json_safe", "non_finite_paths",
           "atomic_write_bytes", "current_umask", "make_temp_dir"]  # the last three live in _files


def _read_text(path: str | os.PathLike) -> str:
    p = os.fspath(path)
    try:
        mode = os.stat(p).st_mode
    except OSError:
        mode = None  # open() below names the problem
    if mode is not None and not stat.S_ISREG(mode) and not stat.S_ISDIR(mode):
        kind = ("a named pipe (FIFO)" if stat.S_ISFIFO(mode) else "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode)
                else "a socket" if stat.S_ISSOCK(mode) else "not a regular file")
        raise DataError(f"{p!r} is {kind}, not a regular file (reading it could block or never end); "
                        "save the data to a CSV file first and give that file")
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
    if raw[:2] in (b"\xff\xfe", b"\xfe\xff") or raw[:4] in (b"\x00\x00\xfe\xff", b"\xff\xfe\x00\x00"):
        raise DataError(f"file {p!r} is UTF-16 or UTF-32 text (a byte-order mark); save it as UTF-8 CSV")
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

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from charcurves.io import read_csv_columns
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "record.csv"
    >>> _ = path.write_text("t,x,F\\n0.0,1.0,0.5\\n0.1,0.9,0.4\\n")
    >>> read_csv_columns(path)["x"].tolist()
    [1.0, 0.9]
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
    if width > MAX_COLUMNS:
        raise DataError(f"file {p!r} has {width} columns, more than the {MAX_COLUMNS} a record may have; keep the "
                        "columns of the record (t, x, F, ...) and drop the others")
    _refuse_lookalike_numbers(text, p, body, body_lines)
    for i, r in enumerate(body):
        if len(r) != width:
            raise DataError(
                f"line {body_lines[i]} of {p!r} has {len(r)} fields but the header has {width}; "
                "fix the ragged row (every row needs one value per column)"
            )
    names: list[str] = []
    seen: set[str] = set()  # linear in the width (a list made 200 000 columns quadratic)
    for j, h in enumerate(header):
        name = h if h else f"column{j + 1}"
        if name in seen:
            raise DataError(f"column name {name!r} appears twice in {p!r}; give unique column names")
        seen.add(name)
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


def _refuse_lookalike_numbers(text: str, p: str, body: list[list[str]], body_lines: list[int]) -> None:
    """Refuse cells that Python's and numpy's float() read as numbers but a CSV of measurements
    never means as one: digit groups with underscores (``1_5`` reads as 15) and non-ASCII digits
    (Arabic-Indic ``١٢`` reads as 12). One scan of the text in C; the row is found only on a hit."""
    start = text.find("\n") + 1  # the header may hold any name
    rest = text[start:]
    if rest.isascii() and "_" not in rest:
        return
    for r, line in zip(body, body_lines):
        for c in r:
            if "_" in c or not c.isascii():
                cell = c.strip()
                if (cell.isascii() and "_" not in cell) or not _is_number(cell):
                    continue  # plain, or not a number to float() either: the usual "is not a number" below
                shown = cell if len(cell) <= 20 else cell[:17] + "..."
                why = ("an underscore between digits" if cell.isascii() else "characters other than ASCII digits")
                raise DataError(f"line {line} of {p!r}: {shown!r} is not a plain decimal number ({why}); write "
                                "numbers with the digits 0-9, '.' and an optional exponent, e.g. 15 or 1.5e3")


def _is_number(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def json_safe(obj: Any) -> Any:
    """``obj`` with plain JSON types only: numpy scalars and arrays as numbers and lists, tuples as
    lists, and every non-finite float (NaN, ±Infinity, which standard JSON lacks) as None.

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.io import json_safe
    >>> json_safe({"rmse": np.float64(0.5), "x": np.array([1.0, np.nan]), "range": (0, np.inf)})
    {'rmse': 0.5, 'x': [1.0, None], 'range': [0, None]}
    """
    if isinstance(obj, dict):
        return {str(k): json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    if hasattr(obj, "tolist") and not isinstance(obj, (str, bytes)):  # numpy arrays and scalars
        return json_safe(obj.tolist())
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    return obj


def non_finite_paths(obj: Any, path: str = "") -> list[str]:
    """Dotted paths of the non-finite numbers in ``obj`` (what :func:`json_bytes` writes as null),
    e.g. ``["rmse", "segments[1].rmse"]``; for a status field beside them.

    Examples
    --------
    >>> from charcurves.io import non_finite_paths
    >>> non_finite_paths({"rmse": float("nan"), "segments": [{"rmse": 0.1}, {"rmse": float("inf")}]})
    ['rmse', 'segments[1].rmse']
    """
    if isinstance(obj, dict):
        return [p for k, v in obj.items() for p in non_finite_paths(v, f"{path}.{k}" if path else str(k))]
    if isinstance(obj, (list, tuple)):
        return [p for i, v in enumerate(obj) for p in non_finite_paths(v, f"{path}[{i}]")]
    if hasattr(obj, "tolist") and not isinstance(obj, (str, bytes)):
        return non_finite_paths(obj.tolist(), path)
    if isinstance(obj, float) and not math.isfinite(obj):
        return [path]
    return []


def json_bytes(obj: Any, indent: int | None = 1) -> bytes:
    """Standard JSON (RFC 8259) as UTF-8 bytes: non-finite numbers become ``null`` (never the bare
    ``NaN``/``Infinity`` that ``json.dumps`` writes by default); name them beside it with
    :func:`non_finite_paths` or a status field.

    Examples
    --------
    >>> from charcurves.io import json_bytes
    >>> json_bytes({"loss": 0.25, "rmse": float("nan")}, indent=None)
    b'{"loss": 0.25, "rmse": null}'
    """
    return json.dumps(json_safe(obj), indent=indent, allow_nan=False).encode("utf-8")


def write_csv_columns(path: str | os.PathLike, columns: dict[str, np.ndarray]) -> None:
    """Write equal-length columns with a header, full float precision, atomically.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> import numpy as np
    >>> from charcurves.io import write_csv_columns
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "record.csv"
    >>> write_csv_columns(path, {"t": np.array([0.0, 0.1]), "x": np.array([1.0, 1 / 3])})
    >>> print(path.read_text())
    t,x
    0,1
    0.10000000000000001,0.33333333333333331
    """
    names = list(columns)
    data = np.column_stack([np.asarray(columns[k], dtype=float) for k in names])
    buf = io.StringIO()
    buf.write(",".join(names) + "\n")
    np.savetxt(buf, data, delimiter=",", fmt="%.17g")
    atomic_write_bytes(path, buf.getvalue().encode())
