"""The curve zoo (issue 46, item 1): curves practitioners meet, placed in the curve slots of every
family, each with its closed form, the argument range a simulated record excites and its parity.

A zoo *curve* is ``sum_k c_k g_k(z)``: coefficients ``c_k`` on closed-form terms ``g_k`` (sympy text
in ``z``, the Parametric basis of the limit) and, independently written, a NumPy function of the
same curve (``fn``; tests/test_zoo.py checks that the two agree). A zoo *system* is a family, its
truth curves, a forcing (sums of cosines) and an initial state (a
:class:`charcurves.systems.CurveSystem`); a *row* of the zoo is a (system, slot) whose curve is
scored. Each system, with its rows, belongs to one half: ``tuning`` (where later default changes
may be chosen) or ``report`` (where they are judged). The halves alternate through the list of
systems, so that each half holds every family and kind of shape; the assignment is fixed here
(``SYSTEM_HALF``) and never recomputed.

Run the benchmark with ``benchmarks/bench_zoo.py``; docs/zoo.md shows its committed results.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

__all__ = ["ZooCurve", "ZooSystem", "CURVES", "SYSTEMS", "ROWS", "get_system", "basis_option", "HALF", "SYSTEM_HALF"]


@dataclasses.dataclass(frozen=True)
class ZooCurve:
    """One true curve: ``sum(c * g(z) for c, g in terms)``, also as the NumPy function ``fn``."""

    key: str
    kind: str
    terms: tuple[tuple[float, str], ...]
    fn: Callable[[np.ndarray], np.ndarray]
    parity: str  # "odd", "even" or "none"
    span: tuple[float, float]  # argument range the record must cover
    polynomial: bool = False

    def text(self) -> str:
        """The closed form, e.g. ``0.2*z + 0.15*z*Abs(z)``."""
        def term(c: float, g: str) -> str:
            if g == "1":
                return f"{c:g}"
            g = f"({g})" if (" + " in g or " - " in g) else g
            return g if c == 1 else f"-{g}" if c == -1 else f"{c:g}*{g}"

        return " + ".join(term(c, g) for c, g in self.terms).replace("+ -", "- ")

    def basis(self) -> str:
        return ", ".join(g for _, g in self.terms)


def _ramp(u, eps):
    """A smooth ramp max(u, 0) (hyperbolic: (u + sqrt(u^2 + eps^2)) / 2)."""
    return 0.5 * (u + np.sqrt(u * u + eps * eps))


def _c(key, kind, terms, fn, parity, span, polynomial=False):
    return ZooCurve(key, kind, tuple(terms), fn, parity, span, polynomial)


CURVES: dict[str, ZooCurve] = {c.key: c for c in [
    # ---- damping curves f1(x') (odd unless said) ----
    _c("drag", "quadratic drag v|v|", [(0.2, "z"), (0.15, "z*Abs(z)")],
       lambda v: 0.2 * v + 0.15 * v * np.abs(v), "odd", (-1.5, 1.5)),
    _c("tanh-friction", "saturation tanh (smooth Coulomb)", [(0.1, "z"), (0.5, "tanh(3*z)")],
       lambda v: 0.1 * v + 0.5 * np.tanh(3 * v), "odd", (-1.2, 1.2)),
    _c("atan-damper", "saturation atan", [(0.05, "z"), (0.6, "atan(2*z)")],
       lambda v: 0.05 * v + 0.6 * np.arctan(2 * v), "odd", (-1.2, 1.2)),
    _c("stribeck", "Stribeck (smooth, no sticking)", [(0.1, "z"), (0.3, "tanh(4*z)"), (0.3, "tanh(4*z)*exp(-4*z**2)")],
       lambda v: 0.1 * v + np.tanh(4 * v) * (0.3 + 0.3 * np.exp(-4 * v * v)), "odd", (-1.2, 1.2)),
    _c("sqrt-damper", "square-root law sign(v)|v|^0.5", [(0.1, "z"), (0.25, "sign(z)*sqrt(Abs(z))")],
       lambda v: 0.1 * v + 0.25 * np.sign(v) * np.sqrt(np.abs(v)), "odd", (-1.2, 1.2)),
    _c("power-damper", "power law sign(v)|v|^1.5", [(0.05, "z"), (0.2, "z*sqrt(Abs(z))")],
       lambda v: 0.05 * v + 0.2 * np.sign(v) * np.abs(v) ** 1.5, "odd", (-1.5, 1.5)),
    _c("asym-damper", "asymmetric damper (kink at 0)", [(0.2, "z"), (0.1, "Abs(z)")],
       lambda v: np.where(v > 0, 0.3 * v, 0.1 * v), "none", (-1.0, 1.0)),
    _c("clipped-damper", "clipped saturation (kinks)", [(0.1, "z"), (0.5, "Abs(2*z + 0.6) - Abs(2*z - 0.6)")],
       lambda v: 0.1 * v + np.clip(2 * v, -0.6, 0.6), "odd", (-1.0, 1.0)),
    _c("cubic-damper", "cubic damping (polynomial truth)", [(0.1, "z"), (0.05, "z**3")],
       lambda v: 0.1 * v + 0.05 * v**3, "odd", (-1.5, 1.5), True),
    _c("softclip-damper", "soft clip v/sqrt(1+4v^2)", [(0.05, "z"), (0.5, "z/sqrt(1 + 4*z**2)")],
       lambda v: 0.05 * v + 0.5 * v / np.sqrt(1 + 4 * v * v), "odd", (-1.2, 1.2)),
    _c("expsat-damper", "exponential saturation", [(0.15, "z"), (0.3, "sign(z)*(1 - exp(-3*Abs(z)))")],
       lambda v: 0.15 * v + 0.3 * np.sign(v) * (1 - np.exp(-3 * np.abs(v))), "odd", (-1.2, 1.2)),
    _c("linear-damper", "linear (viscous)", [(0.2, "z")], lambda v: 0.2 * v, "odd", (-1.5, 1.5), True),
    # ---- spring curves f2(x) (f2(0) = 0, the separable gauge) ----
    _c("tanh-spring", "saturating spring tanh", [(0.2, "z"), (2.0, "tanh(z)")],
       lambda x: 0.2 * x + 2 * np.tanh(x), "odd", (-1.5, 1.5)),
    _c("duffing-spring", "Duffing double well (polynomial truth)", [(-1.0, "z"), (1.0, "z**3")],
       lambda x: x**3 - x, "odd", (-1.4, 1.4), True),
    _c("asym-spring", "asymmetric spring 4x + 1.5x^2", [(4.0, "z"), (1.5, "z**2")],
       lambda x: 4 * x + 1.5 * x * x, "none", (-0.6, 0.6), True),
    _c("hardening-spring", "hardening cubic (polynomial truth)", [(1.0, "z"), (0.5, "z**3")],
       lambda x: x + 0.5 * x**3, "odd", (-1.5, 1.5), True),
    _c("softening-spring", "softening x - 0.1x^3", [(1.0, "z"), (-0.1, "z**3")],
       lambda x: x - 0.1 * x**3, "odd", (-1.3, 1.3), True),
    _c("pendulum", "periodic (pendulum sin x)", [(2.0, "sin(z)")],
       lambda x: 2 * np.sin(x), "odd", (-1.8, 1.8)),
    _c("deadzone-spring", "dead zone (smoothed clearance 0.5)",
       [(0.2, "z"), (2.0, "z + sqrt((z - 0.5)**2 + 0.0025)/2 - sqrt((z + 0.5)**2 + 0.0025)/2")],
       lambda x: 0.2 * x + 2 * (_ramp(x - 0.5, 0.05) - _ramp(-x - 0.5, 0.05)), "odd", (-1.2, 1.2)),
    _c("stops-spring", "piecewise-linear stops at +-0.6", [(1.0, "z"), (3.0, "z + Abs(z - 0.6)/2 - Abs(z + 0.6)/2")],
       lambda x: x + 3 * (x - np.clip(x, -0.6, 0.6)), "odd", (-1.0, 1.0)),
    _c("sinh-spring", "exponential hardening sinh", [(0.5, "sinh(2*z)")],
       lambda x: 0.5 * np.sinh(2 * x), "odd", (-1.0, 1.0)),
    _c("one-sided-stop", "one-sided stop (backlash-like kink at 0.4)", [(1.0, "z"), (1.5, "z + Abs(z - 0.4) - 0.4")],
       lambda x: x + 3 * np.maximum(x - 0.4, 0.0), "none", (-1.0, 0.8)),
    _c("hertz-spring", "power law x|x|^0.5 (Hertz)", [(1.0, "z"), (0.5, "z*sqrt(Abs(z))")],
       lambda x: x + 0.5 * np.sign(x) * np.abs(x) ** 1.5, "odd", (-1.5, 1.5)),
    _c("exp-spring", "asymmetric exponential hardening", [(1.0, "z"), (0.3, "exp(1.5*z) - 1")],
       lambda x: x + 0.3 * np.expm1(1.5 * x), "none", (-1.0, 1.0)),
    # ---- position-damping f1(x) (multiplies x') ----
    _c("vdp-damping", "Van der Pol mu(x^2 - 1) (polynomial truth)", [(-1.0, "1"), (1.0, "z**2")],
       lambda x: x * x - 1, "even", (-1.8, 1.8), True),
    _c("gauss-damping", "position damping 0.6 - 0.5 exp(-2x^2)", [(0.6, "1"), (-0.5, "exp(-2*z**2)")],
       lambda x: 0.6 - 0.5 * np.exp(-2 * x * x), "even", (-1.2, 1.2)),
    _c("abs-spring", "spring x + 0.3x|x|", [(1.0, "z"), (0.3, "z*Abs(z)")],
       lambda x: x + 0.3 * x * np.abs(x), "odd", (-1.5, 1.5)),
    # ---- first-order f1(x) (restoring) and f2(x) (resistance, > 0) ----
    _c("tanh-restoring", "saturating restoring tanh", [(0.3, "z"), (1.0, "tanh(2*z)")],
       lambda x: 0.3 * x + np.tanh(2 * x), "odd", (-1.2, 1.2)),
    _c("tanh-resistance", "asymmetric resistance 0.6 + 0.4 tanh x", [(0.6, "1"), (0.4, "tanh(z)")],
       lambda x: 0.6 + 0.4 * np.tanh(x), "none", (-1.2, 1.2)),
    _c("sinh-restoring", "exponential hardening restoring sinh", [(0.5, "sinh(1.5*z)")],
       lambda x: 0.5 * np.sinh(1.5 * x), "odd", (-1.2, 1.2)),
    _c("cos-resistance", "periodic resistance 0.8 + 0.3 cos 2x", [(0.8, "1"), (0.3, "cos(2*z)")],
       lambda x: 0.8 + 0.3 * np.cos(2 * x), "even", (-1.2, 1.2)),
    # ---- two-dof coupling ----
    _c("drag2", "quadratic drag (second mass)", [(0.2, "z"), (0.1, "z*Abs(z)")],
       lambda v: 0.2 * v + 0.1 * v * np.abs(v), "odd", (-1.0, 1.0)),
]}


@dataclasses.dataclass(frozen=True)
class ZooSystem:
    """A zoo system: a family, its curves (zoo keys by slot), forcing and initial state; ``scored``
    names the slots that are rows of the zoo."""

    name: str
    family: str
    slots: dict[str, str]
    forcing: object
    initial: tuple[float, ...]
    scored: tuple[str, ...] = ("f1", "f2")
    t_end: float = 40.0
    n_points: int = 1000

    def curve(self, slot: str) -> ZooCurve:
        return CURVES[self.slots[slot]]

    def truth(self) -> dict[str, Callable]:
        out = {s: CURVES[k].fn for s, k in self.slots.items()}
        if self.family == "two-dof":  # Newton's third law: the reaction of the coupling spring
            f2 = out["f2"]
            out["f4"] = lambda z, f2=f2: -f2(-np.asarray(z, dtype=float))
        return out

    def curve_system(self):
        from charcurves.systems import CurveSystem

        return CurveSystem(self.family, self.truth(), forcing=self.forcing, initial=self.initial, name=self.name)

    def simulate(self):
        return self.curve_system().simulate(t_end=self.t_end, n_points=self.n_points)

    def all_odd(self) -> bool:
        """Every curve of the system is odd (so the +sym methods' default prior holds)."""
        return all(CURVES[k].parity == "odd" for k in self.slots.values())

    def arguments(self, record) -> dict[str, np.ndarray]:
        """The argument of each scored slot along a clean record."""
        if self.family == "two-dof":
            s, v = record.states, record.velocities
            args = {"f1": v["x1"], "f2": s["x1"] - s["x2"], "f3": v["x2"]}
        elif self.family == "separable":
            args = {"f1": record.v, "f2": record.x}
        else:
            args = {"f1": record.x, "f2": record.x}
        return {k: np.asarray(args[k]) for k in self.scored}


def _two(a1, w1, a2, w2):
    return ((a1, w1), (a2, w2))


SYSTEMS: dict[str, ZooSystem] = {s.name: s for s in [
    ZooSystem("sep-drag-tanh", "separable", {"f1": "drag", "f2": "tanh-spring"}, _two(1.6, 1.0, 0.8, 1.9), (0.0, 0.0)),
    ZooSystem("sep-friction-duffing", "separable", {"f1": "tanh-friction", "f2": "duffing-spring"},
              _two(1.2, 1.1, 0.6, 2.1), (1.0, 0.0)),
    ZooSystem("sep-atan-asym", "separable", {"f1": "atan-damper", "f2": "asym-spring"}, _two(1.5, 1.3, 0.7, 2.9),
              (0.0, 0.0)),
    ZooSystem("sep-stribeck-hardening", "separable", {"f1": "stribeck", "f2": "hardening-spring"},
              _two(1.4, 1.2, 0.7, 2.3), (0.0, 0.0)),
    ZooSystem("sep-sqrt-softening", "separable", {"f1": "sqrt-damper", "f2": "softening-spring"},
              _two(0.45, 0.9, 0.22, 1.7), (0.0, 0.0)),
    ZooSystem("sep-power-pendulum", "separable", {"f1": "power-damper", "f2": "pendulum"}, _two(1.0, 1.1, 0.5, 2.0),
              (0.0, 0.0)),
    ZooSystem("sep-asym-deadzone", "separable", {"f1": "asym-damper", "f2": "deadzone-spring"},
              _two(0.8, 1.0, 0.4, 1.9), (0.0, 0.0)),
    ZooSystem("sep-clipped-stops", "separable", {"f1": "clipped-damper", "f2": "stops-spring"},
              _two(1.2, 1.3, 0.6, 2.4), (0.0, 0.0)),
    ZooSystem("sep-cubic-sinh", "separable", {"f1": "cubic-damper", "f2": "sinh-spring"}, _two(1.2, 1.2, 0.6, 2.2),
              (0.0, 0.0)),
    ZooSystem("sep-softclip-stop", "separable", {"f1": "softclip-damper", "f2": "one-sided-stop"},
              _two(0.8, 1.0, 0.4, 1.8), (0.0, 0.0)),
    ZooSystem("sep-expsat-hertz", "separable", {"f1": "expsat-damper", "f2": "hertz-spring"},
              _two(1.4, 1.1, 0.7, 2.1), (0.0, 0.0)),
    ZooSystem("sep-linear-exp", "separable", {"f1": "linear-damper", "f2": "exp-spring"}, _two(1.0, 1.0, 0.5, 1.9),
              (0.0, 0.0)),
    ZooSystem("pd-vdp-abs", "position-damping", {"f1": "vdp-damping", "f2": "abs-spring"}, _two(1.2, 1.3, 0.6, 2.3),
              (0.5, 0.0)),
    ZooSystem("pd-gauss-tanh", "position-damping", {"f1": "gauss-damping", "f2": "tanh-spring"},
              _two(1.6, 1.0, 0.8, 1.9), (0.0, 0.0)),
    ZooSystem("fo-tanh-tanh", "first-order", {"f1": "tanh-restoring", "f2": "tanh-resistance"},
              _two(1.6, 0.8, 0.8, 2.3), (0.5,)),
    ZooSystem("fo-sinh-cos", "first-order", {"f1": "sinh-restoring", "f2": "cos-resistance"},
              _two(1.6, 0.8, 0.8, 2.3), (0.5,)),
    ZooSystem("2dof-drag-hertz", "two-dof", {"f1": "drag", "f2": "hertz-spring", "f3": "drag2"},
              {"F1": ((1.2, 0.9),), "F2": ((0.8, 1.7),)}, (0.5, 0.0, -0.3, 0.0), t_end=50.0, n_points=1250),
]}

#: The rows of the zoo in a fixed order: (system, slot).
ROWS: tuple[tuple[str, str], ...] = tuple((s.name, slot) for s in SYSTEMS.values() for slot in s.scored)
#: The half of each system (and so of its rows; the curves of one system share its fits): the
#: systems alternate, in the order of SYSTEMS, between the tuning and the report half.
SYSTEM_HALF: dict[str, str] = {name: ("tuning" if i % 2 == 0 else "report") for i, name in enumerate(SYSTEMS)}
HALF: dict[tuple[str, str], str] = {row: SYSTEM_HALF[row[0]] for row in ROWS}


def get_system(name: str) -> ZooSystem:
    return SYSTEMS[name]


def basis_option(system: ZooSystem) -> str:
    """The Parametric basis of the truth (``basis=`` of the limit), e.g. ``"f1=z, z*Abs(z); f2=z, tanh(z)"``;
    two-dof: f4's basis is f2's terms at ``-z``."""
    parts = [f"{slot}={CURVES[key].basis()}" for slot, key in system.slots.items()]
    if system.family == "two-dof":
        terms = [g.replace("z", "(-z)") for _, g in CURVES[system.slots["f2"]].terms]
        parts.append("f4=" + ", ".join(terms))
    return "; ".join(parts)
