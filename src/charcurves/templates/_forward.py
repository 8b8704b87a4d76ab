"""A template solved for its highest derivatives, in torch: the forward model of output error.

For a template with one equation per state, the highest derivative of each state (``x''``, or
``x'`` for first-order states) is the solution of ``A top + r0(y) = 0``, where ``r0`` is the
residual with those derivatives at 0 and ``y`` is the ODE state (each state and its lower
derivatives). Output error integrates this ODE and needs, at every integration stage, the pieces
of ``r0`` and their partial derivatives in ``y`` (the curves themselves are evaluated by the
fitter, which owns their parameters):

* ``known0_e``, the known part with the top derivatives at 0, and the input ``input_e``;
* each curve's argument ``u_i(y)`` and coefficient ``m_ie(y)``; each scalar's signal ``s_je(y)``.

The top derivatives may appear in the known part, with constant coefficients (``A``), as in the
second-order families; in a template of one equation they may also be a factor of curves
(``f1(x) + f2(x) x' = F``: the top derivative is ``-r0 / (A + sum_i m_i f_i)``, see ``divides``).
Other templates cannot be simulated this way and say so.
"""

from __future__ import annotations

from .._errors import ConfigError
from ._parse import show as _shown
from ._structure import EquationTemplate

__all__ = ["ForwardModel", "Signal"]


class Signal:
    """One data signal of the template, compiled for torch, with its gradient in the ODE state.

    ``value(vals)`` and ``grad(vals)`` take a dict of symbol name -> tensor (all one shape ``S``)
    and return a tensor of shape ``S`` (constants broadcast) and a dict layout index -> tensor of
    the non-zero partial derivatives.
    """

    def __init__(self, expr, symbols: list, layout: list[str]):
        import sympy as sp

        expr = sp.sympify(expr)
        self.expr = expr
        self._const = float(expr) if not expr.free_symbols else None
        used = sorted(expr.free_symbols, key=lambda s: s.name)
        self._names = [s.name for s in used]
        self._f = sp.lambdify(used, expr, modules="torch") if used else None
        # (layout index, constant derivative or None, compiled derivative or None, its symbol names or None)
        self._grads: list[tuple] = []
        for i, name in enumerate(layout):
            d = sp.diff(expr, sp.Symbol(name, real=True))
            if d == 0:
                continue
            if not d.free_symbols:
                self._grads.append((i, float(d), None, None))
            else:
                du = sorted(d.free_symbols, key=lambda s: s.name)
                self._grads.append((i, None, sp.lambdify(du, d, modules="torch"), [s.name for s in du]))

    @property
    def constant(self) -> float | None:
        return self._const

    def value(self, vals: dict, like):
        import torch

        if self._const is not None:
            return torch.full_like(like, self._const)
        assert self._f is not None  # not a constant: compiled in __init__
        out = self._f(*[vals[n] for n in self._names])
        return torch.broadcast_to(torch.as_tensor(out, dtype=like.dtype), like.shape)

    def grad(self, vals: dict, like) -> dict:
        import torch

        out = {}
        for i, c, fn, names in self._grads:
            if fn is None:
                out[i] = c
            else:
                out[i] = torch.broadcast_to(torch.as_tensor(fn(*[vals[n] for n in names]), dtype=like.dtype), like.shape)
        return out


