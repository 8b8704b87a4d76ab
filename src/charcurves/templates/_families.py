"""Templates as composable objects: a structure (the equation) plus a representation per curve.

``Separable(f1=Neural(symmetry="odd"), f2=Polynomial(degree=5))`` says which curves exist, how they
combine and what each may be; :meth:`Template.structure` is the parsed
:class:`~charcurves.templates.EquationTemplate` that the fitters work with. Curves left as ``None``
take the estimator's default representation (the ``method`` preset).
"""

from __future__ import annotations

from typing import Any, ClassVar

from .._errors import ConfigError
from .._params import Params
from ._parse import check_equation_option
from ._structure import FAMILY_EQUATIONS, EquationTemplate

__all__ = ["Template", "Separable", "PositionDamping", "FirstOrder", "TwoDOF", "Equation", "get_template",
           "FAMILY_NAMES", "as_template", "parse_equation"]

#: Every built-in family ("custom" is a user-written equation, see Equation).
FAMILY_NAMES = ("separable", "first-order", "position-damping", "two-dof")

_OPTIONS = ("gain", "free_gain", "gauge", "gain_on")


class Template(Params):
    """A structural template with a representation for each curve (scikit-learn parameters).

    Parameters (every template)
    ---------------------------
    f1, f2, ... : AbstractCurve or None
        The representation of each curve (None: the estimator's default).
    gain : float
        The fixed input gain g (the paper: 1).
    free_gain : bool
        Learn g (unknown mass or input scaling, as on real records).
    gauge : str or sequence of str, optional
        Curves anchored at 0 to fix the constants that curves can trade (separable: "f2", the
        paper's f2(0) = 0, or "f1"); None takes the family's default.
    gain_on : {"force", "acceleration"}
        With a free gain, which measured side carries the noise and is the regression target.

    Examples
    --------
    >>> from charcurves.curves import Neural, Polynomial
    >>> from charcurves.templates import Separable, Template
    >>> template = Separable(f1=Polynomial(degree=3), f2=Neural(hidden=(16,)))
    >>> isinstance(template, Template), template.curve_names
    (True, ('f1', 'f2'))
    >>> template.set_params(f2__hidden=(8, 8)).get_params()["f2__hidden"]
    (8, 8)
    >>> template.structure().text
    "x'' + f1(x') + f2(x) = F"
    """

    family: ClassVar[str] = ""
    curve_names: ClassVar[tuple[str, ...]] = ()

    def __init__(self, *, gain: float = 1.0, free_gain: bool = False, gauge=None, gain_on: str = "force", **curves):
        unknown = sorted(set(curves) - set(self.curve_names))
        if unknown:
            raise ConfigError(f"{type(self).__name__} has curves {', '.join(self.curve_names)}, not "
                              f"{', '.join(unknown)}")
        for name in self.curve_names:
            setattr(self, name, curves.get(name))
        self.gain = gain
        self.free_gain = free_gain
        self.gauge = gauge
        self.gain_on = gain_on

    # ------------------------------------------------------------------ scikit-learn contract
    def _names(self) -> list[str]:
        return list(self.curve_names) + list(_OPTIONS)

    def _param_names(self) -> list[str]:  # the curves of the template are parameters (Params' rule)
        return self._names()

    def __eq__(self, other: object) -> bool:
        return type(self) is type(other) and self.get_params(deep=False) == other.get_params(deep=False)  # type: ignore[attr-defined]

    __hash__ = None  # type: ignore[assignment]  # mutable through set_params

    def __repr__(self) -> str:
        parts = [f"{n}={getattr(self, n)!r}" for n in self._names()
                 if getattr(self, n) is not None and not (n in _OPTIONS and getattr(self, n) == _DEFAULTS[n])]
        return f"{type(self).__name__}({', '.join(parts)})"

    # ------------------------------------------------------------------ what fitters use
    @property
    def curves(self) -> dict[str, Any]:
        """Curve name -> representation (None where unset)."""
        return {name: getattr(self, name) for name in self.curve_names}

    def equation_text(self) -> str:
        return FAMILY_EQUATIONS[self.family]

    def structure(self) -> EquationTemplate:
        """The parsed equation with its gain options and gauge (checked; a ConfigError names a problem)."""
        return EquationTemplate(self.equation_text(), family=self.family, free_gain=bool(self.free_gain),
                                gain=self.gain, gauge=self.gauge, gain_on=self.gain_on)

    def with_defaults(self, default) -> Template:
        """A copy in which every unset curve is ``default(name, structure)`` (a representation)."""
        import copy

        out = copy.deepcopy(self)
        structure = out.structure()
        for name in structure.curve_names:
            if getattr(out, name, None) is None:
                setattr(out, name, default(name, structure))
        return out


