"""What a gauge anchored outside a curve's data means for the fitted constants."""

from __future__ import annotations

__all__ = ["anchor_notes"]


def anchor_notes(model) -> list[str]:
    """One line per anchored curve (``f(0) = 0`` of the gauge) whose data range excludes 0.

    The anchor keeps its point 0 (it is the template's convention), so the curve's value there is an
    extrapolation of the fit and the constant it hands to the free constant (or another curve) is a
    convention too; the curve's shape on its data is not affected.

    Examples
    --------
    >>> import numpy as np
    >>> import charcurves as cc
    >>> from charcurves.model import anchor_notes
    >>> from charcurves.systems import get_system
    >>> record = get_system("duffing").simulate()
    >>> model = cc.fit(record.replace(x=np.asarray(record.x) + 10.0), method="poly-cc")
    >>> anchor_notes(model)  # doctest: +ELLIPSIS
    ['f2(x) is anchored at x = 0 (f2(0) = 0), outside its data [8.50..., 11.4...]: its value there is extrapolated, so the constant it moves elsewhere is a convention; compare f2 up to a constant']
    """
    settings = model.info.get("settings") if isinstance(getattr(model, "info", None), dict) else None
    gauge = (settings or {}).get("gauge") or ()
    out = []
    for name in gauge:
        curve = model.curves.get(name)
        if curve is None:
            continue
        lo, hi = (float(v) for v in curve.domain)
        if lo <= 0.0 <= hi:
            continue
        out.append(f"{name}({curve.argument}) is anchored at {curve.argument} = 0 ({name}(0) = 0), outside its data "
                   f"[{lo:.4g}, {hi:.4g}]: its value there is extrapolated, so the constant it moves elsewhere is a "
                   f"convention; compare {name} up to a constant")
    return out
