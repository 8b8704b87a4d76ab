"""The method shorthands as one settings object: what ``CharacteristicCurves.from_method`` builds.

A :class:`MethodPreset` names one of the paper's methods (or none: the default, whose parity
priors are tested on the record) with the options that shape it -- the family, the priors, the
basis, the network... The estimator turns it into a template with a representation per curve at
fit time (the parity test of the default needs the record).
"""

from __future__ import annotations

import inspect
from collections.abc import Sequence
from typing import Any

from .._errors import ConfigError
from .._params import Params
from ._methods import METHODS

__all__ = ["MethodPreset"]

#: options that only shape the curves a method builds (ignored when a template sets every curve)
_CURVE_OPTIONS = {"poly": ("degree", "rescaling", "basis", "expand_tol"),
                  "sindy": ("threshold", "degree", "max_iter", "alpha", "nu", "tol", "rescaling")}
#: settings of the template a preset builds from a family (a template object carries its own)
_TEMPLATE_SETTINGS = ("family", "equation", "free_gain", "gain", "gauge", "gain_on")


class MethodPreset(Params):
    """One of the paper's methods with its shorthands (build it with ``CharacteristicCurves.from_method``).

    Parameters
    ----------
    name : str, optional
        One of :data:`~charcurves.fitting.METHODS`; None: NN-CC whose parity priors are tested on the record.
    family : str
        The template family ("separable", "first-order", "position-damping", "two-dof").
    equation : str, optional
        A user-written equation instead of a family (``"x'' + f1(x') + f2(x) = F"``).
    symmetry : str or dict, optional
        Parity priors ("f1=odd,f2=odd", "odd", a dict, or "auto": tested on unconstrained curves).
    free_gain : bool
        Learn the input gain g.
    gain : float
        The fixed input gain (the paper: 1).
    gauge : str or sequence of str, optional
        Curves anchored at 0 (None: the family's default).
    gain_on : str
        With a free gain, the noisy side: "force" or "acceleration".
    jump : str or sequence of str
        A learned jump at 0 of neural curves: "auto", "none" or curve names.
    basis : str or dict or list, optional
        The functions of each curve of method "parametric" ("f1=z; f2=z, z**3").
    options : dict, optional
        Options of the method's representation ({"degree": 10}) and of sticking detection.
    hidden : sequence of int, optional
        Layer widths of neural curves (None: the training preset's).
    activation : str, optional
        Activation of neural curves (None: the training preset's).
    exclude_sticking : bool
        Leave out samples where the mass sticks.
    sr_options : dict, optional
        Symbolic regression settings (engine, generations, ...) of SR methods and post-SR.

    Examples
    --------
    >>> from charcurves.fitting import MethodPreset
    >>> preset = MethodPreset("poly-cc", symmetry="odd", options={"degree": 5})
    >>> preset
    MethodPreset(name='poly-cc', symmetry='odd', options={'degree': 5})
    >>> preset.set_params(symmetry="f1=odd").get_params(deep=False)["symmetry"]
    'f1=odd'
    """

    def __init__(self, name: str | None = None, *, family: str = "separable", equation: str | None = None,
                 symmetry: str | dict | None = None, free_gain: bool = False, gain: float = 1.0,
                 gauge: str | Sequence[str] | None = None,
                 gain_on: str = "force", jump: str | Sequence[str] = "auto", basis: str | dict | list | None = None,
                 options: dict | None = None, hidden: Sequence[int] | None = None, activation: str | None = None,
                 exclude_sticking: bool = True, sr_options: dict | None = None):
        self.name = name
        self.family = family
        self.equation = equation
        self.symmetry = symmetry
        self.free_gain = free_gain
        self.gain = gain
        self.gauge = gauge
        self.gain_on = gain_on
        self.jump = jump
        self.basis = basis
        self.options = options
        self.hidden = hidden
        self.activation = activation
        self.exclude_sticking = exclude_sticking
        self.sr_options = sr_options

    @classmethod
    def build(cls, name: str | None = None, *, template=None, degree: int | None = None, options: dict | None = None,
              **shorthands: Any) -> MethodPreset:
        """The preset of :meth:`CharacteristicCurves.from_method`: ``degree`` folded into ``options``,
        checked against ``template`` (see :meth:`check`)."""
        if degree is not None:
            rep = METHODS[name]["representation"] if name in METHODS else "neural"
            if rep not in ("poly", "sindy"):
                raise ConfigError(f"degree= applies to poly-cc and the SINDy methods, not to method "
                                  f"{name or 'nn-cc (the default)'!r}")
            if "degree" in (options or {}) and (options or {})["degree"] != degree:
                raise ConfigError("give the degree once: degree= or options={'degree': ...}")
            options = {**(options or {}), "degree": degree}
        preset = cls(name, options=options, **shorthands)
        preset.check(template)
        return preset

    def given(self) -> list[str]:
        """The shorthands set to something other than their default (in signature order)."""
        sig = inspect.signature(type(self).__init__)
        return [n for n in self._param_names() if n != "name" and not _same(getattr(self, n), sig.parameters[n].default)]

    def ignored(self, template=None) -> list[str]:
        """The shorthands that would have no effect with ``template`` (a template object or None):
        a network shape or basis the method's curves do not take, or curve and family settings where
        the template sets them itself."""
        given = set(self.given())
        rep = METHODS[self.name]["representation"] if self.name in METHODS else "neural"
        out: list[str] = []
        if rep != "neural":
            out += [n for n in ("hidden", "activation") if n in given]
        if rep != "basis":
            out += [n for n in ("basis",) if n in given]
        if template is not None:
            out += [n for n in _TEMPLATE_SETTINGS if n in given]
            curves = getattr(template, "curves", None)
            if isinstance(curves, dict) and curves and all(c is not None for c in curves.values()):
                out += [n for n in ("symmetry", "hidden", "activation", "basis") if n in given and n not in out]
                if isinstance(self.jump, (list, tuple)) or str(self.jump).strip().lower() not in ("auto", "none", ""):
                    out.append("jump")  # "none" still says: no sticking samples left out
                shaped = [k for k in (self.options or {}) if k in _CURVE_OPTIONS.get(rep, ())]
                out += [f"options[{k!r}]" for k in shaped]
        return out

    def check(self, template=None) -> None:
        """A ConfigError naming the shorthands that would be ignored (see :meth:`ignored`)."""
        if self.name is not None and self.name not in METHODS:
            raise ConfigError(f"unknown method {self.name!r}; choose one of {', '.join(METHODS)}")
        ignored = self.ignored(template)
        if not ignored:
            return
        label = f"method {self.name!r}" if self.name else "the default method (neural curves)"
        if template is not None and any(n in _TEMPLATE_SETTINGS or n in ("symmetry", "jump") or n.startswith("options")
                                        for n in ignored):
            why = f"the template {type(template).__name__} sets them itself: put them in the template and its curves"
        else:
            why = f"{label} does not take them"
        raise ConfigError(f"{', '.join(ignored)} would be ignored: {why} (leave them out, or choose a method that "
                          "uses them)")

    def check_basis_cost(self) -> None:
        """Refuse basis functions whose exact evaluation by sympy could hang (e.g. ``9**9**9*z``)."""
        import re

        from ..curves import expression_cost_problem

        if isinstance(self.basis, str):
            texts = re.split(r"[;,=]", self.basis)
        elif isinstance(self.basis, dict):
            texts = [str(f) for v in self.basis.values() for f in (v if isinstance(v, (list, tuple)) else [v])]
        else:
            return
        for text in texts:
            problem = expression_cost_problem(text.strip())
            if problem:
                raise ConfigError(f"basis function {text.strip()[:60]!r} {problem}; write a plain closed form "
                                  "such as 'z**3' or 'tanh(50*z)'")

    def __repr__(self) -> str:
        shown = ([f"name={self.name!r}"] if self.name is not None else []) + \
            [f"{n}={getattr(self, n)!r}" for n in self.given()]
        return f"MethodPreset({', '.join(shown)})"

    def __eq__(self, other: object) -> bool:
        return type(self) is type(other) and self.get_params() == other.get_params()  # type: ignore[union-attr]

    __hash__ = None  # type: ignore[assignment]  # mutable through set_params


def _same(value: Any, default: Any) -> bool:
    """Whether a shorthand is left at its default (an empty text or dict counts as None)."""
    try:
        if default is None and isinstance(value, (str, dict, list, tuple)) and not value:
            return True
        return bool(value == default) and isinstance(value, bool) == isinstance(default, bool)
    except Exception:  # noqa: BLE001 - arrays and odd objects: compare by identity
        return value is default
