"""``charcurves fit --equation "..." --measured x2=x``: a state-space template with hidden states;
``validate`` of the model it writes."""

from __future__ import annotations

import os
import sys

__all__ = ["cmd_fit_hidden", "validate_hidden", "is_hidden_model"]


def _read_record(csv, measured, forces, time_col, rows):
    from ..data import MultiTrajectory, Trajectory

    columns = sorted(set(measured.values()))
    if columns == ["x"] and list(forces) == ["F"]:
        return Trajectory.from_csv(csv, time_col=time_col or "t", x_col="x", force_col="F", rows=rows)
    return MultiTrajectory.from_csv(csv, states=columns, forces=forces, time_col=time_col or "t", rows=rows)


def cmd_fit_hidden(a):
    """Fit a state-space template whose unmeasured states are hidden (output error from seeded
    starts); writes result.json (the curves on a grid, the gauges, which start ran), summary.txt and
    the model files (model/, read by validate and report). Ctrl-C or SIGTERM keeps the best model
    so far (``info["interrupted"]``: the caller exits 130). Returns the model."""
    from ..fitting import fit_state_space
    from ..templates import StateSpace, parse_measured
    from ._common import UsageError, check_out_dir, first_interrupt_only, held_out_dir, say, signals_deferred

    if not a.equation:
        raise UsageError("--measured needs --equation with the state equations, e.g. --equation \"x1' = g*F - f1(x1); "
                         "x2' = f1(x1) - f2(x2)\" --measured x2=x (see 'charcurves fit --help')")
    measured = parse_measured(a.measured)
    template = StateSpace(a.equation, measured=measured, free_gain=bool(a.free_gain))
    structure = template.structure()
    if getattr(a, "method", None) == "nn-cc":  # a network per curve (statespace._neural)
        from ..curves import Neural

        template = StateSpace(a.equation, measured=measured, free_gain=bool(a.free_gain),
                              **{name: Neural() for name in structure.curve_names})
    sr_options = {k: v for k, v in (("engine", a.sr_engine), ("generations", a.sr_generations),
                                    ("populations", a.sr_populations), ("max_size", a.sr_max_size),
                                    ("operators", a.sr_operators)) if v is not None}
    record = _read_record(a.csv, measured, structure.forces, a.time_col, a.rows)
    check_out_dir(a.out)  # before the fit: a bad --out must not cost a long run

    def progress(line: str) -> None:
        if not a.quiet:
            print(f"  [{line}]  (Ctrl-C stops and keeps the best model so far)", file=sys.stderr, flush=True)

    with held_out_dir(a.out), first_interrupt_only():
        model = fit_state_space(template, record, start=a.start, seed=int(a.seed or 0), progress=progress,
                                post_sr=bool(getattr(a, "post_sr", False)), sr_options=sr_options or None)
        with signals_deferred() as late_interrupt:
            lines = _write(model, template, a.out)
    say("\n".join(lines), a.quiet)
    model.info["interrupted_while_writing"] = late_interrupt[0]
    return model


def _write(model, template, out) -> list[str]:
    import numpy as np

    from ..io import atomic_write_bytes, json_bytes
    from ._common import make_out_dir, warn

    result = model.summary()
    result["curves_on_grid"] = {}
    for name, curve in model.curves.items():
        lo, hi = curve.domain
        z = np.linspace(float(lo), float(hi), 101)
        result["curves_on_grid"][name] = {"z": z.tolist(), "f": np.asarray(curve(z), dtype=float).tolist()}
    result.pop("seconds", None)  # wall-clock time: timing.json (result.json is what the inputs determine)
    result.pop("cpu_seconds", None)
    for stage in result.get("stages", []):
        stage.pop("seconds", None)
    make_out_dir(out)
    model.save(os.path.join(out, "model"))
    atomic_write_bytes(os.path.join(out, "result.json"), json_bytes(result))
    atomic_write_bytes(os.path.join(out, "timing.json"), json_bytes({"fit_seconds": model.info["seconds"],
                                                                     "fit_cpu_seconds": model.info["cpu_seconds"]}))
    scalars = model.info.get("scalars") or {}
    lines = [f"state-space fit, hidden {', '.join(model.info['hidden'])}: {template.written}",
             f"  start: {model.info['start']} ({model.info['n_starts']} seeded starts), gain {model.gain:.6g}",
             *[f"  scalar {k} = {v:.6g}" for k, v in scalars.items()],
             *[f"  gauge: {g}" for g in model.info["gauge_freedoms"]],
             *[f"  curve {n}: {k}" for n, k in (model.info.get("representations") or {}).items()],
             *_post_sr_lines(model.info.get("post_sr")),
             *[f"  free-run RMSE of {s}: {v:.4g}" for s, v in model.info["free_run_rmse"].items()],
             f"wrote {os.path.join(out, 'result.json')} and the model files in {os.path.join(out, 'model')}"]
    atomic_write_bytes(os.path.join(out, "summary.txt"), ("\n".join(lines) + "\n").encode())
    for line in model.info.get("warnings", []):
        warn(line)
    return lines


