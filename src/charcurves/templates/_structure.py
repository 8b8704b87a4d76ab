"""Template structures: equations linear in unknown univariate curves and unknown scalars.

A template is a list of equations, each written as a residual that must vanish::

    known_e(t) + sum_i m_ie(t) f_i(u_i(t)) + sum_j s_je(t) a_j + b_e - g * input_e(t) = 0

with data signals (``x, x', x'', x1 - x2, F, ...``) for the known part, the coefficients ``m_ie``, the curve arguments
``u_i``, the scalar signals ``s_je`` and the input (every term containing a forcing column ``F``, ``F1``...). ``g`` is
the input gain (fixed, or learned with ``free_gain``) and ``b_e`` a free constant that exists only where no curve can
carry it.

Identifiability (the paper's appendix A, generalised):

* a constant ``c_i`` added to curve ``f_i`` changes equation ``e`` by ``c_i m_ie``; the constants the curves can trade
  without changing any residual are the null space of the matrix whose columns are the stacked coefficient signals.
  Each null vector is a *gauge freedom*, fixed by anchoring one curve at 0 (``f(0) = 0``), as the paper does with
  ``f2(0) = 0``;
* a scalar inside such a null vector is not identifiable (it trades with curve constants);
* two curves whose arguments are functions of one another, entering every equation with a coefficient ratio that is
  itself a function of that argument (``f1(x) + f2(x)``), can trade any function: not identifiable. The same holds for
  a scalar whose signal a curve can reproduce (``a1*x`` next to ``f1(x)``).

Signals are compared as functions of independent data symbols (``x`` and ``x'`` are independent coordinates of phase
space, as in appendix A), by evaluating them at random points."""

from __future__ import annotations

from typing import Any

import numpy as np

from .._errors import ConfigError, DataError, IdentifiabilityError
from .._lambdify import numpy_function
from ._parse import (DERIV, FORCE, MAX_TEXT, STATE, ParsedEquation, display, parse_side, raw_arguments,
                     show, sort_key, split_equation)

__all__ = ["EquationTemplate", "FAMILY_EQUATIONS", "FAMILY_ANCHORS", "record_columns", "evaluate_signal"]

#: The built-in families written as equations (curve order = result order).
FAMILY_EQUATIONS = {
    "separable": "x'' + f1(x') + f2(x) = F",
    "first-order": "f1(x) + f2(x)*x' = F",
    "position-damping": "x'' + f1(x)*x' + f2(x) = F",
    "two-dof": "x1'' + f1(x1') + f2(x1 - x2) = F1; x2'' + f3(x2') + f4(x2 - x1) = F2",
}
#: Curves anchored at 0 by default (the paper's f2(0) = 0; appendix A: zero coupling force at equilibrium).
FAMILY_ANCHORS = {"separable": ("f2",), "first-order": (), "position-damping": (), "two-dof": ("f2", "f4")}

