"""What the command line prints of an output-error fit: the refinement's summary and the closed form."""

from __future__ import annotations

from ._display import display_expression

__all__ = ["closed_form_text", "summary_lines"]


def closed_form_text(model, digits: int = 6) -> str:
    """``x'' + f1(x') + f2(x) + b = g F`` with the closed forms written out (separable family), to
    ``digits`` significant digits; a term that changes no printed digit of its curve over the curve's
    range is left out (:func:`display_expression`).

    Examples
    --------
    >>> from charcurves.curves import SymbolicFittedCurve
    >>> from charcurves.fitting import FittedModel, closed_form_text
    >>> from charcurves.templates import get_template
    >>> curves = {"f1": SymbolicFittedCurve("f1", "x'", (-1, 1), "0.3*z"),
    ...           "f2": SymbolicFittedCurve("f2", "x", (-2, 2), "z**3 - z")}
    >>> closed_form_text(FittedModel(get_template(), "demo", curves, gain=1.0, offset=0.0, loss=0.0), digits=3)
    "x'' + 0.3*x' + (x**3 - x) + 0 = 1*F"
    >>> curves["f1"] = SymbolicFittedCurve("f1", "x'", (-99, 99), "41.7279*z + 7.5452e-37*tanh(3.76e-38*z)")
    >>> closed_form_text(FittedModel(get_template(), "demo", curves, gain=1.0, offset=0.0, loss=0.0), digits=3)
    "x'' + 41.7*x' + (x**3 - x) + 0 = 1*F"
    """
    import sympy as sp

    parts = []
    for name, arg in (("f1", "x'"), ("f2", "x")):
        curve = model.curves[name]
        expr = curve.expression()
        if expr is not None:  # terms that change no printed digit over the curve's range are left out
            expr = display_expression(expr, getattr(curve, "domain", None), digits=digits)
        text = "?" if expr is None else str(sp.N(expr, digits)).replace("z", arg)
        parts.append(f"({text})" if expr is not None and len(sp.Add.make_args(sp.expand(expr))) > 1 else text)
    sign = "-" if model.offset < 0 else "+"
    return f"x'' + {parts[0]} + {parts[1]} {sign} {abs(model.offset):.{digits}g} = {model.gain:.{digits}g}*F"


def summary_lines(model) -> list[str]:
    """Lines for the CLI summary describing ``model.info["output_error"]``.

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.fitting import summary_lines
    >>> from charcurves.systems import get_system
    >>> record = cc.corrupt(get_system("duffing").simulate(t_end=20.0, n_points=500), 30, on="state", seed=0)
    >>> model = cc.fit(record, method="parametric", basis="f1=z; f2=z, z**3", objective=cc.OutputError(segment_length=16, substeps=1, max_iter=2))
    >>> print(summary_lines(model)[0])
    output-error refinement (hold linear, 1 RK4 step per sample, 33 segments of 16 samples; 2 iterations, status ok):
    """
    oe = model.info.get("output_error", {})
    if not oe:
        return []
    if not oe.get("status", "").startswith(("ok", "interrupted")):
        return [f"output error: {oe.get('status')}"]
    how = (f"hold {oe['hold']}, {oe['substeps']} RK4 step{'s' if oe['substeps'] > 1 else ''} per sample, "
           f"{oe['segments']} segment{'s' if oe['segments'] > 1 else ''} of {oe['segment_length']} samples")
    lines = [f"output-error refinement ({how}; {oe['iterations']} iterations, status {oe['status']}):",
             f"  RMSE of the segments' free runs against the measured positions {oe['segmented_rmse_before']:.4g} -> "
             f"{oe['segmented_rmse_after']:.4g}"]
    if oe.get("free_run_rmse_after") is not None:
        lines.append(f"  RMSE of one free run of the whole record {oe['free_run_rmse_before']:.4g} -> "
                     f"{oe['free_run_rmse_after']:.4g}")
    if not model.template.is_general and model.is_symbolic:
        lines.append("  closed form: " + closed_form_text(model))
    return lines
