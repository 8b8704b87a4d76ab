"""Views of one fitted model for people: closed forms to the precision a fit supports, one line per
curve, the fit's statistics and settings, and the HTML block a notebook shows.

The stored model keeps every digit; only what is printed is rounded. The report package (above
this one) builds the one-page fit report from these same views.
"""

from __future__ import annotations

import base64
import html

from ._display import DISPLAY_DIGITS, curve_scale, display_number, format_closed_form
from ._gauge_notes import anchor_notes
from ._plots import figure_png

__all__ = ["equation_text", "curve_lines", "fit_statistics", "settings_rows", "output_error_rows", "model_html"]


def equation_text(model, *, digits: int = DISPLAY_DIGITS) -> str | None:
    """The identified equation with the closed forms written in (``x'' + 0.3*x' + (x**3 - x) = F``),
    numbers to ``digits`` significant digits; several equations joined by ``; ``. None when a curve
    has no closed form (a neural curve not distilled).

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.fitting import equation_text
    >>> from charcurves.systems import get_system
    >>> model = cc.fit(get_system("duffing").simulate(), method="parametric", basis="f1=z; f2=z, z**3")
    >>> equation_text(model)
    "x'' + 0.3*x' + (x**3 - x) = F"
    """
    import sympy as sp

    if not model.is_symbolic:
        return None
    if model.template.is_general:
        eqs = model.to_sympy(digits=digits)
        eqs = eqs if isinstance(eqs, list) else [eqs]
        return "; ".join(f"{e.lhs} = {e.rhs}" for e in eqs)
    exprs = model.to_sympy(curves=True, digits=digits)
    text = "x''"
    for name, arg in (("f1", sp.Symbol("x'")), ("f2", sp.Symbol("x"))):
        e = exprs[name].subs(sp.Symbol("z"), arg)
        if e == 0:
            continue
        term = str(e)
        if len(sp.Add.make_args(e)) > 1:
            text += f" + ({term})"
        else:
            text += f" - {term[1:]}" if term.startswith("-") else f" + {term}"
    b = display_number(model.offset, curve_scale(model), digits)
    if b != 0:
        text += f" {'-' if b < 0 else '+'} {abs(float(b)):.{digits}g}"
    gain = "" if model.gain == 1 else f"{model.gain:.{digits}g}*"
    return f"{text} = {gain}F"


def _settings(model) -> dict:
    st = model.info.get("settings") if isinstance(getattr(model, "info", None), dict) else None
    return st if isinstance(st, dict) else {}


def curve_lines(model, *, digits: int = DISPLAY_DIGITS) -> list[str]:
    """One line per curve: its closed form where it has one, else what kind of curve it is and how to distil it.

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.fitting import curve_lines
    >>> from charcurves.systems import get_system
    >>> model = cc.fit(get_system("duffing").simulate(), method="parametric", basis="f1=z; f2=z, z**3")
    >>> curve_lines(model)[0]
    "f1(x') = 0.3*x' on [-0.9304, 0.9809]"
    """
    representation = _settings(model).get("curves", {})
    out = []
    for name, c in model.curves.items():
        lo, hi = (float(v) for v in c.domain)
        where = f"on [{lo:.4g}, {hi:.4g}]"
        expr = c.expression()
        comps = c.components() or {}
        jump = (f"; a jump at 0 of height {comps['jump_height']:.4g} (width {comps['jump_width']:.3g})"
                if "jump_height" in comps else "")
        if expr is not None:
            text = format_closed_form(expr, c.domain, digits=digits, argument=c.argument)
            out.append(f"{name}({c.argument}) = {text} {where}{jump}")
        else:
            rep = representation.get(name) or type(c).__name__
            out.append(f"{name}({c.argument}) {where}: a {c.kind} curve ({rep}), no closed form; distil it with "
                       f"post_sr=True or a +post-sr method{jump}")
    return out


def fit_statistics(model) -> list[tuple[str, str]]:
    """``(quantity, value)`` rows: method, template, objective, data loss, gain, constant, scalars, samples.

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.fitting import fit_statistics
    >>> from charcurves.systems import get_system
    >>> model = cc.fit(get_system("duffing").simulate(), method="parametric", basis="f1=z; f2=z, z**3")
    >>> dict(fit_statistics(model))["gain g"]
    '1 (fixed)'
    """
    st = _settings(model)
    rows = [("method", str(model.method)),
            ("template", str(st.get("template") or model.template.equation)),
            ("objective", str(st.get("objective") or "equation-error")),
            ("data loss (mean squared equation residual)", f"{model.loss:.4g}"),
            ("gain g", f"{model.gain:.6g} ({'learned' if model.template.free_gain else 'fixed'})"),
            ("free constant b", f"{model.offset:.4g}")]
    for name, value in (model.info.get("scalars") or {}).items():
        rows.append((f"scalar {name}", f"{float(value):.6g}"))
    if model.info.get("n_samples") is not None:
        rows.append(("samples fitted", f"{model.info.get('n_fitted_samples', model.info['n_samples'])} of "
                                       f"{model.info['n_samples']}"))
    if model.info.get("interrupted"):
        rows.append(("interrupted", "yes: the best curves reached before Ctrl-C"))
    return rows