class EquationTemplate:
    """A template parsed from equations; see the module docstring for the model it fits.

    Parameters
    ----------
    equation : str
        One or several equations separated by ``;``, e.g. ``"x'' + a1*x' + f1(x) = F"``.
    family : str
        Family name reported in results ("custom" for user-written templates).
    free_gain, gain, gain_on
        As in :class:`~charcurves.templates.Template` (one gain for every input).
    gauge : str or sequence of str, optional
        Curves anchored at 0 to fix the gauge freedoms ("f2" or "f2,f4"); by default one curve
        per freedom is chosen (the highest-numbered curve that can carry it).

    Examples
    --------
    >>> from charcurves.templates import EquationTemplate
    >>> t = EquationTemplate("x'' + f1(x') + f2(x) = F")
    >>> t.curve_names, t.arguments, t.gauge_conditions()
    (('f1', 'f2'), {'f1': "x'", 'f2': 'x'}, ['f2(0) = 0'])
    """

    def __init__(self, equation: str, *, family: str = "custom", free_gain: bool = False, gain: float = 1.0,
                 gauge=None, gain_on: str = "force"):
        import sympy as sp

        if not isinstance(equation, str) or not equation.strip():
            raise ConfigError("the equation is empty; write e.g. \"x'' + f1(x') + f2(x) = F\"")
        if len(equation) > MAX_TEXT:
            raise ConfigError(f"the equation text is {len(equation)} characters long; keep it under {MAX_TEXT}")
        if gain_on not in ("force", "acceleration"):
            raise ConfigError(f"gain_on must be 'force' or 'acceleration', got {gain_on!r}")
        try:
            gain = float(gain)
        except (TypeError, ValueError):
            raise ConfigError(f"the fixed gain must be a number, got {gain!r}") from None
        if not np.isfinite(gain) or gain == 0:
            raise ConfigError(f"the fixed gain must be a finite non-zero number, got {gain}")
        self.text = equation.strip()
        self.family = family
        self.free_gain = bool(free_gain)
        self.gain = gain
        self.gain_on = gain_on
        parts = [p for p in self.text.split(";") if p.strip()]
        if not parts:
            raise ConfigError("the equation is empty; write e.g. \"x'' + f1(x') + f2(x) = F\"")
        arguments: dict[str, Any] = {}
        self.equations: list[ParsedEquation] = []
        for k, part in enumerate(parts, 1):
            where = f"equation {k}" if len(parts) > 1 else "equation"
            if part.count("=") != 1:
                raise ConfigError(f"{where} {part.strip()!r} needs exactly one '=', e.g. \"x'' + f1(x') + f2(x) = F\"")
            lhs_t, rhs_t = part.split("=")
            if not lhs_t.strip() or not rhs_t.strip():
                raise ConfigError(f"{where} {part.strip()!r} has an empty side; write e.g. \"x'' + f1(x) = F\"")
            eq = split_equation(parse_side(lhs_t, where), parse_side(rhs_t, where), where, arguments)
            if eq.known == 0 and eq.input == 0:
                raise IdentifiabilityError(
                    f"{where} {part.strip()!r} has no known term (such as x'' or F): all curves = 0 solves it, so "
                    "their scale is not identifiable; put a measured signal such as F on one side")
            if not eq.curves and not eq.scalars:
                raise ConfigError(f"{where} {part.strip()!r} has no unknown curve or scalar; drop it or add one")
            self.equations.append(eq)
        names = sorted({n for eq in self.equations for n in eq.curves}, key=sort_key)
        if not names:
            raise ConfigError("the template has no unknown curve; write curves as f1(...), f2(...)")
        self.curve_names = tuple(names)
        self.scalar_names = tuple(sorted({n for eq in self.equations for n in eq.scalars}, key=sort_key))
        self.argument_exprs = {n: arguments[n] for n in names}
        raw = raw_arguments(self.text)
        self.arguments = {n: raw.get(n) or show(arguments[n]) for n in names}
        #: data column each curve reads (its argument as written)
        self.variables = dict(self.arguments)
        syms = set()
        for eq in self.equations:
            for e in (eq.known, eq.input, *eq.curves.values(), *eq.scalars.values()):
                syms |= {s.name for s in sp.sympify(e).free_symbols}
        for a in arguments.values():
            syms |= {s.name for s in a.free_symbols}
        self.symbols = tuple(sorted(syms))
        self.states = tuple(sorted({(dm.group(1) if (dm := DERIV.match(s)) else s)
                                    for s in syms if STATE.match(s) or DERIV.match(s)}))
        self.forces = tuple(sorted(s for s in syms if FORCE.match(s)))
        self.order = max([int(dm.group(2)) for s in syms if (dm := DERIV.match(s))] or [0])
        self._rng_points: dict[str, np.ndarray] | None = None
        self._check_pairs()
        self.anchors = self._choose_anchors(gauge, {n: False for n in names})
        #: the gauge as asked for (None: the family's default anchors); ``anchors`` is what it resolved to
        self.gauge = gauge

    @property
    def is_general(self) -> bool:
        """False for the paper's separable family (which has its own closed-form output and simulator)."""
        return self.family != "separable"

    @property
    def velocity_curves(self) -> tuple[str, ...]:
        """Curves whose argument is a velocity (x', x1', ...): where dry friction puts a jump at 0."""
        return tuple(n for n in self.curve_names
                     if DERIV.match(str(self.argument_exprs[n])) and str(self.argument_exprs[n]).endswith("__d1"))

    @property
    def equation(self) -> str:
        text = self.text
        if self.family == "separable":  # the paper's notation
            g = "g" if self.free_gain else ("" if self.gain == 1 else f"{self.gain:g}")
            return f"x'' + f1(x') + f2(x) = {g + '*F' if g else 'F'}"
        if self.free_gain:
            text += "  (input gain g learned)"
        elif self.gain != 1:
            text += f"  (input gain {self.gain:g})"
        return text

    @property
    def n_equations(self) -> int:
        return len(self.equations)

    @property
    def multi_dof(self) -> bool:
        return self.states != ("x",) or any(f != "F" for f in self.forces)

    def to_dict(self) -> dict:
        if self.family == "separable":  # model files of every release keep this form
            return {"family": "separable", "free_gain": self.free_gain, "gain": self.gain,
                    "gauge": self.anchors[0] if self.anchors else "f2", "gain_on": self.gain_on}
        return {"family": self.family, "equation": self.text, "free_gain": self.free_gain, "gain": self.gain,
                "gauge": list(self.anchors), "gain_on": self.gain_on}

    def __repr__(self) -> str:
        return f"EquationTemplate({self.text!r}, family={self.family!r})"

    def _points(self, n: int = 12) -> dict[str, np.ndarray]:
        """Random values of the data symbols (independent coordinates), drawn once from a fixed seed."""
        if self._rng_points is None:
            rng = np.random.default_rng(20240229)
            self._rng_points = {s: rng.uniform(0.3, 1.7, n) * rng.choice([-1.0, 1.0], n) for s in self.symbols}
        return self._rng_points

    def _eval(self, expr, pts=None) -> np.ndarray:
        pts = self._points() if pts is None else pts
        return evaluate_signal(expr, pts, len(next(iter(pts.values()))) if pts else 12)

    def _function_of(self, r, u) -> bool:
        """Whether ``r`` is (locally) a function of ``u``: their gradients are parallel everywhere."""
        import sympy as sp

        syms = sorted(sp.sympify(r).free_symbols | sp.sympify(u).free_symbols, key=lambda s: s.name)
        if len(syms) <= 1 or not sp.sympify(r).free_symbols & sp.sympify(u).free_symbols:  # a constant, or both
            return len(syms) <= 1 or bool(np.ptp(np.nan_to_num(self._eval(r))) <= 1e-9)  # of one symbol; sign(x1')
        gu = np.stack([self._eval(sp.diff(u, s)) for s in syms])
        gr = np.stack([self._eval(sp.diff(r, s)) for s in syms])
        for k in range(gu.shape[1]):
            M = np.stack([gu[:, k], gr[:, k]])
            if not np.all(np.isfinite(M)):
                continue
            sv = np.linalg.svd(M, compute_uv=False)
            if sv[1] > 1e-9 * max(sv[0], 1e-300):
                return False
        return True

    def _same_signal(self, a, b) -> bool:
        va, vb = self._eval(a), self._eval(b)
        ok = np.isfinite(va) & np.isfinite(vb)
        return bool(np.allclose(va[ok], vb[ok], rtol=1e-9, atol=1e-12))

    def _trade_ratio(self, coef_a: dict, coef_b: dict, u):
        """Ratio r(u) with coef_a = r * coef_b in every equation, when it exists; else None."""
        import sympy as sp

        eqs = [e for e in range(self.n_equations) if e in coef_a or e in coef_b]
        if any(e not in coef_a or e not in coef_b for e in eqs):
            return None
        ratios = [sp.simplify(coef_a[e] / coef_b[e]) for e in eqs]
        if not all(self._same_signal(r, ratios[0]) for r in ratios[1:]):
            return None
        return ratios[0] if self._function_of(ratios[0], u) else None

    def _check_pairs(self) -> None:
        import sympy as sp

        coef = {n: {e: eq.curves[n] for e, eq in enumerate(self.equations) if n in eq.curves} for n in self.curve_names}
        for i, a in enumerate(self.curve_names):
            for b in self.curve_names[i + 1:]:
                ua, ub = self.argument_exprs[a], self.argument_exprs[b]
                if not self._function_of(ub, ua):
                    continue
                if self._trade_ratio(coef[b], coef[a], ua) is not None:
                    raise IdentifiabilityError(
                        f"{a}({self.arguments[a]}) and {b}({self.arguments[b]}) enter the template in the same way: "
                        f"any function of {self.arguments[a]} can move from one to the other, so neither is "
                        f"identifiable; merge them into one curve or give them independent arguments")
        for s in self.scalar_names:
            sc = {e: eq.scalars[s] for e, eq in enumerate(self.equations) if s in eq.scalars}
            for n in self.curve_names:
                r = self._trade_ratio(sc, coef[n], self.argument_exprs[n])
                if r is None or not sp.sympify(r).free_symbols:
                    continue  # a constant is traded through the curve's constant: see check_identifiable
                shown = show(next(iter(sc.values())))
                raise IdentifiabilityError(
                    f"the scalar term {s}*{shown} can be absorbed by {n}({self.arguments[n]}) (it adds "
                    f"{show(r)} * {s} to {n}), so {s} is not identifiable; drop {s} or the curve {n}")

    def _slot_matrix(self, slots: list[tuple[str, str]]) -> np.ndarray:
        """Columns: the stacked coefficient signals of constant slots (curve, scalar or offset)."""
        cols = []
        for kind, name in slots:
            parts = []
            for e, eq in enumerate(self.equations):
                if kind == "curve":
                    sig = eq.curves.get(name, 0)
                elif kind == "scalar":
                    sig = eq.scalars.get(name, 0)
                else:
                    sig = 1 if int(name[1:]) - 1 == e else 0
                parts.append(self._eval(sig))
            cols.append(np.concatenate(parts))
        if not cols:
            return np.zeros((self.n_equations * 12, 0))
        M = np.column_stack(cols)
        M[~np.isfinite(M)] = 0.0
        return M

    def offsets_needed(self, pinned: dict[str, bool]) -> list[int]:
        """Equations (0-based) that get a free constant: no unpinned curve or scalar can carry it."""
        base = [("curve", n) for n in self.curve_names if not pinned.get(n, False)]
        base += [("scalar", s) for s in self.scalar_names]
        M = self._slot_matrix(base)
        r0 = np.linalg.matrix_rank(M, tol=1e-9 * max(1.0, np.abs(M).max(initial=0.0))) if M.size else 0
        out = []
        for e in range(self.n_equations):
            M1 = np.column_stack([M, self._slot_matrix([("offset", f"b{e + 1}")])])
            if np.linalg.matrix_rank(M1, tol=1e-9 * max(1.0, np.abs(M1).max())) > r0:
                out.append(e)
        return out

    def _freedoms(self, pinned: dict[str, bool], priority: list[tuple[str, str]]):
        """Null space of the slot matrix as vectors with a unit pivot each, pivots by ``priority``."""
        slots = list(priority)
        M = self._slot_matrix(slots)
        if M.shape[1] == 0:
            return slots, []
        scale = max(1.0, float(np.abs(M).max()))
        _, s, vt = np.linalg.svd(M, full_matrices=True)
        rank = int(np.sum(s > 1e-9 * scale))
        N = vt[rank:].T  # (n_slots, k)
        if N.shape[1] == 0:
            return slots, []
        pivots: list[int] = []
        for idx in range(len(slots)):
            trial = pivots + [idx]
            if np.linalg.matrix_rank(N[trial, :], tol=1e-9) == len(trial):
                pivots = trial
            if len(pivots) == N.shape[1]:
                break
        B = N @ np.linalg.inv(N[pivots, :])
        B[np.abs(B) < 1e-10] = 0.0
        near = np.abs(B - np.round(B)) < 1e-10  # trade ratios are usually integers (+-1): make them exact
        B[near] = np.round(B[near])
        return slots, [(slots[p], B[:, k]) for k, p in enumerate(pivots)]

    def _priority(self, pinned: dict[str, bool], anchors, offsets: list[int]):
        free = [n for n in self.curve_names if not pinned.get(n, False)]
        first = [("curve", a) for a in anchors if a in free]
        rest = [("curve", n) for n in reversed(free) if n not in anchors]
        return first + [("offset", f"b{e + 1}") for e in offsets] + rest + [("scalar", s) for s in self.scalar_names]

    def _choose_anchors(self, gauge, pinned) -> tuple[str, ...]:
        if gauge is None or gauge == "" or gauge == "auto":
            wanted: list[str] = list(FAMILY_ANCHORS.get(self.family, ()))
        elif isinstance(gauge, str):
            wanted = [g.strip() for g in gauge.split(",") if g.strip()]
        else:
            wanted = [str(g).strip() for g in gauge]
        for g in wanted:
            if g not in self.curve_names:
                raise ConfigError(f"gauge names unknown curve {g!r}; the curves are {', '.join(self.curve_names)}")
        offsets = self.offsets_needed(pinned)
        slots, vecs = self._freedoms(pinned, self._priority(pinned, wanted, offsets))
        anchors = tuple(name for (kind, name), _ in vecs if kind == "curve")
        explicit = gauge not in (None, "", "auto")
        useless = [g for g in wanted if g not in anchors]
        if explicit and useless:
            movable = sorted({name for (kind, name), v in vecs for (k2, n2), c in zip(slots, v) if c and k2 == "curve"})
            hint = (f"the curves that can trade constants are {', '.join(movable)}" if movable
                    else "this template has no gauge freedom, so leave the gauge unset")
            raise ConfigError(f"gauge {', '.join(useless)}: anchoring {useless[0]} at 0 fixes no freedom of "
                              f"this template ({hint})")
        return anchors

    def anchored_offsets(self, pinned: dict[str, bool]) -> list[int]:
        """Equations that get a free constant once the anchors are imposed: an anchor is a condition
        (the paper's f2(0) = 0; zero coupling force at equilibrium), so when it leaves no other curve
        to carry an equation's constant, the constant becomes the equation's free constant b."""
        return self.offsets_needed({**pinned, **{a: True for a in self.anchors}})

    def gauge_conditions(self, pinned: dict[str, bool] | None = None) -> list[str]:
        """The anchoring conditions that fix the gauge, e.g. ``["f2(0) = 0"]``."""
        pinned = pinned or {}
        offsets = self.anchored_offsets(pinned)
        _, vecs = self._freedoms(pinned, self._priority(pinned, self.anchors, offsets))
        return [f"{name}(0) = 0" for (kind, name), _ in vecs if kind == "curve"]

    def gauge_freedoms(self, pinned: dict[str, bool] | None = None) -> list[str]:
        """Human-readable gauge freedoms: which curves trade a constant, and the anchor that fixes it."""
        pinned = pinned or {}
        offsets = self.anchored_offsets(pinned)
        slots, vecs = self._freedoms(pinned, self._priority(pinned, self.anchors, offsets))
        out = []
        for (kind, name), v in vecs:
            members = [n2 for (_, n2), c in zip(slots, v) if c]
            fix = f"{name}(0) = 0" if kind == "curve" else f"{name} = 0"
            out.append(f"a constant c moves between {' and '.join(members)}; fixed by {fix}")
        return out

    def check_identifiable(self, pinned: dict[str, bool]) -> None:
        """Raise IdentifiabilityError when a scalar cannot be determined under these curve priors."""
        if not self.scalar_names:
            return
        offsets = self.offsets_needed(pinned)
        slots, vecs = self._freedoms(pinned, self._priority(pinned, self.anchors, offsets))
        for (kind, name), v in vecs:
            involved = [(k2, n2) for (k2, n2), c in zip(slots, v) if c]
            bad = [n2 for k2, n2 in involved if k2 == "scalar"]
            if bad:
                others = [n2 for k2, n2 in involved if k2 != "scalar" and n2 not in bad]
                with_ = f" with the constants of {', '.join(others)}" if others else " with another scalar"
                raise IdentifiabilityError(
                    f"the scalar {bad[0]} trades{with_}, so its value is not identifiable; drop {bad[0]}"
                    + (f" or make {', '.join(o for o in others if o.startswith('f'))} odd (an odd curve carries "
                       "no constant)" if any(o.startswith("f") for o in others) else ""))

    def normalise(self, values_at_zero: dict[str, float], pinned: dict[str, bool], offsets: dict[int, float]):
        """Shifts per curve (and new offsets) that satisfy the anchors; see :meth:`_freedoms`."""
        offs = self.anchored_offsets(pinned)
        slots, vecs = self._freedoms(pinned, self._priority(pinned, self.anchors, offs))
        value = {}
        for kind, name in slots:
            if kind == "curve":
                value[(kind, name)] = float(values_at_zero[name])
            elif kind == "offset":
                value[(kind, name)] = float(offsets.get(int(name[1:]) - 1, 0.0))
            else:
                value[(kind, name)] = 0.0
        shifts = {n: 0.0 for n in self.curve_names}
        new_off = {int(name[1:]) - 1: value[(k, name)] for k, name in slots if k == "offset"}
        for piv, v in vecs:
            lam = -value[piv]
            if lam == 0.0:
                continue
            for slot, c in zip(slots, v):
                if c:
                    value[slot] += lam * c
                    if slot[0] == "curve":
                        shifts[slot[1]] += lam * c
                    elif slot[0] == "offset":
                        new_off[int(slot[1][1:]) - 1] = value[slot]
        return shifts, new_off

    def columns_of(self, record) -> dict[str, np.ndarray]:
        return record_columns(record, self)

    def design(self, record) -> dict[str, Any]:
        """Stacked arrays of the equations on a record (rows: equation-major)."""
        cols = self.columns_of(record)
        n = len(cols["t"])
        ev = lambda e: evaluate_signal(e, cols, n)  # noqa: E731
        y = np.concatenate([ev(eq.known) for eq in self.equations])
        F = np.concatenate([ev(eq.input) for eq in self.equations])
        args = {name: ev(self.argument_exprs[name]) for name in self.curve_names}
        mult = {name: np.concatenate([ev(eq.curves.get(name, 0)) for eq in self.equations]) for name in self.curve_names}
        scal = {s: np.concatenate([ev(eq.scalars.get(s, 0)) for eq in self.equations]) for s in self.scalar_names}
        for label, arr in [("known part", y), ("input", F), *[(f"argument of {k}", v) for k, v in args.items()],
                           *[(f"coefficient of {k}", v) for k, v in mult.items()], *scal.items()]:
            if not np.all(np.isfinite(arr)):
                raise DataError(f"the {label} of the template is not finite on this record (division by zero or "
                                "log of a negative value?); change the template or the record")
        return {"n": n, "E": self.n_equations, "y": y, "F": F, "args": args, "mult": mult, "scalars": scal}

    def arguments_of(self, record) -> dict[str, np.ndarray]:
        cols = self.columns_of(record)
        n = len(cols["t"])
        return {name: evaluate_signal(self.argument_exprs[name], cols, n) for name in self.curve_names}

    def check_excitation(self, record) -> None:
        for name, z in self.arguments_of(record).items():
            if np.ptp(z) <= 1e-12 * max(1.0, float(np.max(np.abs(z)))):
                extra = " (the masses move together)" if "-" in self.arguments[name] else ""
                fix = ("give a record in which the system moves (excite it)" if self.family == "separable"
                       else "give a record in which it varies (excite the system)")
                raise DataError(f"the argument {self.arguments[name]} of {name} is constant over the record{extra}, so "
                                f"{name} cannot be identified; {fix}")


