"""The input map of a neural curve: its argument onto a range the network resolves."""

from __future__ import annotations

import numpy as np

__all__ = ["neural_input_map"]


def neural_input_map(z, anchored: bool = False) -> tuple[float, float]:
    """``(center, half_width)`` of a neural curve's input ``u = (z - center) / half_width``.

    A range that contains 0, or a curve that keeps a point at ``z = 0`` (``anchored``: an odd or
    even prior, a jump), is only scaled: ``(0, max|z|)``, so parity stays parity. Any other range is
    mapped onto [-1, 1] by its midpoint and half width: a network fed ``z / max|z|`` of a record
    resting far from 0 (a sensor offset, volts around a bias point) sees a nearly constant input.
    Affine changes of ``z`` then leave ``u`` as it was, so the fit does not depend on the units or
    the offset of the argument.

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.curves import neural_input_map
    >>> neural_input_map(np.array([-2.0, 0.5, 1.0])), neural_input_map(np.array([9.0, 10.0, 11.0]))
    ((0.0, 2.0), (10.0, 1.0))
    >>> neural_input_map(np.array([9.0, 11.0]), anchored=True)  # an odd prior keeps its point 0
    (0.0, 11.0)
    """
    z = np.asarray(z, dtype=float)
    lo, hi = float(np.min(z)), float(np.max(z))
    if anchored or lo <= 0.0 <= hi or not hi > lo:
        return 0.0, max(float(np.max(np.abs(z))), 1e-300)
    return 0.5 * (lo + hi), 0.5 * (hi - lo)
