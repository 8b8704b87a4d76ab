"""``--truth`` of another system than the record's is said, not used without a word (issue 50)."""

from __future__ import annotations

import numpy as np

__all__ = ["FIT_AT_FLOOR", "TRUTH_MISMATCH", "truth_mismatch"]

#: a fit whose loss is at most this many times its noise floor describes the record (the self-check)
FIT_AT_FLOOR = 3.0
#: a curve RMSE against the truth above this fraction of the true curve's spread (standard deviation
#: over the curve's range) is not a noisy estimate of that curve but another curve
TRUTH_MISMATCH = 0.5


def truth_mismatch(model, truth: dict, errors: dict[str, float]) -> str | None:
    """One warning line when the fit reaches its noise floor (so its curves are the record's) but
    its curves differ from the truth's by more than :data:`TRUTH_MISMATCH` of their spread: the
    record is then not of the ``--truth`` system. None otherwise (a fit far from its floor is
    already warned about by the self-check)."""
    check = model.info.get("self_check") or {}
    ratios = [float(r) for r in check.get("loss_over_floor") or []]
    if not ratios or not max(ratios) <= FIT_AT_FLOOR:
        return None
    rel: dict[str, float] = {}
    for name, err in errors.items():
        lo, hi = model.curves[name].domain
        values = np.asarray(truth[name](np.linspace(lo, hi, 1000)), dtype=float)
        spread = float(np.std(values))
        if spread > 0 and np.isfinite(err):
            rel[name] = float(err) / spread
    bad = {k: v for k, v in rel.items() if v > TRUTH_MISMATCH}
    if not bad:
        return None
    shown = ", ".join(f"{k} {v:.2g}" for k, v in bad.items())
    return (f"the fit reaches its noise floor (loss {max(ratios):.3g} times it), but its curves differ from those of "
            f"--truth by {shown} times the true curve's spread: the record is probably not of that system; check "
            "--truth and --truth-variant (curve_rmse compares with it all the same)")