def evaluate_signal(expr, cols: dict[str, np.ndarray], n: int) -> np.ndarray:
    """Values of a template expression on data columns (``x__d1`` is x'), as an array of length ``n``.

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.templates import evaluate_signal
    >>> evaluate_signal("x - x__d1", {"x": np.array([1.0, 2.0]), "x__d1": np.array([0.5, 0.5])}, 2).tolist()
    [0.5, 1.5]
    """
    import sympy as sp
    expr = sp.sympify(expr)
    syms = sorted(expr.free_symbols, key=lambda s: s.name)
    if not syms:
        return np.full(n, float(expr))
    f = numpy_function(syms, expr)
    with np.errstate(all="ignore"):
        return np.broadcast_to(np.asarray(f(*[cols[s.name] for s in syms]), dtype=float), (n,)).copy()


def record_columns(record, template: EquationTemplate) -> dict[str, np.ndarray]:
    """The data symbols a template reads, from a Trajectory or a MultiTrajectory.

    Examples
    --------
    >>> from charcurves import systems, templates
    >>> sorted(templates.record_columns(systems.get_system("duffing").simulate(), templates.get_template()))
    ['F', 't', 'x', 'x__d1', 'x__d2']
    """
    from ..data import MultiTrajectory, Trajectory

    need = set(template.symbols)
    if isinstance(record, Trajectory):
        if template.multi_dof:
            raise DataError(f"the template uses {', '.join(template.states + template.forces)} but the record has one "
                            "state x and forcing F; give a multi-DOF record (columns t,x1,x2,F1,F2)")
        cols = {"t": np.asarray(record.t), "x": np.asarray(record.x), "F": np.asarray(record.F)}
        if record.v is not None:
            cols["x__d1"] = np.asarray(record.v)
        if record.a is not None:
            cols["x__d2"] = np.asarray(record.a)
    elif isinstance(record, MultiTrajectory):
        cols = {"t": np.asarray(record.t)}
        for s in record.states:
            cols[s] = np.asarray(record.states[s])
            if record.velocities is not None:
                cols[f"{s}__d1"] = np.asarray(record.velocities[s])
            if record.accelerations is not None:
                cols[f"{s}__d2"] = np.asarray(record.accelerations[s])
        cols.update({k: np.asarray(v) for k, v in record.forces.items()})
    else:
        raise DataError(f"expected a Trajectory or MultiTrajectory, got {type(record).__name__}")
    missing = sorted(need - set(cols))
    if missing:
        shown = ", ".join(display(m) for m in missing)
        raise DataError(f"the template needs {shown}, which the record lacks; estimate derivatives first or give "
                        "those columns")
    return cols