_DEFAULTS = {"gain": 1.0, "free_gain": False, "gauge": None, "gain_on": "force"}


def _family_init(names):
    def __init__(self, *args, gain: float = 1.0, free_gain: bool = False, gauge=None, gain_on: str = "force",
                 **curves):
        if len(args) > len(names):
            raise ConfigError(f"{type(self).__name__} takes at most {len(names)} curves ({', '.join(names)})")
        curves.update(dict(zip(names, args)))
        Template.__init__(self, gain=gain, free_gain=free_gain, gauge=gauge, gain_on=gain_on, **curves)

    return __init__


class Separable(Template):
    """``x'' + f1(x') + f2(x) = g F`` (the paper's family; anchored by f2(0) = 0 by default).

    Examples
    --------
    >>> from charcurves.curves import Neural, Polynomial
    >>> from charcurves.templates import Separable
    >>> Separable(f1=Polynomial(degree=3, symmetry="odd"), f2=Neural(symmetry="odd"))
    Separable(f1=Polynomial(degree=3, symmetry='odd'), f2=Neural(symmetry='odd'))
    """

    family = "separable"
    curve_names = ("f1", "f2")
    __init__ = _family_init(curve_names)


class PositionDamping(Template):
    """``x'' + f1(x) x' + f2(x) = g F`` (position-dependent damping, Van der Pol type).

    Examples
    --------
    >>> from charcurves.curves import Polynomial
    >>> from charcurves.templates import PositionDamping
    >>> template = PositionDamping(f1=Polynomial(degree=2, symmetry="even"))
    >>> template.structure().arguments
    {'f1': 'x', 'f2': 'x'}
    >>> template.f2 is None
    True
    """

    family = "position-damping"
    curve_names = ("f1", "f2")
    __init__ = _family_init(curve_names)


class FirstOrder(Template):
    """``f1(x) + f2(x) x' = g F``.

    Examples
    --------
    >>> from charcurves.templates import FirstOrder
    >>> FirstOrder(free_gain=True).structure().text
    "f1(x) + f2(x)*x' = F"
    """

    family = "first-order"
    curve_names = ("f1", "f2")
    __init__ = _family_init(curve_names)


class TwoDOF(Template):
    """``x1'' + f1(x1') + f2(x1 - x2) = F1; x2'' + f3(x2') + f4(x2 - x1) = F2`` (f2(0) = f4(0) = 0).

    Examples
    --------
    >>> from charcurves.templates import TwoDOF
    >>> structure = TwoDOF().structure()
    >>> structure.states, structure.forces, structure.gauge_conditions()
    (('x1', 'x2'), ('F1', 'F2'), ['f2(0) = 0', 'f4(0) = 0'])
    """

    family = "two-dof"
    curve_names = ("f1", "f2", "f3", "f4")
    __init__ = _family_init(curve_names)


