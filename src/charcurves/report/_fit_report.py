"""The one-page report of one fit: a self-contained HTML page (figures inline as base64 PNG, no
external assets) with the equation and closed forms, the curves (truth and bands where known), the
fit's statistics, output-error diagnostics, settings, warnings and versions.

``charcurves report FIT_DIR`` and ``charcurves fit ... --report`` write it; in Python,
``fit_report(model).to_html()``.
"""

from __future__ import annotations

import json
import os
import platform

from .._errors import ModelFileError
from ..fitting import residual_test_rows
from ..model import (curve_lines, equation_text, figure_png, fit_statistics, load_model, model_posterior,
                     output_error_rows, posterior_bands, resolve_truth, scalar_lines, settings_rows)
from ._html import Report

__all__ = ["fit_report", "load_fit", "versions", "write_fit_report"]


def versions() -> dict[str, str]:
    """Versions of charcurves, Python, torch and numpy here (torch's read from its metadata, not imported).

    Examples
    --------
    >>> from charcurves.report import versions
    >>> sorted(versions())
    ['charcurves', 'numpy', 'python', 'torch']
    """
    from importlib import metadata

    from .._version import VERSION

    out = {"charcurves": VERSION, "python": platform.python_version()}
    for dist in ("torch", "numpy"):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[dist] = "not installed"
    return out


def load_fit(path: str | os.PathLike):
    """The model and the ``result.json`` of a fit: ``(model, result or None)``.

    ``path`` is the folder ``charcurves fit --out`` wrote (with ``model/`` and ``result.json``) or a
    model folder itself (``model.json``; when it is named ``model``, the ``result.json`` beside it is read too). The
    bands stored in ``result.json`` are attached to the model so that its figure draws them.

    Examples
    --------
    >>> import os, tempfile
    >>> import charcurves as cc
    >>> from charcurves.report import load_fit
    >>> from charcurves.systems import get_system
    >>> path = os.path.join(tempfile.mkdtemp(), "model")
    >>> cc.fit(get_system("duffing").simulate(), method="poly-cc").save(path)
    >>> model, result = load_fit(path)  # a model folder: no result.json beside it
    >>> model.method, result
    ('poly-cc', None)
    """
    p = os.fspath(path)
    if not os.path.isdir(p):
        what = "does not exist" if not os.path.exists(p) else "is not a directory"
        raise ModelFileError(f"{p!r} {what}; give the folder 'charcurves fit --out' wrote, or its model/ folder")
    if os.path.isfile(os.path.join(p, "model.json")):  # fit writes result.json beside a folder named model/
        parent = os.path.dirname(os.path.abspath(p))
        model_dir = p
        result_path = os.path.join(parent, "result.json") if os.path.basename(os.path.abspath(p)) == "model" else ""
    elif os.path.isdir(os.path.join(p, "model")):
        model_dir, result_path = os.path.join(p, "model"), os.path.join(p, "result.json")
    else:
        raise ModelFileError(f"{p!r} is not a fit folder (no model/ in it) nor a model folder (no model.json); give "
                             "the folder 'charcurves fit --out' wrote, or its model/ folder")
    model = load_model(model_dir)
    result = None
    if os.path.isfile(result_path):
        try:
            with open(result_path, encoding="utf-8") as fh:
                result = json.load(fh)
        except (OSError, UnicodeDecodeError, ValueError, RecursionError):
            raise ModelFileError(f"{result_path!r} is not readable JSON; delete it to report the model alone, "
                                 "or re-fit") from None
        from ._result_file import check_result_fields

        check_result_fields(result, result_path)  # a field of another type: one line, not a TypeError later
        if result.get("method") not in (None, model.method):
            result = None  # not this model's result.json
    if result and isinstance(result.get("bands"), dict) and result["bands"]:
        setattr(model, "bands", result["bands"])  # as selection.attach_bands does
    return model, result


