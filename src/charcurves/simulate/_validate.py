"""Free runs of a fitted model on a measured record: RMSE of x, the initial state, ``charcurves validate``."""

from __future__ import annotations

import numpy as np

from .._errors import ConfigError, DataError
from ..data import check_hold, stage_inputs
from ._sampled import model_acceleration, rk4_sampled, simulate_sampled

__all__ = ["free_run_error", "estimate_initial_state", "validate_cli"]


def free_run_error(model, traj, *, hold: str = "linear", substeps: int = 4, x0: float | None = None,
                   v0: float | None = None, time_budget: float = 120.0, init_window: int | None = None):
    """Free-run simulation of ``model`` driven by the record's input, and its RMSE against x.

    Parameters
    ----------
    model : FittedModel
    traj : Trajectory
        Uniformly sampled record (x and F).
    hold, substeps : see :func:`charcurves.simulate.simulate_sampled`.
    x0, v0 : float, optional
        Initial state; by default estimated from the first samples (:func:`estimate_initial_state`).
    init_window : int, optional
        The nonlinear benchmarks' convention: the initial state (velocity included) is fitted to the
        first ``init_window`` samples only and the RMSE is counted after them (the run starts at the
        first sample). None: the state is fitted to the first 128 samples, the RMSE over all.

    Returns
    -------
    rmse : float
        Root-mean-square of simulated minus measured x over all samples (inf when the run fails).
    result : SimulationResult

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.simulate import free_run_error
    >>> from charcurves.systems import get_system
    >>> system = get_system("duffing")
    >>> record = system.simulate().slice(slice(0, 250))  # 10 s
    >>> rmse, res = free_run_error(cc.fit(record, method="parametric", basis="f1=z; f2=z, z**3"), record, x0=system.x0, v0=system.v0)
    >>> res.status, rmse < 1e-3
    ('ok', True)
    """
    traj.require_uniform("a free-run simulation of a sampled record")
    skip = check_init_window(init_window, traj.n_samples)
    if x0 is None or v0 is None:
        n_fit = 128 if init_window is None else skip
        ex0, ev0 = estimate_initial_state(model, traj, hold=hold, substeps=substeps, n_fit=n_fit)
        x0 = ex0 if x0 is None else x0
        v0 = ev0 if v0 is None else v0
    res = simulate_sampled(model, traj, float(x0), float(v0), hold=hold, substeps=substeps, time_budget=time_budget)
    if not res.ok:
        return float("inf"), res
    return float(np.sqrt(np.mean((res.x[skip:] - np.asarray(traj.x)[skip:]) ** 2))), res


def check_init_window(init_window, n: int) -> int:
    """The samples an initialisation window takes (0 for None); ConfigError unless 2 <= N <= n - 16."""
    if init_window is None:
        return 0
    if isinstance(init_window, bool) or not isinstance(init_window, (int, np.integer)) or \
            not 2 <= int(init_window) <= n - 16:
        raise ConfigError(f"the initialisation window must be a whole number of samples from 2 to {n - 16} (the "
                          f"record has {n}; at least 16 are left to count the RMSE on), got {init_window!r}; give "
                          "e.g. --init-window 100")
    return int(init_window)


def estimate_initial_state(model, traj, *, hold: str = "linear", substeps: int = 4, n_fit: int = 128):
    """The initial state (x0, x0') that best explains the first ``n_fit`` samples by a free run.

    A record's first velocity is not measured, and a derivative estimate at the very edge of a
    record is poor (spectral methods assume periodic continuation); two parameters fitted by
    output error on a short span are robust and cost a few milliseconds.

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.simulate import estimate_initial_state
    >>> from charcurves.systems import get_system
    >>> system = get_system("duffing")
    >>> record = system.simulate()
    >>> x0, v0 = estimate_initial_state(cc.fit(record, method="parametric", basis="f1=z; f2=z, z**3"), record, substeps=1, n_fit=32)
    >>> (round(x0, 3), round(v0, 3)) == (round(system.x0, 3), round(system.v0, 3))
    True
    """
    from scipy.optimize import least_squares


    n = int(min(max(n_fit, 2), traj.n_samples))
    x = np.asarray(traj.x[:n], dtype=float)
    ua, um, ub = stage_inputs(np.asarray(traj.F[:n]), substeps, hold)
    # one trial run on Python floats (closed-form curves compiled with ``math``): a few hundred
    # trial runs cost well under a second, where 1-element numpy arrays took ~60 ms a run
    accel = model_acceleration(model)
    dt = float(traj.dt)
    v_guess = float(np.gradient(x[:5], dt)[0]) if n >= 5 else 0.0
    sx = max(float(np.std(x)), 1e-12)
    sv = max(float(np.std(np.gradient(x, dt))), 1e-12)

    def resid(q):
        xs, _, _ = rk4_sampled(accel, ua, um, ub, float(q[0] * sx), float(q[1] * sv), dt, substeps)
        with np.errstate(over="ignore", invalid="ignore"):
            r = (np.asarray(xs, dtype=float) - x) / sx
        # a diverging trial run: a large finite residual (least squares rejects the step), not inf
        return np.clip(np.nan_to_num(r, nan=1e3, posinf=1e3, neginf=-1e3), -1e3, 1e3)

    sol = least_squares(resid, [x[0] / sx, v_guess / sv], method="lm", xtol=1e-12, ftol=1e-12, max_nfev=200)
    return float(sol.x[0] * sx), float(sol.x[1] * sv)