def settings_rows(model) -> list[tuple[str, str]]:
    """The settings that shaped the answer (``model.info["settings"]``) as ``(setting, value)`` rows;
    empty for a model fitted before they were recorded.

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.fitting import settings_rows
    >>> from charcurves.systems import get_system
    >>> rows = dict(settings_rows(cc.fit(get_system("duffing").simulate(), method="poly-cc", symmetry="odd")))
    >>> rows["symmetry"], rows["gauge"], rows["objective"]
    ('f1 odd, f2 odd', 'f2(0) = 0', 'equation-error (asked: auto)')
    """
    st = _settings(model)
    if not st:
        return []
    rows = [("template", f"{st.get('template')} ({st.get('family')})"),
            ("curves", "; ".join(f"{k} = {v}" for k, v in (st.get("curves") or {}).items()) or "–"),
            ("symmetry", ", ".join(f"{k} {v}" for k, v in (st.get("symmetry") or {}).items()) or "none"),
            ("gauge", "; ".join([", ".join(f"{g}(0) = 0" for g in st.get("gauge") or ()) or "none",
                                 *anchor_notes(model)])),
            ("learned jumps", ", ".join(st.get("jumps") or ()) or "none"),
            ("differentiator", str(st.get("differentiator"))),
            ("objective", f"{st.get('objective')} (asked: {st.get('objective_requested')})"),
            ("post-SR", "yes" if st.get("post_sr") else "no"),
            ("training preset", str(st.get("preset")))]
    poly = {k: v for k, v in (st.get("polynomial_terms") or {}).items() if v}
    if poly:
        rows.append(("polynomial terms", "; ".join(f"{k}: z^{', z^'.join(str(p) for p in v)}"
                                                   for k, v in poly.items())))
    return rows


def output_error_rows(model) -> list[tuple[str, str]]:
    """The output-error refinement (``model.info["output_error"]``): status, how the free runs were
    simulated, and the free-run RMSE before and after; empty when there was none.

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.fitting import output_error_rows
    >>> from charcurves.systems import get_system
    >>> record = cc.corrupt(get_system("duffing").simulate(t_end=20.0, n_points=500), 30, on="state", seed=0)
    >>> model = cc.fit(record, method="parametric", basis="f1=z; f2=z, z**3", objective=cc.OutputError(segment_length=16, substeps=1, max_iter=2))
    >>> output_error_rows(model)[:2]
    [('status', 'ok'), ('free runs', 'hold linear, 1 RK4 step per sample, 33 segments of 16 samples, 2 iterations')]
    """
    oe = model.info.get("output_error") or {}
    if not isinstance(oe, dict) or not oe:
        return []
    rows = [("status", str(oe.get("status")))]
    if oe.get("segments") is not None:
        steps = "step" if oe.get("substeps") == 1 else "steps"
        rows.append(("free runs", f"hold {oe.get('hold')}, {oe.get('substeps')} RK4 {steps} per sample, "
                                  f"{oe.get('segments')} segments of {oe.get('segment_length')} samples, "
                                  f"{oe.get('iterations')} iterations"))
    for key, label in (("segmented_rmse", "RMSE of the segments' free runs (before → after)"),
                       ("free_run_rmse", "RMSE of one free run of the whole record (before → after)")):
        before, after = oe.get(f"{key}_before"), oe.get(f"{key}_after")
        if isinstance(before, (int, float)) and isinstance(after, (int, float)):
            rows.append((label, f"{before:.4g} → {after:.4g}"))
    return rows


def model_html(model, *, figure: bool = True, truth=None) -> str:
    """The HTML block a notebook shows for a fitted model: equation, curves, statistics, a small figure.

    The figure is an inline base64 PNG; if it cannot be drawn the block says why instead.

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.fitting import model_html
    >>> from charcurves.systems import get_system
    >>> model = cc.fit(get_system("duffing").simulate(), method="parametric", basis="f1=z; f2=z, z**3")
    >>> "f1(x&#x27;) = 0.3*x&#x27;" in model_html(model, figure=False)
    True
    """
    esc = html.escape
    parts = ['<div class="charcurves-model" style="font-family:system-ui,sans-serif;font-size:13px">',
             f"<strong>FittedModel</strong> — {esc(str(model.method))} on "
             f"<code>{esc(str(model.template.equation))}</code>", "<ul style='margin:.3em 0'>"]
    parts += [f"<li><code>{esc(line)}</code></li>" for line in curve_lines(model)]
    parts.append("</ul><table style='border-collapse:collapse'>")
    parts += [f"<tr><td style='padding:1px 8px;text-align:left'>{esc(k)}</td>"
              f"<td style='padding:1px 8px;text-align:left'>{esc(v)}</td></tr>"
              for k, v in fit_statistics(model) + output_error_rows(model)]
    parts.append("</table>")
    if figure:
        try:
            png = base64.b64encode(figure_png(model, truth)).decode("ascii")
            parts.append(f'<img alt="the identified curves" src="data:image/png;base64,{png}">')
        except Exception as exc:  # a view must not fail the notebook cell; say why there is no figure
            parts.append(f"<p><em>no figure: {esc(type(exc).__name__)}: {esc(str(exc)[:200])}</em></p>")
    parts.append("</div>")
    return "\n".join(parts)