class Equation(Template):
    """A user-written template, e.g. ``Equation("x'' + f1(x)*x' + f2(x) = F", f1=Neural())``.

    Parameters
    ----------
    equation : str
        One or several equations separated by ``;`` with unknown curves ``f1(...)``, ``f2(...)``
        and scalars ``a1, a2, ...`` (see docs/families.md); parsed safely, never evaluated.
    **curves
        A representation per curve name of the equation (``f1=...``); unset ones take the default.
    gain, free_gain, gauge, gain_on
        As every template.

    Examples
    --------
    >>> from charcurves.curves import Polynomial
    >>> from charcurves.templates import Equation
    >>> template = Equation("x'' + a1*x' + f1(x) = F", f1=Polynomial(degree=3, symmetry="odd"))
    >>> template.curve_names, template.structure().scalar_names
    (('f1',), ('a1',))
    """

    family = "custom"

    def __init__(self, equation: str, *, gain: float = 1.0, free_gain: bool = False, gauge=None,
                 gain_on: str = "force", **curves):
        bad = [k for k in curves if not (k.startswith("f") and k[1:].isdigit())]
        if bad:
            raise ConfigError(f"Equation takes curves named f1, f2, ..., not {', '.join(bad)}")
        self.equation = equation
        self._curve_keys = tuple(sorted(curves, key=lambda k: int(k[1:])))
        self.gain = gain
        self.free_gain = free_gain
        self.gauge = gauge
        self.gain_on = gain_on
        for name, value in curves.items():
            setattr(self, name, value)

    @property
    def curve_names(self) -> tuple[str, ...]:  # type: ignore[override]
        try:
            names = EquationTemplate(str(self.equation)).curve_names
        except ConfigError:
            names = ()
        return tuple(sorted(set(names) | set(self._curve_keys), key=lambda k: int(k[1:])))

    def _names(self) -> list[str]:
        return ["equation", *self.curve_names, *_OPTIONS]

    def __getattr__(self, name: str):
        if name.startswith("f") and name[1:].isdigit():
            return None  # a curve of the equation not given a representation
        raise AttributeError(name)

    def equation_text(self) -> str:
        check_equation_option(self.equation)
        return str(self.equation)

    def structure(self) -> EquationTemplate:
        structure = EquationTemplate(self.equation_text(), family="custom", free_gain=bool(self.free_gain),
                                     gain=self.gain, gauge=self.gauge, gain_on=self.gain_on)
        extra = sorted(set(self._curve_keys) - set(structure.curve_names))
        if extra:
            raise ConfigError(f"the equation has curves {', '.join(structure.curve_names)}, but a representation was "
                              f"given for {', '.join(extra)}; drop it or use it in the equation")
        return structure


_FAMILY_CLASSES: dict[str, type[Template]] = {"separable": Separable, "position-damping": PositionDamping,
                                              "first-order": FirstOrder, "two-dof": TwoDOF}


def as_template(family: str | None = "separable", *, equation: str | None = None, **options) -> Template:
    """The template object of a family name or a user-written equation, without representations.

    Examples
    --------
    >>> from charcurves.templates import as_template
    >>> as_template("position-damping", free_gain=True)
    PositionDamping(free_gain=True)
    >>> as_template(equation="x'' + f1(x)*x' + f2(x) = F")
    Equation(equation="x'' + f1(x)*x' + f2(x) = F")
    """
    check_equation_option(equation)
    if family in FAMILY_EQUATIONS and family != "separable" and equation is not None and \
            " ".join(str(equation).split()) == \
            " ".join(FAMILY_EQUATIONS[family].split()):
        equation = None  # a saved family template names its own equation
    if equation is not None and str(equation).strip():
        if family not in ("separable", "custom", None, ""):
            raise ConfigError(f"give either a family ({family!r}) or an equation, not both")
        return Equation(str(equation), **options)
    if family in _FAMILY_CLASSES:
        return _FAMILY_CLASSES[family](**options)
    if family == "custom":
        raise ConfigError("the custom family needs an equation, e.g. equation=\"x'' + a1*x' + f1(x) = F\"")
    raise ConfigError(f"unknown family {family!r}; available: {', '.join(FAMILY_NAMES)} "
                      "(or write your own with --equation)")


def get_template(family: str = "separable", *, equation: str | None = None, **kwargs) -> EquationTemplate:
    """The parsed structure of a family name, or of a user-written ``equation`` (family "custom").

    ``gauge=None`` takes the family's default anchors (separable: f2(0) = 0).

    Examples
    --------
    >>> from charcurves.templates import get_template
    >>> structure = get_template("first-order")
    >>> structure.family, structure.curve_names, structure.arguments
    ('first-order', ('f1', 'f2'), {'f1': 'x', 'f2': 'x'})
    """
    if family == "separable" and equation is None and kwargs.get("gauge") not in (None, "f1", "f2", ("f1",),
                                                                                  ("f2",), ["f1"], ["f2"]):
        raise ConfigError(f"gauge must name a curve to anchor at 0 (f1 or f2), got {kwargs.get('gauge')!r}")
    return as_template(family, equation=equation, **kwargs).structure()


def parse_equation(text: str, **kwargs) -> EquationTemplate:
    """Parse a user-written template (see :class:`EquationTemplate`); never evaluates the text as code.

    Examples
    --------
    >>> from charcurves.templates import parse_equation
    >>> structure = parse_equation("x'' + f1(x') + a1*x = F")
    >>> structure.curve_names, structure.scalar_names, structure.family
    (('f1',), ('a1',), 'custom')
    """
    return EquationTemplate(text, **kwargs)