def fit_report(model, *, result: dict | None = None, truth=None, title: str | None = None) -> Report:
    """The report of one fitted model as a :class:`Report` (``.to_html()`` gives the page).

    Parameters
    ----------
    model : FittedModel
    result : dict, optional
        The fit's ``result.json`` (source record, warnings, errors against the truth).
    truth : mapping or str, optional
        True curves (name -> callable) or a benchmark system's name, drawn dashed and compared.
    title : str, optional

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.report import fit_report
    >>> from charcurves.systems import get_system
    >>> model = cc.fit(get_system("duffing").simulate(), method="parametric", basis="f1=z; f2=z, z**3")
    >>> page = fit_report(model, truth="duffing").to_html()
    >>> "x'' + 0.3*x' + (x**3 - x) = F" in page.replace("&#x27;", "'")
    True
    """
    from ..metrics import curve_errors

    result = result or {}
    truth = resolve_truth(truth)
    rep = Report(title or f"charcurves fit: {model.method} on {model.template.equation}")
    what = [f"Method `{model.method}` on the template `{model.template.equation}`"]
    if result.get("source"):
        what.append(f"record `{result['source']}` (relative to the fit folder)")
    rep.paragraph("; ".join(what) + ".")
    if model.info.get("interrupted") or result.get("interrupted"):
        rep.paragraph("Interrupted: these are the best curves reached before Ctrl-C, or a finished fit without "
                      "the steps listed in the fit's info; rerun the fit to complete it.")

    rep.heading("Identified equation")
    text = equation_text(model)
    if text is not None:
        rep.paragraph(f"`{text}`")
        rep.paragraph("Numbers to 4 significant digits; terms below that precision over the curves' training "
                      "ranges are left out. The model files keep every digit.")
        if model_posterior(model) is not None:  # every term, each constant with its posterior sd
            rep.paragraph(f"With 1-sd posterior uncertainties: `{model.to_sympy(uncertainty=True)}`")
    else:
        rep.paragraph("Some curves have no closed form (neural curves not distilled); refit with a +post-sr "
                      "method or run `charcurves.fitting.distill_model` to get one.")
    rep.bullets(curve_lines(model))

    rep.heading("Curves")
    bands = getattr(model, "bands", None) or {}
    if not bands and (bands := posterior_bands(model)):  # the fit's posterior (saved with the model)
        setattr(model, "bands", bands)
    parts = ["The identified curves over their training range (shaded), drawn 15 % beyond it"]
    if truth:
        parts.append("the true curves dashed")
    if bands:
        parts.append("uncertainty bands filled")
    rep.figure(figure_png(model, truth, width=4.6, height=3.4, dpi=100), "curves", caption="; ".join(parts) + ".")
    errors = curve_errors(model, truth) if truth else (result.get("curve_rmse") or {})
    if errors:
        where = ("over each curve's training range" if truth else
                 "as the fit computed them (result.json curve_rmse; the truth it was given is not drawn here)")
        rep.table(["curve", "RMSE against the truth"], [[k, float(v) if v is not None else None]
                                                        for k, v in errors.items()], digits=4,
                  caption=f"Errors of the curves against the true ones, {where}.")

    rep.heading("Fit statistics")
    rep.table(["quantity", "value"], [list(r) for r in fit_statistics(model)])
    pm = [line.strip() for line in scalar_lines(model)]
    if pm:
        rep.paragraph("The learned scalars with their posterior standard deviations (the bands of the curves above "
                      "come from the same posterior):")
        rep.bullets(pm)
    oe = output_error_rows(model)
    rep.heading("Output error (free runs of the model against the measured x)")
    if oe:
        rep.table(["quantity", "value"], [list(r) for r in oe])
    else:
        rep.paragraph("No output-error refinement in this fit (the objective was equation error), so no free-run "
                      "RMSE is recorded; `charcurves validate MODEL_DIR RECORD.csv` runs one.")

    rep.heading("Self-check")
    check = model.info.get("self_check") or {}
    if check:
        rt = check.get("residual_tests") or {}
        rep.paragraph(f"Loss over the noise floor: {', '.join(f'{r:.3g}' for r in check['loss_over_floor'])} "
                      f"(warned above {check['threshold']:g}; {check['floor_source']})."
                      + (f" Residual tests (a residual that is a function of a curve's argument or, with measured "
                         f"derivatives, correlated with the input or not white means a misfit): {len(rt['tests'])} "
                         f"tests at an overall level of {rt['level']:g} (each at {rt['per_test_level']:.2g}), "
                         f"{'all passed' if rt['passed'] else 'some FAILED'}; whiteness {rt['whiteness']}."
                         if rt else ""))
        tests = residual_test_rows(model)
        if tests:
            rep.table(["test", "of", "statistic", "verdict"], [list(r) for r in tests])
    else:
        rep.paragraph("This model does not record a self-check (fitted by an older charcurves).")

    rep.heading("Settings")
    rows = settings_rows(model)
    if rows:
        rep.table(["setting", "value"], [list(r) for r in rows])
    else:
        rep.paragraph("This model does not record its settings (fitted by an older charcurves).")

    rep.heading("Warnings")
    warnings = [str(w) for w in (result.get("warnings") or [])]
    if warnings:
        rep.bullets(warnings)
    elif result:
        rep.paragraph("None about the record.")
    else:
        rep.paragraph("No result.json beside the model, so the warnings about the record are not known here.")

    rep.heading("Versions")
    rep.paragraph("The software that wrote this page (with `fit --report`, the same run as the fit).")
    rep.table(["package", "version"], [[k, v] for k, v in versions().items()])
    return rep


def write_fit_report(path: str | os.PathLike, out: str | os.PathLike, *, truth=None) -> str:
    """Write the report of the fit in ``path`` (see :func:`load_fit`) to the HTML file ``out``; returns ``out``.

    Examples
    --------
    >>> import os, tempfile
    >>> import charcurves as cc
    >>> from charcurves.report import write_fit_report
    >>> from charcurves.systems import get_system
    >>> folder = tempfile.mkdtemp()
    >>> cc.fit(get_system("duffing").simulate(), method="parametric", basis="f1=z; f2=z, z**3").save(os.path.join(folder, "model"))
    >>> out = write_fit_report(os.path.join(folder, "model"), os.path.join(folder, "report.html"))
    >>> with open(out, encoding="utf-8") as fh:
    ...     print("<h1>" in fh.read())
    True
    """
    from ..io import atomic_write_bytes

    model, result = load_fit(path)
    page = fit_report(model, result=result, truth=truth).to_html()
    out = os.fspath(out)
    atomic_write_bytes(out, page.encode("utf-8"))
    return out