def _post_sr_lines(post) -> list[str]:
    """summary.txt's lines of a post-SR: each closed form after the refit and the data losses."""
    if not post:
        return []
    return [*[f"  post-SR {n} = {c['expression']}" if c["expression"] is not None else
              f"  post-SR {n}: {c['data_guard']}" for n, c in post["curves"].items()],
            f"  post-SR data loss: {post['loss_before']:.4g} learned, {post['loss_distilled']:.4g} distilled, "
            f"{post['loss_refit']:.4g} refitted"]


def is_hidden_model(path) -> bool:
    """Whether the model folder (or the fit folder holding model/) is a state-space model's."""
    import json

    folder = path if os.path.isfile(os.path.join(path, "model.json")) else os.path.join(path, "model")
    try:
        with open(os.path.join(folder, "model.json"), encoding="utf-8") as fh:
            doc = json.load(fh)
        return doc.get("template", {}).get("family") == "state-space"
    except (OSError, ValueError, AttributeError):
        return False  # the ordinary reader names the problem


def validate_hidden(a) -> int:
    """``validate`` of a state-space model: one free run of the record's input from the whole state
    (hidden states included) fitted to the record's first 128 samples, the RMSE of every sample per
    measured state; with ``--init-window N`` fitted to the first N, the RMSE counted after them."""
    from ..fitting import load_model
    from ..io import atomic_write_bytes, json_bytes
    from ._common import UsageError, say

    folder = a.model if os.path.isfile(os.path.join(a.model, "model.json")) else os.path.join(a.model, "model")
    model = load_model(folder)
    if a.rows and len(a.rows) > 1:
        raise UsageError("--rows once for a model with hidden states (its free run starts from the span's own first "
                         "samples); validate one span per call")
    given = [flag for flag, on in (("--x-col", a.x_col != "x"), ("--force-col", a.force_col != "F"),
                                   ("--sample-rate", a.sample_rate is not None), ("--hold", a.hold is not None),
                                   ("--substeps", a.substeps is not None)) if on]
    if given:
        raise UsageError(f"{given[0]} does not apply to a model with hidden states (its record's columns are the "
                         "measured map's, its input hold and RK4 steps the fit's); drop it")
    if a.time_col is None or str(a.time_col).strip().lower() == "none":
        raise UsageError("a model with hidden states needs the record's time column; give --time-col NAME")
    span = a.rows[0] if a.rows else None  # may start anywhere: the state is estimated from the span's first samples
    record = _read_record(a.csv, model.info["measured"], model.structure.forces, a.time_col, span)
    if len(record.t) < 16:
        raise UsageError(f"the span has {len(record.t)} rows; validate needs at least 16 (widen --rows)")
    start = getattr(a, "start", None)
    if start is not None and a.init_window is not None:
        raise UsageError("--start and --init-window both say where the free run starts; give one")
    if a.init_window is None:  # the state fitted to the first samples by default, every sample counted
        initial = model.start_values(record, start or "window")
        rmse, counted = model.free_run_rmse(record, initial=initial), [0, len(record.t)]
        how = model.start_description(start or "window", len(record.t))
    else:
        from ..fitting import window_free_run_error

        rmse, initial = window_free_run_error(model, record, a.init_window)
        counted = [int(a.init_window), len(record.t)]
        how = (f"initial state (hidden states included) fitted to the first {int(a.init_window)} samples, the RMSE "
               "counted after them")
    lines = [f"free run of {folder} (state-space, hidden {', '.join(model.info['hidden'])}; {how})",
             *[f"  {s}: RMSE {v:.5g}" for s, v in rmse.items()],
             "  estimated initial state: " + ", ".join(f"{k} = {v:.6g}" for k, v in initial.items())]
    failed = [s for s, v in rmse.items() if not v < float("inf")]
    if a.out is not None:
        os.makedirs(a.out, exist_ok=True)
        doc = {"model": folder, "csv": a.csv, "status": "failed" if failed else "ok",
               "rmse": {s: (v if v < float("inf") else None) for s, v in rmse.items()}}
        doc.update(init_window=None if a.init_window is None else int(a.init_window), rmse_rows=counted,
                   start=how, initial_state=initial)
        atomic_write_bytes(os.path.join(a.out, "validation.json"), json_bytes(doc))
        lines.append(f"wrote {os.path.join(a.out, 'validation.json')}")
    for line in lines:
        say(line)
    if failed:
        print(f"charcurves: validation failed: the free run of {', '.join(failed)} diverges; the model does not "
              "reproduce the record", file=sys.stderr, flush=True)
        return 1
    return 0
