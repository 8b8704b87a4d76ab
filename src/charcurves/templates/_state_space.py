"""State-space templates with hidden states: which states a sensor sees, and what the others add.

``StateSpace("x1' = g*F - f1(x1); x2' = f1(x1) - f2(x2)", measured={"x2": "x"})`` is a template of
first-order (or second-order) state equations, one per state, parsed and checked token by token
like every :class:`~charcurves.templates.Equation`. ``measured`` maps the measured states to record
columns; every other state is *hidden*: it has no data, its initial value is a parameter of output
error, and it may add gauge freedoms that the analysis here finds and fixes:

* **offset** of a hidden state ``h`` (``h -> h + d``): absorbed when every occurrence of ``h`` is in
  a curve argument with a constant slope in ``h`` (the curve's argument shifts), or a term of the
  known part linear in ``h`` whose equation has a curve that can carry the constant. Fixed by
  anchoring the carrying curves at 0 (``f(0) = 0``) when there are any, else by the hidden state's
  initial value (``initial``, default 0: a record that starts at rest).
* **scale** of a hidden state (``h -> c h``): absorbed when ``h``'s own equation can be multiplied
  by ``c`` (its curves occur in no other equation, its known part is linear in ``h``, its input has a
  free gain of its own) and ``h`` appears elsewhere only as the argument ``k*h`` of curves. Fixed by
  holding the gain at its value; without a free gain it is refused (IdentifiabilityError).

A hidden state that reaches no measured state's equation (directly or through other hidden
states) cannot be identified and is refused. The analysis is structural (sympy on the parsed
equations); it does not prove local identifiability of the curves' shapes.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Mapping

from .._errors import ConfigError, IdentifiabilityError
from ._families import Equation
from ._parse import STATE
from ._structure import EquationTemplate

__all__ = ["StateSpace", "HiddenAnalysis", "parse_measured"]

_GAIN = re.compile(r"\bg\s*\*\s*(?=F\d*\b)")


def parse_measured(measured) -> dict[str, str]:
    """``{"x2": "x"}`` or the CLI's ``"x2=x,x3=y"`` -> a dict state -> record column.

    Examples
    --------
    >>> from charcurves.templates import parse_measured
    >>> parse_measured("x2=x, x1=y")
    {'x2': 'x', 'x1': 'y'}
    """
    if isinstance(measured, str):
        out = {}
        for part in (p.strip() for p in measured.split(",")):
            if not part:
                continue
            state, sep, column = (s.strip() for s in part.partition("="))
            if not sep or not state or not column:
                raise ConfigError(f"--measured {measured!r}: write state=column pairs, e.g. --measured x2=x")
            if state in out:  # the last would win silently
                raise ConfigError(f"--measured {measured!r} names the state {state} twice; give each state one column")
            out[state] = column
        measured = out
    if not isinstance(measured, Mapping) or not measured:
        raise ConfigError("measured must name at least one measured state and its column, e.g. measured={'x2': 'x'}")
    return {str(k): str(v) for k, v in measured.items()}


@dataclasses.dataclass(frozen=True)
class HiddenAnalysis:
    """What a state-space template's hidden states add (see the module docstring).

    Attributes
    ----------
    measured : dict
        Measured state -> record column.
    hidden : tuple of str
        The hidden states.
    anchored : tuple of str
        Curves anchored at 0 (``f(0) = 0``) to fix a hidden state's offset.
    fixed_initial : dict
        Hidden state -> its initial value held fixed (fixes its offset).
    gain_fixed : bool
        The gain is held at its value (it fixes a hidden state's scale).
    freedoms : tuple of str
        Each gauge freedom of a hidden state and how it is fixed (reported in results).

    Examples
    --------
    >>> from charcurves.templates import StateSpace
    >>> analysis = StateSpace("x1' = g*F - f1(x1); x2' = f2(x1) - f3(x2)", measured="x2=x").analysis()
    >>> analysis.gain_fixed, analysis.freedoms[1]
    (True, 'the scale of hidden x1 trades with the gain g; fixed by g = 1')
    """

    measured: dict
    hidden: tuple
    anchored: tuple
    fixed_initial: dict
    gain_fixed: bool
    freedoms: tuple


class StateSpace(Equation):
    """A template of state equations with measured and hidden states.

    Parameters
    ----------
    equation : str
        One equation per state separated by ``;``, each with its state's highest derivative, e.g.
        ``"x1' = g*F - f1(x1); x2' = f1(x1) - f2(x2)"``. ``g*F`` asks for a free input gain (as
        ``free_gain=True``). States are ``x1, x2, ...``; curves ``f1, f2, ...``; scalars ``a1, ...``.
    measured : dict or str
        Measured state -> record column (``{"x2": "x"}``, or ``"x2=x"`` as on the command line).
        Every other state is hidden.
    initial : dict, optional
        Initial values of hidden states whose offset is fixed by it (default 0).
    **curves
        A representation per curve (``f1=Polynomial(degree=6)``); unset ones take the fitter's default.

    Examples
    --------
    >>> from charcurves.templates import StateSpace
    >>> tanks = StateSpace("x1' = g*F - f1(x1); x2' = f1(x1) - f2(x2)", measured={"x2": "x"})
    >>> analysis = tanks.analysis()
    >>> analysis.hidden, analysis.fixed_initial
    (('x1',), {'x1': 0.0})
    >>> analysis.freedoms[0]
    'the offset of hidden x1 moves the argument of f1; fixed by x1(t0) = 0'
    """

    family = "state-space"

    def __init__(self, equation: str, *, measured=None, initial=None, gain: float = 1.0, free_gain: bool = False,
                 gauge=None, **curves):
        text = str(equation)
        if _GAIN.search(text):
            text, free_gain = _GAIN.sub("", text), True
        if re.search(r"\bg\b", text):
            raise ConfigError(f"the gain g must multiply a forcing (g*F) in {str(equation).strip()!r}; "
                              "write e.g. \"x1' = g*F - f1(x1)\"")
        super().__init__(text, gain=gain, free_gain=free_gain, gauge=gauge, **curves)
        self.written = str(equation)
        self.measured = measured
        self.initial = initial

    def _names(self) -> list[str]:
        return [*super()._names(), "measured", "initial"]

    def structure(self) -> _Structure:
        structure = _Structure(self.equation_text(), family="state-space", free_gain=bool(self.free_gain),
                               gain=self.gain, gauge=self.gauge)
        extra = sorted(set(self._curve_keys) - set(structure.curve_names))
        if extra:
            raise ConfigError(f"the equation has curves {', '.join(structure.curve_names)}, but a representation was "
                              f"given for {', '.join(extra)}; drop it or use it in the equation")
        # what a model file needs to rebuild the template (EquationTemplate.to_dict writes it)
        structure.state_space = {"written": self.written, "measured": parse_measured(self.measured) if self.measured
                                 else {}, "initial": {str(k): float(v) for k, v in (self.initial or {}).items()},
                                 "asked_gauge": self.gauge}
        return structure

    @classmethod
    def from_dict(cls, doc: dict) -> StateSpace:
        """The template a model file's ``template`` object describes (what :meth:`structure` wrote)."""
        return cls(doc["written"], measured=doc["measured"], initial=doc.get("initial") or None,
                   gain=doc.get("gain", 1.0), free_gain=bool(doc.get("free_gain", False)), gauge=doc.get("asked_gauge"))

    def analysis(self, pinned: Mapping[str, bool] | None = None, structure=None) -> HiddenAnalysis:
        """Measured and hidden states and the gauges of the hidden ones (module docstring); raises
        ConfigError / IdentifiabilityError with the fix. ``pinned``: curves whose representation
        has no constant (an odd polynomial, a basis without 1); ``structure``: :meth:`structure`, if
        already parsed."""
        from ._forward import ForwardModel

        structure = structure or self.structure()
        fm = ForwardModel(structure)
        measured = parse_measured(self.measured)
        states = structure.states
        for s in measured:
            if not STATE.match(s) or s not in states:
                raise ConfigError(f"measured names {s!r}, which is not a state of the template; the states are "
                                  f"{', '.join(states)}")
        hidden = tuple(s for s in states if s not in measured)
        initial = {str(k): float(v) for k, v in (self.initial or {}).items()}
        bad = sorted(set(initial) - set(hidden))
        if bad:
            raise ConfigError(f"initial names {', '.join(bad)}, which {'is' if len(bad) == 1 else 'are'} not a hidden "
                              f"state; the hidden states are {', '.join(hidden) or 'none'}")
        return _analyse(structure, fm, measured, hidden, initial, dict(pinned or {}))


class _Structure(EquationTemplate):
    """The parsed state-space template; its ``to_dict`` (what a model file holds) adds the text as
    written, the measured map and the hidden initial values, which :meth:`StateSpace.from_dict` reads."""

    state_space: dict = {}

    def to_dict(self) -> dict:
        return {**super().to_dict(), **self.state_space}


def _uses(expr, state: str) -> bool:
    import sympy as sp

    names = {s.name for s in sp.sympify(expr).free_symbols}
    return any(n == state or n.startswith(f"{state}__d") for n in names)


def _has(expr, name: str) -> bool:
    import sympy as sp

    return any(s.name == name for s in sp.sympify(expr).free_symbols)


def _reach(structure, fm, measured, hidden) -> None:
    """Refuse a hidden state whose value no measured state's equation feels."""
    import numpy as np

    A_inv = np.asarray(fm.A_inv) if fm.A_inv is not None else np.ones((1, 1))
    states = list(structure.states)
    drives: dict[str, set] = {s: set() for s in states}  # h -> states whose equations read h
    for e, eq in enumerate(structure.equations):
        parts = [eq.known, eq.input, *eq.curves.values(), *eq.scalars.values(),
                 *(structure.argument_exprs[n] for n in eq.curves)]
        for h in states:
            if any(_uses(p, h) for p in parts):
                for j, s in enumerate(states):
                    if abs(A_inv[j, e]) > 0 and s != h:
                        drives[h].add(s)
    for h in hidden:
        seen, todo = {h}, [h]
        while todo:
            for nxt in drives[todo.pop()]:
                if nxt not in seen:
                    seen.add(nxt)
                    todo.append(nxt)
        if not seen & set(measured):
            raise IdentifiabilityError(f"the hidden state {h} enters no equation of a measured state (directly or "
                                       f"through other hidden states), so it cannot be identified; measure {h} or "
                                       "drop it from the template")


def _analyse(structure, fm, measured, hidden, initial, pinned) -> HiddenAnalysis:
    import sympy as sp

    _reach(structure, fm, measured, hidden)
    anchored: list[str] = []
    fixed: dict[str, float] = {}
    freedoms: list[str] = []
    gain_fixed = False
    eqs = structure.equations
    for h in hidden:
        hs = sp.Symbol(h, real=True)
        # ---- offset: h -> h + d
        movers, carriers, ok = [], [], True
        for e, eq in enumerate(eqs):
            if _has(eq.input, h) or any(_has(m, h) for m in eq.curves.values()):
                ok = False
            # the known part and the scalars' signals: linear in h, their constant carried by a curve
            slopes = [sp.diff(eq.known, hs), *(sp.diff(sig, hs) for sig in eq.scalars.values())]
            dk = next((d for d in slopes if d != 0), sp.Integer(0))
            if dk != 0:
                if any(d.free_symbols for d in slopes):
                    ok = False
                else:
                    carry = [n for n, m in eq.curves.items() if not sp.sympify(m).free_symbols
                             and not pinned.get(n, False)]
                    if not carry:
                        ok = False
                    carriers += [n for n in carry if n not in carriers]
        for n in structure.curve_names:
            u = structure.argument_exprs[n]
            if _has(u, h):
                du = sp.diff(u, hs)
                if du.free_symbols:
                    ok = False
                elif pinned.get(n, False):
                    ok = False  # an anchored curve of h fixes h's offset itself
                else:
                    movers.append(n)
        if ok and (movers or carriers):
            if carriers:
                anchored += [n for n in carriers if n not in anchored]
                fix = " and ".join(f"{n}(0) = 0" for n in carriers)
                what = "the constants of " + " and ".join(carriers)
                if movers:
                    what += " and the argument of " + " and ".join(movers)
            else:
                fixed[h] = float(initial.get(h, 0.0))
                fix = f"{h}(t0) = {fixed[h]:g}"
                what = "the argument of " + " and ".join(movers)
            freedoms.append(f"the offset of hidden {h} moves {what}; fixed by {fix}")
        # ---- scale: h -> c h
        if _scale_free(structure, fm, h, hs):
            if structure.free_gain:
                gain_fixed = True
                freedoms.append(f"the scale of hidden {h} trades with the gain g; fixed by g = {structure.gain:g}")
            else:
                raise IdentifiabilityError(
                    f"the scale of the hidden state {h} trades with the curves of its equation (h -> c*h leaves the "
                    f"measured output unchanged); give {h}'s equation a known term or a fixed gain (g*F with g "
                    "fixed), or measure it")
    return HiddenAnalysis(dict(measured), tuple(hidden), tuple(anchored), fixed, gain_fixed, tuple(freedoms))


def _scale_free(structure, fm, h, hs) -> bool:
    """Whether ``h -> c h`` can be absorbed (module docstring; conservative: False when unsure)."""
    import numpy as np
    import sympy as sp

    A = np.asarray(fm.A)
    j = list(structure.states).index(h)
    own = [e for e in range(A.shape[0]) if A[e, j] != 0]
    if len(own) != 1 or np.count_nonzero(A[own[0]]) != 1:
        return False
    e_h = own[0]
    c = sp.Symbol("c_scale", positive=True)
    eq_h = structure.equations[e_h]
    sub = {s: c * s for s in sp.sympify(eq_h.known).free_symbols if s.name == h or s.name.startswith(f"{h}__d")}
    if sp.expand(sp.sympify(eq_h.known).subs(sub) - c * eq_h.known) != 0:
        return False
    for n in eq_h.curves:
        if any(n in eq.curves for k, eq in enumerate(structure.equations) if k != e_h):
            return False

    def homogeneous(sig) -> bool:  # s(c h) = c s(h)
        sig = sp.sympify(sig)
        hs_ = {v: c * v for v in sig.free_symbols if v.name == h or v.name.startswith(f"{h}__d")}
        return sp.expand(sig.subs(hs_) - c * sig) == 0

    where = {a: [k for k, eq in enumerate(structure.equations) if a in eq.scalars] for a in structure.scalar_names}
    for a, sig in eq_h.scalars.items():  # a*s(h) scales with h; a*s (s without h) needs a to absorb c
        if not (homogeneous(sig) if _uses(sig, h) else where[a] == [e_h]):
            return False
    if eq_h.input != 0:
        if not structure.free_gain or any(eq.input != 0 for k, eq in enumerate(structure.equations) if k != e_h):
            return False
    for k, eq in enumerate(structure.equations):
        if k == e_h:
            continue
        if _uses(eq.known, h) or _uses(eq.input, h) or any(_uses(m, h) for m in eq.curves.values()):
            return False
        for a, sig in eq.scalars.items():  # a*s(h) elsewhere: a -> a/c absorbs the scale
            if _uses(sig, h) and not (homogeneous(sig) and where[a] == [k]):
                return False
    for n in structure.curve_names:
        u = structure.argument_exprs[n]
        if _uses(u, h) and sp.simplify(u / hs).free_symbols:
            return False
    return True
