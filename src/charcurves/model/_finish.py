"""The fitted model a fitter hands back: the template's gauge applied (each curve's value at zero and
the constants moved where the template says) and the data loss computed on the fitted samples."""

from __future__ import annotations

import numpy as np

from .._errors import ConfigError
from ..templates import EquationTemplate
from ._model import FittedModel

__all__ = ["finish_model"]


def finish_model(template: EquationTemplate, method: str, curves: dict, gain: float, offsets: dict, scalars: dict,
                 record, info: dict, mask: np.ndarray | None = None) -> FittedModel:
    """A FittedModel with the template's gauge applied and its data loss (mean squared residual over
    the fitted samples of every equation) computed.

    Examples
    --------
    >>> from charcurves.curves import SymbolicFittedCurve
    >>> from charcurves.model import finish_model
    >>> from charcurves.systems import get_system
    >>> from charcurves.templates import get_template
    >>> record = get_system("duffing").simulate(t_end=10.0, n_points=200)
    >>> curves = {"f1": SymbolicFittedCurve("f1", "x'", (-1, 1), "0.3*z"),
    ...           "f2": SymbolicFittedCurve("f2", "x", (-2, 2), "z**3 - z")}
    >>> model = finish_model(get_template(), "demo", curves, 1.0, {0: 0.0}, {}, record, {})
    >>> model.method, float(round(model.loss, 12)), model.offset  # the true curves: no residual
    ('demo', 0.0, 0.0)
    """
    pinned = {n: c.pinned_at_zero for n, c in curves.items()}
    # a curve may arrive with a shift (output error trains around the equation-error model's gauge, its
    # offsets fitted with those shifts in place): the gauge moves the whole curve, its shift kept in it
    with np.errstate(all="ignore"):  # a basis such as 1/z is infinite at 0: only a gauge there is an error
        raw0 = {n: float(c.raw(np.array([0.0]))[0]) + c.shift if c.shift else float(c.raw(np.array([0.0]))[0])
                for n, c in curves.items()}
        shifts, new_off = template.normalise(raw0, pinned, offsets)
    bad = [n for n in curves if not np.isfinite(shifts.get(n, 0.0))]
    if bad:
        raise ConfigError(f"curve {bad[0]} is not finite at 0 (value {raw0[bad[0]]}), where the gauge anchors it "
                          f"({bad[0]}(0) = 0); give functions that are finite at 0, or anchor another curve (--gauge)")
    for n, c in curves.items():
        c.shift = c.shift + shifts[n] if c.shift else shifts[n]
    scal = dict(scalars)
    for e, v in new_off.items():
        if e > 0:
            scal[f"b{e + 1}"] = float(v)
    info = dict(info)
    if template.is_general:
        info["scalars"] = scal
    info["gauge_conditions"] = template.gauge_conditions(pinned)
    info["gauge_freedoms"] = template.gauge_freedoms(pinned)
    model = FittedModel(template, method, curves, gain, float(new_off.get(0, 0.0)), 0.0, info)
    r = np.asarray(model.force_residual(record))
    if mask is not None:
        r = r[mask]
    model.loss = float(np.mean(r**2))
    return model
