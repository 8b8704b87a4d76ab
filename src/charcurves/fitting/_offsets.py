"""The likely cause the self-check names when a curve's argument lies far from 0 (a record resting
far from its origin, such as a level sensor).

A gauge anchored at 0 outside the data moves no residual, and polynomial, basis and symbolic
curves fit such a range as well as any other (Duffing at 30 dB shifted by 10: poly-cc at 1.01
times its noise floor, as unshifted). Neural curves take their argument as ``z / max|z|`` (the
scaling of :class:`charcurves.curves.Neural`), which squeezes a range far from 0 into a sliver near
1: the same record fits nn-cc at 84.7 times its floor (unshifted 1.01). So the record itself is not
warned about; a fit whose self-check finds a misfit names the offset of every curve argument whose
range does not contain 0, with the fix.
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
        neural = getattr(curve, "kind", "") == "neural"
        warnings.append(
            f"self-check: the argument {curve.argument} of {name} lies in [{lo:.4g}, {hi:.4g}], which does not "
            f"contain 0" + (" (a neural curve sees it squeezed near 1 by its input scale z / max|z|)" if neural else "")
            + f", a likely cause of the misfit; subtract the offset ({curve.argument} - {centre:.4g}) and fit again"
            + (" (or use a polynomial or symbolic representation, which are not affected)" if neural else ""))
    model.info["warnings"] = warnings
