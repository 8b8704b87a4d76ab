"""``charcurves select``: read the records, run :func:`select_family`, print and write the verdicts."""

from __future__ import annotations

import csv
import io
import json
import os

from .._errors import ConfigError

__all__ = ["run_select"]


def run_select(a, *, say, check_out, fit=None) -> int:
    """Run the family search for the parsed command line ``a``; 0 whether or not a family is accepted."""
    from ..data import Trajectory
    from ..templates import get_template, read_record
    from ..io import atomic_write_bytes
    from ..fitting import MIN_MEMBERS
    from ..selection import select_family

    families = [f.strip() for f in a.families.split(",") if f.strip()]
    if not families:
        raise ConfigError("--families is empty; give e.g. --families separable,position-damping")
    twice = sorted({f for f in families if families.count(f) > 1})
    if twice:  # the last one won silently before (issue 50 class: names given twice)
        raise ConfigError(f"--families names {twice[0]!r} twice; give each family once, e.g. "
                          "--families separable,position-damping")
    real = [os.path.realpath(p) for p in a.csv]
    same = sorted({p for p, r in zip(a.csv, real) if real.count(r) > 1})
    if same:  # the other-record loop would validate a record on itself
        raise ConfigError(f"the record {same[0]!r} is given twice; give each record once (other initial conditions "
                          "or forcings of the same system)")
    if a.members < MIN_MEMBERS:
        raise ConfigError(f"--members must be at least {MIN_MEMBERS} to measure the curves' spread, got {a.members}")
    if a.out is not None:
        check_out(a.out)
    multi = [getattr(get_template(f), "multi_dof", False) for f in families]
    if any(multi) and not all(multi):
        raise ConfigError(f"--families mixes multi-DOF and one-DOF families ({', '.join(families)}); a selection "
                          "compares families on the same records: give only one-DOF families for t,x,F records, "
                          "or only two-dof for t,x1,x2,F1,F2 records")
    if any(multi):
        records = [read_record(path, family=families[0], time_col=a.time_col) for path in a.csv]
    else:
        records = [Trajectory.from_csv(path, time_col=a.time_col, x_col=a.x_col, force_col=a.force_col)
                   for path in a.csv]
    report = select_family(records, families, method=a.method, n_members=a.members, snr_db=a.snr,
                           all_families=a.all, all_loops=a.all, random_state=a.seed,
                           threads=1 if a.threads is None else a.threads, differentiator=a.derivatives,
                           progress=None if a.quiet else (lambda text: say(f"  {text}")), fit=fit)
    say(report.table())
    if a.out is not None:
        doc = report.to_dict()
        doc["records"] = [os.path.abspath(p) for p in a.csv]
        atomic_write_bytes(os.path.join(a.out, "selection.json"), json.dumps(doc, indent=1).encode())
        rows = report.csv_rows()
        buf = io.StringIO()
        writer = csv.DictWriter(buf, fieldnames=list(rows[0]), lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
        atomic_write_bytes(os.path.join(a.out, "selection.csv"), buf.getvalue().encode())
        say(f"wrote {os.path.join(a.out, 'selection.json')}, selection.csv")
    return 0
