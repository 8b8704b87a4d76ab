"""``charcurves fit --equation "..." --measured x2=x``: a state-space template with hidden states."""

from __future__ import annotations

import os

__all__ = ["cmd_fit_hidden"]


def cmd_fit_hidden(a) -> int:
    """Fit a state-space template whose unmeasured states are hidden (output error from seeded
    starts); writes result.json (the curves on a grid, the gauges, which start ran) and summary.txt."""
    import numpy as np

    from ..data import MultiTrajectory, Trajectory
    from ..fitting import fit_state_space
    from ..io import atomic_write_bytes, json_bytes
    from ..templates import StateSpace, parse_measured
    from ._common import UsageError, make_out_dir, say, warn

    if not a.equation:
        raise UsageError("--measured needs --equation with the state equations, e.g. --equation \"x1' = g*F - f1(x1); "
                         "x2' = f1(x1) - f2(x2)\" --measured x2=x (see 'charcurves fit --help')")
    measured = parse_measured(a.measured)
    template = StateSpace(a.equation, measured=measured, free_gain=bool(a.free_gain))
    structure = template.structure()
    columns = sorted(set(measured.values()))
    record: Trajectory | MultiTrajectory
    if columns == ["x"] and list(structure.forces) == ["F"]:
        record = Trajectory.from_csv(a.csv, time_col=a.time_col or "t", x_col="x", force_col="F", rows=a.rows)
    else:
        record = MultiTrajectory.from_csv(a.csv, states=columns, forces=structure.forces, time_col=a.time_col or "t",
                                          rows=a.rows)
    model = fit_state_space(template, record, start=a.start, seed=int(a.seed or 0))
    result = model.summary()
    result["curves_on_grid"] = {}
    for name, curve in model.curves.items():
        lo, hi = curve.domain
        z = np.linspace(float(lo), float(hi), 101)
        result["curves_on_grid"][name] = {"z": z.tolist(), "f": np.asarray(curve(z), dtype=float).tolist()}
    result.pop("seconds", None)  # wall-clock time: timing.json (result.json is what the inputs determine)
    for stage in result.get("stages", []):
        stage.pop("seconds", None)
    make_out_dir(a.out)
    atomic_write_bytes(os.path.join(a.out, "result.json"), json_bytes(result))
    atomic_write_bytes(os.path.join(a.out, "timing.json"), json_bytes({"fit_seconds": model.info["seconds"]}))
    lines = [f"state-space fit, hidden {', '.join(model.info['hidden'])}: {template.written}",
             f"  start: {model.info['start']} ({model.info['n_starts']} seeded starts), gain {model.gain:.6g}",
             *[f"  gauge: {g}" for g in model.info["gauge_freedoms"]],
             *[f"  free-run RMSE of {s}: {v:.4g}" for s, v in model.info["free_run_rmse"].items()],
             f"wrote {os.path.join(a.out, 'result.json')}"]
    atomic_write_bytes(os.path.join(a.out, "summary.txt"), ("\n".join(lines) + "\n").encode())
    for line in model.info.get("warnings", []):
        warn(line)
    say("\n".join(lines), a.quiet)
    return 0
