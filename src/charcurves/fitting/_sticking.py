"""The samples each record fits: the sticking phases of dry friction left out."""

from __future__ import annotations

import numpy as np

from ..templates import ESTIMATED_STICK_TOL, EquationTemplate, sticking_mask

__all__ = ["sticking_masks"]


def sticking_masks(records, template: EquationTemplate, estimated: list[bool], *, exclude: bool, kind: str,
                   stick_tol="default") -> list[np.ndarray]:
    """The samples each record fits: sticking phases (x' = 0 over a run) left out for dry friction.

    The |x'| threshold is exact zeros for given derivatives and ESTIMATED_STICK_TOL (5 %) of max|x'|
    for estimated ones (see :func:`~charcurves.templates.sticking_mask` for the rest of the test);
    symbolic fits look for exact zeros first and then 5 %. Multi-DOF records
    and templates without a velocity curve keep every sample.
    """
    out = []
    for rec, est in zip(records, estimated):
        n = rec.n_samples
        if not exclude or not template.velocity_curves or getattr(rec, "v", None) is None:
            out.append(np.ones(n, bool))
            continue
        if stick_tol != "default":
            stuck = sticking_mask(rec, rel_tol=None if stick_tol is None else float(stick_tol))
        elif kind == "symbolic":
            stuck = sticking_mask(rec, rel_tol=None)
            if not stuck.any():
                stuck = sticking_mask(rec, rel_tol=ESTIMATED_STICK_TOL)
        else:
            stuck = sticking_mask(rec, rel_tol=ESTIMATED_STICK_TOL if est else None)
        out.append(~stuck)
    return out
