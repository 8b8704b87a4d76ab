"""RMSE of identified curves against a known truth (paper Eq. 18)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .._errors import ConfigError

__all__ = ["curve_rmse", "curve_errors"]


def curve_rmse(curve, truth: Callable, *, n: int = 1000, domain=None, align: str = "none") -> float:
    """RMSE of ``curve`` against ``truth`` on ``n`` points spanning the curve's training range.

    ``align``: "none" compares as is (the model's gauge, e.g. f2(0) = 0, already fixes the
    constant); "zero" subtracts each function's value at 0 first; "mean" removes the mean
    difference (the best constant).

    Examples
    --------
    >>> from charcurves.curves import SymbolicFittedCurve
    >>> from charcurves.metrics import curve_rmse
    >>> f2 = SymbolicFittedCurve("f2", "x", (-2.0, 2.0), "1.01*z**3 - z + 0.05")
    >>> round(curve_rmse(f2, lambda z: z**3 - z), 4), round(curve_rmse(f2, lambda z: z**3 - z, align="zero"), 4)
    (0.0585, 0.0303)
    """
    lo, hi = curve.domain if domain is None else domain
    z = np.linspace(lo, hi, n)
    d = np.asarray(curve(z), dtype=float) - np.asarray(truth(z), dtype=float)
    if align == "zero":
        d = d - (float(np.asarray(curve(np.array([0.0])))[0]) - float(np.asarray(truth(np.array([0.0])))[0]))
    elif align == "mean":
        d = d - d.mean()
    elif align != "none":
        raise ConfigError(f"align must be 'none', 'zero' or 'mean', got {align!r}")
    return float(np.sqrt(np.mean(d * d)))


def curve_errors(model, truth: dict[str, Callable], **kwargs) -> dict[str, float]:
    """``{curve name: RMSE}`` for every curve of ``model`` that has a truth.

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.systems import get_system
    >>> system = get_system("duffing")
    >>> model = cc.fit(cc.corrupt(system.simulate(), 20, seed=0), method="parametric", basis="f1=z; f2=z, z**3")
    >>> {name: round(err, 3) for name, err in cc.curve_errors(model, system.true_curves()).items()}
    {'f1': 0.002, 'f2': 0.002}
    """
    return {name: curve_rmse(c, truth[name], **kwargs) for name, c in model.curves.items() if name in truth}