def validate_cli(model_dir, csv, *, rows=None, time_col="t", x_col="x", force_col="F", sample_rate=None,
                 hold=None, substeps=None, out_dir=None, init_window=None) -> tuple[list[str], list[str]]:
    """``charcurves validate``: free runs of a saved model on row spans of a CSV record.

    The initial state of each span is estimated from its first 128 samples
    (:func:`estimate_initial_state`); the RMSE is over every sample of the span. With
    ``init_window`` N (the benchmarks' convention) the state is fitted to the first N samples of each
    span only and the RMSE counted after them. Returns the report lines and the spans
    (``"start:stop"``) whose free run failed.

    Examples
    --------
    >>> import os, tempfile
    >>> import charcurves as cc
    >>> from charcurves.simulate import validate_cli
    >>> from charcurves.systems import get_system
    >>> folder = tempfile.mkdtemp()
    >>> record = get_system("duffing").simulate(t_end=10.0, n_points=251)
    >>> record.to_csv(os.path.join(folder, "record.csv"))
    >>> cc.fit(record, method="parametric", basis="f1=z; f2=z, z**3").save(os.path.join(folder, "model"))
    >>> lines, failed = validate_cli(os.path.join(folder, "model"), os.path.join(folder, "record.csv"),
    ...                              rows=[slice(0, 200)], substeps=1)
    >>> lines[1].split(",")[0], failed
    ('  rows 0:200: ok', [])
    """
    import os

    from ..data import Trajectory
    from ..model import load_model

    model = load_model(model_dir)
    if getattr(model.template, "is_general", False):
        raise ConfigError(f"validate simulates the separable family; the {model.template.family} template is "
                          "not supported")
    refined = model.info.get("output_error", {})
    hold = hold or refined.get("hold", "linear")
    substeps = substeps if substeps is not None else refined.get("substeps", 4)
    check_hold(hold, substeps)
    full = Trajectory.from_csv(csv, time_col=time_col, x_col=x_col, force_col=force_col, sample_rate=sample_rate)
    spans = rows or [slice(0, full.n_samples)]
    results, sims = [], []
    for span in spans:
        beyond = [v for v in (span.start, span.stop) if v is not None and v > full.n_samples]
        if beyond:  # clamped silently before (issue 50)
            raise DataError(f"--rows {'' if span.start is None else span.start}:{'' if span.stop is None else span.stop}"
                            f" goes beyond the file, which has {full.n_samples} rows; choose START:STOP within "
                            f"0:{full.n_samples}")
        start, stop, _ = span.indices(full.n_samples)
        if stop - start < 16:
            raise DataError(f"--rows {span.start}:{span.stop} selects {max(stop - start, 0)} of the record's "
                            f"{full.n_samples} rows; give a span of at least 16 rows inside the record")
        seg = full.slice(slice(start, stop))
        rmse, res = free_run_error(model, seg, hold=hold, substeps=substeps, init_window=init_window)
        x = np.asarray(seg.x)[int(init_window or 0):]
        results.append({"rows": [start, stop], "status": res.status, "rmse": rmse,
                        "rmse_rows": [start + int(init_window or 0), stop],
                        "rmse_relative_to_std": rmse / float(np.std(x)) if np.std(x) > 0 else None,
                        "std_x": float(np.std(x)), "seconds": res.seconds})
        band = None
        if res.ok:  # the posterior propagated through the free run, where the model has one (._predictive)
            from ._predictive import predictive_band

            band = predictive_band(model, seg, float(res.x[0]), float(res.v[0]), hold=hold, substeps=substeps,
                                   skip=int(init_window or 0))
            if band is not None:
                results[-1]["predictive_band"] = {k: band[k] for k in ("level", "inside", "draws", "diverged",
                                                                       "noise_sd", "unbounded") if k in band}
        sims.append((seg, res, f"{start}:{stop}", band))
    how = "initial state fitted to the first 128 samples" if init_window is None else \
        f"initial state fitted to the first {init_window} samples of each span, the RMSE counted after them"
    lines = [f"free run of {model_dir} ({model.method}; hold {hold}, {substeps} RK4 steps per sample; {how})"]
    for r in results:
        pct = "" if r["rmse_relative_to_std"] is None else f" ({100 * r['rmse_relative_to_std']:.3g} % of std x)"
        pb = r.get("predictive_band")
        inside = "" if pb is None else \
            f", no predictive band: the record leaves {', '.join(pb['unbounded'])} undetermined" if "unbounded" in pb \
            else f", {100 * pb['inside']:.3g} % of x inside the 95 % predictive band"
        lines.append(f"  rows {r['rows'][0]}:{r['rows'][1]}: {r['status']}, RMSE {r['rmse']:.5g}{pct}, "
                     f"{r['seconds']:.2f} s{inside}")
    if out_dir is not None:
        from ..io import atomic_write_bytes, json_bytes, non_finite_paths

        os.makedirs(out_dir, exist_ok=True)
        rel = lambda p: os.path.relpath(os.path.abspath(os.fspath(p)), os.path.abspath(out_dir)).replace(os.sep, "/")  # noqa: E731
        failed = [r for r in results if r["status"] != "ok" or not np.isfinite(r["rmse"])]
        doc = {"model": rel(model_dir), "csv": rel(csv), "hold": hold, "substeps": int(substeps),
               "init_window": None if init_window is None else int(init_window), "initial_state": how,
               "status": "failed" if failed else "ok", "segments": results}
        doc["non_finite"] = non_finite_paths(doc)
        atomic_write_bytes(os.path.join(out_dir, "validation.json"), json_bytes(doc))
        _validation_figure(os.path.join(out_dir, "validation.png"), sims)
        lines.append(f"wrote {os.path.join(out_dir, 'validation.json')}, validation.png")
    failed_spans = [f"{r['rows'][0]}:{r['rows'][1]}" for r in results if r['status'] != 'ok' or not np.isfinite(r['rmse'])]
    return lines, failed_spans


