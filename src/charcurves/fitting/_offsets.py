"""The likely cause the self-check names when a curve's argument lies far from 0 (a record resting
far from its origin, such as a level sensor).

A gauge anchored at 0 outside the data moves no residual, and every representation fits such a
range as well as any other: polynomial, basis and symbolic curves by their own centring, neural
curves by the input map of :func:`charcurves.curves.neural_input_map` (midpoint and half width of
a range without 0: Duffing at 20 dB on F shifted by 10, nn-cc at 1.06 / 1.35 times the unshifted
f1 / f2 error). So the record itself is not warned about; a fit whose self-check finds a misfit
names the offset of every curve argument whose range does not contain 0, with the fix.
"""

from __future__ import annotations

__all__ = ["name_offset_in_warnings"]


def name_offset_in_warnings(model) -> None:
    """Append, when the self-check warned, one line per curve whose data range excludes 0."""
    warnings = list(model.info.get("warnings") or [])
    if not any(isinstance(w, str) and w.startswith("self-check:") for w in warnings):
        return
    for name, curve in model.curves.items():
        lo, hi = (float(v) for v in curve.domain)
        if lo <= 0.0 <= hi:
            continue
        centre = 0.5 * (lo + hi)
        head = f"self-check: the argument {curve.argument} of {name} lies in ["
        if any(isinstance(w, str) and w.startswith(head) for w in warnings):
            continue  # named already (a default fit tests its priors with fits that name it too)
        warnings.append(
            f"self-check: the argument {curve.argument} of {name} lies in [{lo:.4g}, {hi:.4g}], which does not "
            f"contain 0, a likely cause of the misfit; subtract the offset ({curve.argument} - {centre:.4g}) and fit again")
    model.info["warnings"] = warnings
