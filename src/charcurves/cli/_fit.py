"""``charcurves fit`` and ``charcurves demo``: fit a record, write result.json, the model and a summary."""

from __future__ import annotations

import os
import sys
import time

from ._common import (FIT_OUTPUTS, check_out_dir, first_interrupt_only, held_out_dir, make_out_dir, say,
                      signals_deferred, warn)

__all__ = ["cmd_fit", "cmd_demo", "source_path", "time_column"]


def _progress_printer(enabled: bool):
    """A training callback printing at most every 2 s, starting 2 s in (short fits stay silent)."""
    if not enabled:
        return None
    last = [time.monotonic()]

    def report(phase, step, total, loss):
        now = time.monotonic()
        if now - last[0] >= 2.0:
            last[0] = now
            shown = f"  loss {loss:.4g}" if loss == loss else ""  # nan: a search, whose loss is not known yet
            print(f"  [{phase}] {step}/{total}{shown}  (Ctrl-C stops and keeps the best model so far)",
                  file=sys.stderr, flush=True)

    return report


def time_column(text: str | None) -> str | None:
    """``--time-col none`` ignores any time column (then ``--sample-rate`` gives the times)."""
    return None if text is None or text.strip().lower() == "none" else text


def source_path(csv: str, out_dir: str) -> str:
    """The record's path as ``result.json`` stores it: relative to the output folder (POSIX
    separators), so the same record and options give the same bytes wherever the two folders lie
    (as long as they keep their relative position); absolute only when no relative path exists
    (another drive)."""
    try:
        rel = os.path.relpath(os.path.abspath(csv), os.path.abspath(out_dir))
    except ValueError:  # Windows: another drive
        return os.path.abspath(csv)
    return rel.replace(os.sep, "/")


def fit_and_write(traj, out_dir, *, method, family="separable", sym=None, free_gain=False, gauge=None,
                  gain_on="force", preset="default", seed=0, derivatives="auto", jump="auto", basis=None,
                  keep_sticking=False, truth=None, threads=None, device="cpu", figure=True, quiet=False, source=None,
                  sr_options=None, refine=None, refine_options=None, bands=None, bands_kind="bootstrap",
                  bands_level=0.95, equation=None, warnings=(), objective=None, report=False, snr=None):
    from ..fitting import CharacteristicCurves, cli_objective

    est = CharacteristicCurves.from_method(
        method, family=family, symmetry=sym, free_gain=free_gain, gauge=gauge, gain_on=gain_on, preset=preset,
        differentiator=derivatives,
        jump=jump if jump in ("auto", "none", "") else [j for j in jump.split(",") if j.strip()],
        basis=basis, sr_options=sr_options, exclude_sticking=not keep_sticking, random_state=seed,
        threads=1 if threads is None else threads, device=device, progress=_progress_printer(not quiet),
        objective=cli_objective(objective, refine, refine_options or None), equation=equation, snr_db=snr,
    )
    check_out_dir(out_dir)  # before the fit: a bad --out must not cost a long run
    # one writer at a time (a second fit into the same --out is refused); a second interrupt never
    # loses what the first kept
    with held_out_dir(out_dir), first_interrupt_only():
        t0 = time.perf_counter()
        if bands is not None:
            from ..fitting import check_band_options

            # before the fit: a bad option must not cost a long run
            check_band_options(8 if bands == "posterior" else bands, bands_level)
        model = est.fit(traj).model_
        late, attached = False, False  # from here on the fit is finished: an interrupt never loses it
        try:
            say(f"charcurves: priors: {model.info['priors']['summary']}"
                + ("; tests in result.json under 'symmetry'" if "symmetry_auto" in model.info else ""), quiet)
            if bands == "posterior" and not model.info.get("interrupted"):
                from ._bands import attach_posterior_bands

                attach_posterior_bands(model, bands_level, quiet)
                attached = True
            elif bands is not None and not model.info.get("interrupted"):
                from ..fitting import fit_ensembles, resolved_estimator
                from ..selection import attach_bands, curve_bands

                say(f"uncertainty bands: {bands} {bands_kind} refits ...", quiet)
                ens = fit_ensembles(resolved_estimator(est, model), [traj], bands, kind=bands_kind, points=[model])[0]
                attach_bands(model, curve_bands(ens, level=bands_level))
                attached = True
        except KeyboardInterrupt:  # write the finished fit, with the bands (if asked) marked skipped
            if bands is not None and not attached and not model.info.get("interrupted"):
                model.info["interrupted"] = True
                model.info["bands"] = "skipped: interrupted"
            else:
                late = True
        elapsed = time.perf_counter() - t0
        with signals_deferred() as late_interrupt:
            make_out_dir(out_dir)
            write_results(model, out_dir, method=model.method, family=family, free_gain=free_gain, truth=truth,
                          figure=figure, quiet=quiet, source=source, elapsed=elapsed, warnings=list(warnings),
                          record=traj, report=report)
    model.info["interrupted_while_writing"] = late or late_interrupt[0]
    return model