def _validation_figure(path, sims) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(sims), 2, figsize=(12, 2.8 * len(sims)), squeeze=False,
                             gridspec_kw={"width_ratios": [1, 2]})
    for row, (seg, res, label, band) in enumerate(sims):
        band = None if band is not None and "unbounded" in band else band  # no finite band to draw
        t, x = np.asarray(seg.t), np.asarray(seg.x)
        n = res.x.size
        mid = x.size // 2
        win = slice(max(0, mid - 75), min(x.size, mid + 75))
        ax = axes[row, 0]
        ax.plot(t[win], x[win], "k", lw=1.5, label="measured")
        if n:
            ax.plot(t[:n][win], res.x[win], "C1", lw=1.0, label="free run")
        if band is not None:
            ax.fill_between(t[win], band["lo"][win], band["hi"][win], color="C1", alpha=0.25, lw=0,
                            label=f"{100 * band['level']:g} % predictive band ({100 * band['inside']:.3g} % inside)")
        ax.set_title(f"{seg.name} rows {label}: zoom", fontsize=9)
        ax.set_xlabel("t")
        ax.set_ylabel("x")
        ax.legend(fontsize=7)
        ax = axes[row, 1]
        if n:
            ax.plot(t[:n], res.x - x[:n], "C3", lw=0.5)
        if band is not None:
            ax.fill_between(t, band["lo"] - band["centre"], band["hi"] - band["centre"], color="C1", alpha=0.25, lw=0)
        ax.set_title(f"simulation error ({res.status}; std x {np.std(x):.4g})", fontsize=9)
        ax.set_xlabel("t")
        ax.set_ylabel("simulated - measured")
    fig.tight_layout()
    import io

    from ..io import atomic_write_bytes

    buf = io.BytesIO()  # rendered in memory, then written like every other output (atomically, links through)
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())