class ForwardModel:
    """The template as an ODE in its states (see the module docstring).

    Attributes
    ----------
    layout : list of str
        The ODE state: each state and its lower derivatives (``["x", "x__d1"]``).
    top : list of str
        The highest derivative of each state (``["x__d2"]``), one per equation.
    A_inv : list of list of float or None
        Inverse of the constant matrix of the top derivatives in the equations (None when
        ``divides``).
    divides : bool
        One equation whose top derivative is also a factor of curves (``mult_top``).

    Examples
    --------
    >>> from charcurves.templates import ForwardModel, get_template
    >>> model = ForwardModel(get_template("separable"))
    >>> model.layout, model.top
    (['x', 'x__d1'], ['x__d2'])
    """

    def __init__(self, template: EquationTemplate):
        import numpy as np
        import sympy as sp

        self.template = template
        orders = {s: 0 for s in template.states}
        for name in template.symbols:
            for s in template.states:
                if name.startswith(f"{s}__d"):
                    orders[s] = max(orders[s], int(name[-1]))
        if any(k == 0 for k in orders.values()):
            raise ConfigError(f"the template has no derivative of {[s for s, k in orders.items() if k == 0]}; "
                              "nothing to simulate for output error")
        if template.n_equations != len(template.states):
            raise ConfigError(f"the template has {template.n_equations} equation(s) for {len(template.states)} "
                              "state(s); output error simulates one equation per state")
        self.orders = orders
        self.layout = [s if k == 0 else f"{s}__d{k}" for s in template.states for k in range(orders[s])]
        self.top = [f"{s}__d{orders[s]}" for s in template.states]
        top_syms = [sp.Symbol(n, real=True) for n in self.top]
        layout_syms = list(self.layout)
        self.curves: dict[str, Signal] = {}
        self.equations = []
        A = np.zeros((template.n_equations, len(self.top)))
        single = template.n_equations == 1
        for e, eq in enumerate(template.equations):
            for part in (eq.input, *eq.scalars.values(), *(template.argument_exprs[n] for n in eq.curves),
                         *([] if single else eq.curves.values())):
                if set(sp.sympify(part).free_symbols) & set(top_syms):
                    raise ConfigError(f"equation {e + 1} has {_shown(', '.join(self.top))} inside a curve's "
                                      "argument, a coefficient, a scalar term or the input; output error needs the "
                                      "highest derivatives in the known part or as a factor of curves of one equation "
                                      "(use objective='equation-error' for this template)")
            mult0, mult_top = {}, {}
            for n, m in eq.curves.items():
                m = sp.sympify(m)
                if single and top_syms[0] in m.free_symbols:  # f2(x) * x' of the first-order family
                    m1 = sp.expand(sp.diff(m, top_syms[0]))
                    if top_syms[0] in m1.free_symbols:
                        raise ConfigError(f"equation {e + 1}: {_shown(self.top[0])} enters the factor {_shown(m)} "
                                          f"of {n} nonlinearly; "
                                          "output error needs it linear (use objective='equation-error')")
                    m0 = sp.expand(m - m1 * top_syms[0])
                    mult_top[n] = Signal(m1, [], layout_syms)
                    if m0 != 0:
                        mult0[n] = Signal(m0, [], layout_syms)
                else:
                    mult0[n] = Signal(m, [], layout_syms)
            known = sp.sympify(eq.known)
            for j, ts in enumerate(top_syms):
                coef = sp.diff(known, ts)
                if coef.free_symbols:
                    raise ConfigError(f"equation {e + 1}: {_shown(self.top[j])} enters with the coefficient "
                                      f"{_shown(coef)}, which "
                                      "depends on the data; output error needs constant coefficients")
                A[e, j] = float(coef)
            known0 = known.subs({ts: 0 for ts in top_syms})
            self.equations.append({
                "known0": Signal(known0, [], layout_syms),
                "input": Signal(eq.input, [], layout_syms),
                "mult": mult0,
                "mult_top": mult_top,
                "scalars": {s: Signal(sig, [], layout_syms) for s, sig in eq.scalars.items()},
            })
        self.A = A.tolist()
        #: the top derivative is ``-r0 / (A + sum_i m_i f_i)`` (one equation with curves as its factor)
        self.divides = bool(self.equations[0]["mult_top"]) if single else False
        if self.divides:
            self.A_inv = None
        else:
            if abs(np.linalg.det(A)) < 1e-12:
                raise ConfigError(f"the equations cannot be solved for {_shown(', '.join(self.top))} (singular); "
                                  "output error needs one equation per state")
            self.A_inv = np.linalg.inv(A).tolist()
        for n in template.curve_names:
            self.curves[n] = Signal(template.argument_exprs[n], [], layout_syms)

    @property
    def n_state(self) -> int:
        return len(self.layout)

    def derivative_of(self, i: int) -> int | None:
        """Index in the layout of the time derivative of entry ``i`` (None: it is a top derivative)."""
        name = self.layout[i]
        base, _, k = name.partition("__d")
        nxt = f"{base}__d{int(k or 0) + 1}"
        return self.layout.index(nxt) if nxt in self.layout else None

    def top_index(self, i: int) -> int:
        """For a layout entry whose derivative is a top derivative: which one."""
        base = self.layout[i].partition("__d")[0]
        return self.template.states.index(base)