def _curves_figure(model, truth, record, title):
    """curves.png: the curves; below them, for a fit refitted by output error, the measured x against
    the model's free run over the whole record and the residual (the diagnostics panel)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from ..fitting import free_run_diagnostics
    from ..report import plot_curves, plot_free_run

    # a Figure on the Agg canvas, not pyplot: nothing global is opened and pyplot's import (about
    # 0.3 s of a 6 s fit) is not paid
    diag = free_run_diagnostics(model, record) if record is not None else None
    n = len(model.curves)
    fig = Figure(figsize=(5.0 * n, 3.8 if diag is None else 3.8 + 4.4))
    FigureCanvasAgg(fig)
    if diag is None:
        return plot_curves(model, truth, axes=[fig.add_subplot(1, n, k + 1) for k in range(n)], title=title)
    grid = fig.add_gridspec(3, n, height_ratios=(1.5, 1.0, 0.7))
    plot_curves(model, truth, axes=[fig.add_subplot(grid[0, k]) for k in range(n)])
    top = fig.add_subplot(grid[1, :])
    plot_free_run(*diag, axes=[top, fig.add_subplot(grid[2, :], sharex=top)])
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig


def write_results(model, out_dir, *, method, family, free_gain, truth, figure, quiet, source, elapsed, warnings=(),
                  record=None, report=False):
    """result.json (what the inputs and the seed determine, bit-identical on reruns; standard JSON:
    non-finite numbers as null, listed under ``non_finite``), timing.json (wall-clock times), the
    model, curves.png, summary.txt and (``report``) report.html. ``warnings`` (one line each, about the record), then the
    fit's own (``model.info["warnings"]``: the self-check, a failed output error) go to stderr and
    to result.json ``warnings`` (an empty list when there are none); the self-check's ratios are in
    result.json ``loss_over_floor``."""
    from ..io import atomic_write_bytes, json_bytes, non_finite_paths
    from ..metrics import curve_errors

    result = model.result_dict()
    result["interrupted"] = bool(model.info.get("interrupted", False))
    if source:
        result["source"] = source
    if "records" in model.info:  # several records in one fit: each one's losses and free-run RMSE
        result["records"] = [dict(r, source=s) for r, s in zip(model.info["records"], source)] \
            if isinstance(source, list) else list(model.info["records"])
    result["warnings"] = [str(w) for w in warnings] + [str(w) for w in model.info.get("warnings", [])]
    check = model.info.get("self_check")
    if check:
        result["loss_over_floor"] = list(check["loss_over_floor"])
        result["noise_floor"] = {"value": list(check["noise_floor"]), "source": check["floor_source"],
                                 "loss": check["loss"]}
        if check.get("residual_tests"):  # the tests themselves: info.self_check.residual_tests
            result["residual_tests_passed"] = bool(check["residual_tests"]["passed"])
    errors = None
    if truth is not None:
        errors = curve_errors(model, truth)
        result["curve_rmse"] = errors
        from ._truth import truth_mismatch

        mismatch = truth_mismatch(model, truth, errors)
        if mismatch:
            result["warnings"].append(mismatch)
    bad = non_finite_paths(result)
    if bad:
        result["non_finite"] = bad  # the numbers written as null, by path
    for line in result["warnings"]:
        warn(line)
    model.save(os.path.join(out_dir, "model"))
    atomic_write_bytes(os.path.join(out_dir, "result.json"), json_bytes(result))
    timing = {"fit_seconds": elapsed, **model.timings()}
    atomic_write_bytes(os.path.join(out_dir, "timing.json"), json_bytes(timing))
    if figure:
        fig = _curves_figure(model, truth, record, f"{method}: {model.template.equation}")
        import io

        buf = io.BytesIO()  # rendered in memory, then written atomically like the other files
        fig.savefig(buf, format="png", dpi=120)
        atomic_write_bytes(os.path.join(out_dir, "curves.png"), buf.getvalue())
    if report:
        import matplotlib

        matplotlib.use("Agg")
        from ..report import fit_report

        page = fit_report(model, result=result, truth=truth).to_html()
        atomic_write_bytes(os.path.join(out_dir, "report.html"), page.encode("utf-8"))
    from .. import __version__
    from ..fitting import format_closed_form

    fam = getattr(model.template, "family", family)
    where = "a user-written equation" if fam == "custom" else f"the {fam} family"
    lines = [f"charcurves {__version__} — {method} on {where}: {model.template.equation}",
             f"fit time {elapsed:.2f} s, data loss {model.loss:.4g}, gain {model.gain:.6g}"
             + ("" if not free_gain else " (learned)") + f", free constant {model.offset:.4g}"]
    for name, c in model.curves.items():
        expr = c.expression()
        comp = c.components()
        extra = ""
        if "jump_height" in comp:
            extra = f"; jump at 0: height {comp['jump_height']:.4g}, width {comp['jump_width']:.3g}"
        lines.append(f"  {name}({c.argument}) on [{c.domain[0]:.4g}, {c.domain[1]:.4g}]"
                     + (f" = {format_closed_form(expr, c.domain, argument=c.argument)}" if expr is not None
                        else f" ({c.kind} curve)") + extra
                     + (f"; RMSE vs truth {errors[name]:.3e}" if errors and name in errors else ""))
    if any(c.expression() is not None for c in model.curves.values()):
        lines.append("  (closed forms to 4 significant digits, terms below that precision left out; result.json "
                     "and model/ keep every digit)")
    for name, value in result.get("scalars", {}).items():  # unknown scalars of user-written templates
        lines.append(f"  {name} = {value:.6g}")
    from ..fitting import closed_form_lines, scalar_lines

    lines += scalar_lines(model)  # the posterior's ± (where the fit has one)
    lines += closed_form_lines(model)  # the closed forms' constants with theirs
    if "output_error" in model.info:
        from ..fitting import summary_lines

        lines += summary_lines(model)
    for k, r in enumerate(result.get("records", [])):
        rmse = r.get("free_run_rmse")
        lines.append(f"  record {k} ({r.get('source', r['name'])}): {r['n_samples']} samples, step {r['dt']:.4g}, "
                     f"equation-error loss {r['loss_equation_error']:.4g}"
                     + ("" if rmse is None else f", free-run RMSE x {rmse:.4g}"))
    lines += _settings_lines(model)
    lines += _self_check_lines(model)
    lines += [f"warning: {w}" for w in result["warnings"]]
    skipped = _skipped_by_interrupt(model)
    if skipped:
        lines.append(f"interrupted: the fit finished, but Ctrl-C skipped {' and '.join(skipped)}")
    elif result["interrupted"]:
        lines.append("interrupted: these are the best curves reached before Ctrl-C, not a finished fit")
    lines.append(f"wrote {os.path.join(out_dir, 'result.json')}" + (", curves.png" if figure else "")
                 + (", report.html" if report else "") + ", timing.json, model/")
    text = "\n".join(lines)
    atomic_write_bytes(os.path.join(out_dir, "summary.txt"), (text + "\n").encode())
    say(text, quiet)


def _self_check_lines(model) -> list[str]:
    """The self-check: loss over the noise floor and the residual tests (result.json info.self_check)."""
    from ..fitting import residual_test_rows

    check = model.info.get("self_check")
    if not check:
        return []
    ratios = ", ".join(f"{r:.3g}" for r in check["loss_over_floor"])
    rt = check.get("residual_tests") or {}
    lines = [f"self-check (result.json info.self_check): loss over noise floor {ratios}"
             + (f"; residual tests at level {rt['level']:g} ({len(rt['tests'])} tests, each at "
                f"{rt['per_test_level']:.2g}): {'passed' if rt['passed'] else 'FAILED'}" if rt else "")]
    lines += [f"  {what}: {stat}, {verdict}" for _, what, stat, verdict in residual_test_rows(model)]
    return lines


def _settings_lines(model) -> list[str]:
    """Every default that shaped the answer (also in result.json under info.settings)."""
    st = model.info.get("settings")
    if not st:
        return []
    from ..fitting import anchor_notes

    curves = ", ".join(f"{k} = {v}" for k, v in st["curves"].items())
    return ["settings (result.json info.settings):",
            f"  template {st['template']} ({st['family']}), gauge {', '.join(st['gauge']) or 'none'}",
            *(f"  note: {line}" for line in anchor_notes(model)),
            f"  curves {curves}" + (f"; learned jump on {', '.join(st['jumps'])}" if st["jumps"] else ""),
            f"  derivatives {st['differentiator']}; objective {st['objective']} (asked: {st['objective_requested']}); "
            f"post-SR {'yes' if st['post_sr'] else 'no'}; training preset {st['preset']}"]


def cmd_fit(a) -> int:
    from ..templates import read_record
    from ._common import UsageError

    if a.gauge is not None and a.family == "separable" and not a.equation and a.gauge not in ("f1", "f2"):
        raise UsageError(f"argument --gauge: invalid choice: {a.gauge!r} (the separable family anchors 'f1' or "
                         "'f2'; other families name their own curves) (see 'charcurves fit --help')")

    from ..io import FOLDER_LOCK_NAME
    from ._common import refuse_inputs_among_outputs

    paths = [a.csv] if isinstance(a.csv, str) else list(a.csv)
    outputs = [os.path.join(a.out, name) for name in FIT_OUTPUTS + (FOLDER_LOCK_NAME,)]
    seen: dict[str, str] = {}
    for path in paths:
        refuse_inputs_among_outputs({"record": path}, outputs)
        key = os.path.realpath(path)
        if key in seen:  # the same samples twice would count as two independent records
            raise UsageError(f"the record {path!r} is given twice (also as {seen[key]!r}); give each record once")
        seen[key] = path
    if getattr(a, "measured", None):
        if len(paths) > 1:
            raise UsageError("--measured (hidden states) takes one record; fit one CSV file")
        from ._hidden import cmd_fit_hidden

        a.csv = paths[0]
        return interrupted_exit(cmd_fit_hidden(a), a.out)
    if len(paths) > 1 and a.bands is not None:
        raise UsageError("--bands takes one record; fit several records without --bands")
    records = [read_record(path, family=a.family, equation=a.equation, time_col=time_column(a.time_col), x_col=a.x_col,
                           force_col=a.force_col, sample_rate=a.sample_rate, rows=a.rows) for path in paths]
    traj = records[0] if len(records) == 1 else records
    quality = records[0].quality_warnings() if len(records) == 1 else \
        [f"{path}: {w}" for path, r in zip(paths, records) for w in r.quality_warnings()]
    source = source_path(paths[0], a.out) if len(paths) == 1 else [source_path(p, a.out) for p in paths]
    from ._cost import record_cost_warnings

    from ..fitting import cli_objective, get_preset, resolve_objective

    objective = resolve_objective(cli_objective(a.objective, a.refine))
    oe = objective.refines(not records[0].has_derivatives, get_preset(a.preset))
    cost = record_cost_warnings(sum(r.n_samples for r in records), allow_long=a.long_record, output_error=oe)
    for line in cost:  # before the fit, not only in result.json after it
        warn(line)
    truth = None
    if a.truth:
        from ..systems import get_system

        truth = get_system(a.truth, a.truth_variant).true_curves()
    sr_options = {k: v for k, v in (("engine", a.sr_engine), ("generations", a.sr_generations),
                                    ("populations", a.sr_populations), ("max_size", a.sr_max_size),
                                    ("operators", a.sr_operators)) if v is not None}
    refine_options = {k: v for k, v in (("hold", a.refine_hold), ("substeps", a.refine_substeps),
                                        ("segment_length", a.segment_length)) if v is not None}
    model = fit_and_write(traj, a.out, method=a.method, family=a.family, sym=a.sym, free_gain=a.free_gain,
                          sr_options=sr_options, gauge=a.gauge, gain_on=a.noisy_side, preset=a.preset, seed=a.seed,
                          derivatives=a.derivatives, jump=a.jump, basis=a.basis, keep_sticking=a.keep_sticking,
                          truth=truth, threads=a.threads, device=a.device, figure=not a.no_figure, quiet=a.quiet,
                          source=source, refine=a.refine, refine_options=refine_options,
                          bands=a.bands, bands_kind=a.bands_kind, bands_level=a.bands_level, equation=a.equation,
                          warnings=quality, objective=a.objective, report=a.report, snr=a.snr)
    return interrupted_exit(model, a.out)


def _skipped_by_interrupt(model) -> list[str]:
    """The steps after a finished fit that Ctrl-C skipped (post-SR, bands); [] when the training itself
    was interrupted (then the curves are the best reached, and that is what is reported)."""
    if not model.info.get("interrupted") or "interrupted" in str(model.info.get("stopped_by", "")):
        return []
    return [label for key, label in (("post_sr", "post-SR"), ("refine", "the output-error refinement"),
                                     ("bands", "the uncertainty bands"))
            if model.info.get(key) == "skipped: interrupted"]


def interrupted_exit(model, out_dir: str) -> int:
    """0, or 130 with one line when Ctrl-C or SIGTERM stopped the fit (the best model so far was written)."""
    if model.info.pop("interrupted_while_writing", False) and not model.info.get("interrupted"):
        print(f"charcurves: interrupted while writing; the finished fit was written completely to {out_dir}",
              file=sys.stderr, flush=True)
        return 130
    if not model.info.get("interrupted"):
        return 0
    skipped = _skipped_by_interrupt(model)
    if skipped:
        print(f"charcurves: interrupted; the fit had finished and was written to {out_dir}, without "
              f"{' and '.join(skipped)} (result.json marked interrupted); rerun to compute them",
              file=sys.stderr, flush=True)
        return 130
    print(f"charcurves: interrupted; kept the best model so far in {os.path.join(out_dir, 'model')} "
          "(result.json marked interrupted); rerun to finish the fit", file=sys.stderr, flush=True)
    return 130


def cmd_demo(a) -> int:
    from ..data import corrupt
    from ..systems import get_system

    t0 = time.perf_counter()
    system = get_system("duffing")
    traj = corrupt(system.simulate(), 20.0, on="force", seed=a.seed)
    check_out_dir(a.out)
    with held_out_dir(a.out):  # the record and the fit, one writer at a time
        traj.to_csv(os.path.join(a.out, "duffing_20dB.csv"))
        say(f"simulated the Duffing oscillator (paper parameters), 20 dB noise on the forcing -> "
            f"{os.path.join(a.out, 'duffing_20dB.csv')}")
        model = fit_and_write(traj, a.out, method="nn-cc+sym", sym="f1=odd,f2=odd", seed=a.seed,
                              truth=system.true_curves(), threads=a.threads, warnings=traj.quality_warnings())
    say(f"demo finished in {time.perf_counter() - t0:.1f} s")
    return interrupted_exit(model, a.out)
