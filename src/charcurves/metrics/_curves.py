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
    """``{curve name: RMSE}`` for every curve of ``model`` that has a truth."""
    return {name: curve_rmse(c, truth[name], **kwargs) for name, c in model.curves.items() if name in truth}
