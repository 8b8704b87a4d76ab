"""The separable family x'' + f1(x') + f2(x) + b = g * F (paper Eq. 1, appendix A.1)."""

from __future__ import annotations

import dataclasses

import numpy as np

from .._errors import ConfigError, DataError
from ..data._trajectory import Trajectory

__all__ = ["SeparableTemplate", "get_template", "FAMILY_NAMES", "sticking_mask", "apply_gauge"]

#: Every built-in family ("custom" is a user-written equation, see EquationTemplate).
FAMILY_NAMES = ("separable", "first-order", "position-damping", "two-dof")


@dataclasses.dataclass(frozen=True)
class SeparableTemplate:
    """``x'' + f1(x') + f2(x) + b = g * F``.

    Parameters
    ----------
    free_gain : bool
        Learn the input gain ``g`` (unknown mass or input scaling, as on real records);
        otherwise ``g = gain``.
    gain : float
        The fixed gain (the paper: 1).
    gauge : {"f2", "f1"}
        Which curve is anchored at 0 to fix the constant that f1 and f2 can trade
        (the paper's NN-CC: f2(0) = 0).
    gain_on : {"force", "acceleration"}
        With a free gain, the side of the equation whose measurement carries the noise, used as
        the regression target: "force" fits F = (x'' + f1 + f2 + b) / g (the paper's loss; noise
        on the forcing then does not bias g), "acceleration" fits x'' = g F - f1 - f2 - b (noise
        on the state). Irrelevant when the gain is fixed.
    """

    free_gain: bool = False
    gain: float = 1.0
    gauge: str = "f2"
    gain_on: str = "force"

    family = "separable"
    curve_names = ("f1", "f2")
    #: data column each curve reads
    variables = {"f1": "v", "f2": "x"}
    #: the argument as written in the equation
    arguments = {"f1": "x'", "f2": "x"}

    def __post_init__(self) -> None:
        if self.gauge not in self.curve_names:
            raise ConfigError(f"gauge must name a curve to anchor at 0 (f1 or f2), got {self.gauge!r}")
        if self.gain_on not in ("force", "acceleration"):
            raise ConfigError(f"gain_on must be 'force' or 'acceleration', got {self.gain_on!r}")
        if not np.isfinite(self.gain) or self.gain == 0:
            raise ConfigError(f"the fixed gain must be a finite non-zero number, got {self.gain}")

    @property
    def equation(self) -> str:
        g = "g" if self.free_gain else ("" if self.gain == 1 else f"{self.gain:g}")
        rhs = f"{g}*F" if g else "F"
        return f"x'' + f1(x') + f2(x) = {rhs}"

    def arguments_of(self, traj: Trajectory) -> dict[str, np.ndarray]:
        if not traj.has_derivatives:
            raise DataError("the template needs x' and x''; estimate derivatives first (estimate_derivatives)")
        return {"f1": np.asarray(traj.v), "f2": np.asarray(traj.x)}

    def check_excitation(self, traj: Trajectory) -> None:
        """Refuse records whose curves cannot be identified (a constant state or forcing)."""
        for name, z in self.arguments_of(traj).items():
            if np.ptp(z) <= 1e-12 * max(1.0, float(np.max(np.abs(z)))):
                raise DataError(
                    f"the argument {self.arguments[name]} of {name} is constant over the record, so {name} "
                    "cannot be identified; give a record in which the system moves (excite it)"
                )
        if np.ptp(traj.F) == 0 and np.ptp(traj.a) == 0:
            raise DataError("the forcing and acceleration are constant: the record has no excitation")

    def to_dict(self) -> dict:
        return {"family": self.family, "free_gain": self.free_gain, "gain": self.gain, "gauge": self.gauge,
                "gain_on": self.gain_on}


def get_template(family: str = "separable", *, equation: str | None = None, **kwargs):
    """The template of a family name, or of a user-written ``equation`` (family "custom").

    ``gauge=None`` takes the family's default anchors (separable: f2(0) = 0).
    """
    from ._general import FAMILY_EQUATIONS, EquationTemplate

    if family in FAMILY_EQUATIONS and equation is not None and " ".join(str(equation).split()) == \
            " ".join(FAMILY_EQUATIONS[family].split()):
        equation = None  # a saved family template names its own equation
    if equation is not None and str(equation).strip():
        if family not in ("separable", "custom", None, ""):
            raise ConfigError(f"give either a family ({family!r}) or an equation, not both")
        return EquationTemplate(str(equation), family="custom", **kwargs)
    if family == "separable":
        if kwargs.get("gauge") is None:
            kwargs.pop("gauge", None)
        return SeparableTemplate(**kwargs)
    if family in FAMILY_EQUATIONS:
        return EquationTemplate(FAMILY_EQUATIONS[family], family=family, **kwargs)
    if family == "custom":
        raise ConfigError("the custom family needs an equation, e.g. equation=\"x'' + a1*x' + f1(x) = F\"")
    raise ConfigError(f"unknown family {family!r}; available: {', '.join(FAMILY_NAMES)} "
                      "(or write your own with --equation)")


def sticking_mask(traj: Trajectory, *, rel_tol: float | None = None, min_run: int = 3) -> np.ndarray:
    """Samples where the mass sticks (dry friction): x' = 0 over a run of samples.

    There the friction force is set-valued (any value with |f| <= mu*N), so these samples only
    bound f1 and must not be fitted as points of the curve. ``rel_tol`` is the threshold on
    |x'| relative to max|x'|: exact zeros (1e-12) for given derivatives, 1 % for estimated ones.
    """
    if getattr(traj, "v", None) is None:  # multi-DOF records: sticking is not detected (see docs/families.md)
        return np.zeros(traj.n_samples, dtype=bool)
    v = np.asarray(traj.v)
    if rel_tol is None:
        rel_tol = 1e-12
    thresh = rel_tol * max(float(np.max(np.abs(v))), 1e-300)
    small = np.abs(v) <= thresh
    if not small.any():
        return small
    # keep runs of at least min_run samples (a single crossing of zero is not sticking)
    mask = np.zeros_like(small)
    idx = np.flatnonzero(np.diff(np.concatenate([[0], small.astype(int), [0]])))
    for start, stop in zip(idx[::2], idx[1::2]):
        if stop - start >= min_run:
            mask[start:stop] = True
    return mask


def apply_gauge(raw_at_zero: dict[str, float], pinned: dict[str, bool], bias: float, anchor: str,
                order: tuple[str, ...]) -> tuple[dict[str, float], float]:
    """Shifts per curve and the free constant so that the anchor curve is 0 at 0.

    The anchor curve loses its value at 0; the constant then goes to the first other curve that
    can carry it (not pinned at 0 by exact odd symmetry); when none can, it stays as the
    equation's free constant ``b`` (offsets of real records) and is reported.
    """
    if hasattr(anchor, "apply"):  # a general template's gauge (see templates._general)
        return anchor.apply(raw_at_zero, pinned, bias, order)
    shifts = {name: 0.0 for name in order}
    total = float(bias)
    if not pinned[anchor]:
        shifts[anchor] = -raw_at_zero[anchor]
        total += raw_at_zero[anchor]
    for name in order:
        if name != anchor and not pinned[name]:
            shifts[name] = total
            return shifts, 0.0
    return shifts, total
