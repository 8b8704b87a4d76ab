"""Benchmark systems ``x'' + f1(x') + f2(x) = A cos(Ω t)``: Duffing and stick-slip; and one system
per other family: van-der-pol (position-damping), first-order, two-dof (see ``system.family``);
:class:`CurveSystem` simulates any family with curves you give (the curve zoo's systems).

Examples
--------
>>> from charcurves.systems import get_system
>>> system = get_system("duffing")
>>> system.parameters()["alpha"]
-1.0
"""

from __future__ import annotations

from typing import Any

from .._errors import ConfigError
from ._base import MAX_SIMULATE_POINTS, MAX_SIMULATE_SPAN, BenchmarkSystem, sample_times
from ._duffing import Duffing
from ._stick_slip import StickSlip

__all__ = ["BenchmarkSystem", "Duffing", "StickSlip", "VanDerPolDamping", "FirstOrderSystem", "TwoDOF",
           "corrupt_forces", "get_system", "SYSTEM_NAMES", "MAX_SIMULATE_POINTS", "MAX_SIMULATE_SPAN",
           "sample_times", "CurveSystem", "CURVE_SYSTEM_FAMILIES", "TwoTank", "BoucWen"]

from ._curve_system import CURVE_SYSTEM_FAMILIES, CurveSystem  # noqa: E402
from ._families import FirstOrderSystem, TwoDOF, VanDerPolDamping, corrupt_forces  # noqa: E402
from ._greybox import BoucWen, TwoTank  # noqa: E402

_REGISTRY: dict[str, type[BenchmarkSystem] | type[TwoDOF]] = {
    "duffing": Duffing, "stick-slip": StickSlip, "van-der-pol": VanDerPolDamping, "first-order": FirstOrderSystem,
    "two-dof": TwoDOF}
#: Every name accepted by :func:`get_system`: the paper's separable benchmarks (duffing,
#: stick-slip; "stick_slip" is accepted too) and one system per other family (van-der-pol:
#: position-damping, first-order, two-dof). ``get_system(name).family`` tells which.
SYSTEM_NAMES = tuple(_REGISTRY)


def get_system(name: str, variant: str = "paper", **overrides: Any) -> BenchmarkSystem | TwoDOF:
    """Build a benchmark system by name.

    Parameters
    ----------
    name : {"duffing", "stick-slip", "van-der-pol", "first-order", "two-dof"}
        System name (``"stick_slip"`` and any letter case are accepted too).
    variant : str
        Named parameter set: ``"paper"`` or ``"scripts"`` (both systems), ``"smooth"``
        (stick-slip).
    **overrides
        Field values that replace the variant's, e.g. ``alpha=-1.05``, ``tolerance="scipy-default"``.

    Returns
    -------
    BenchmarkSystem or TwoDOF
        A :class:`TwoDOF` for ``"two-dof"`` (two degrees of freedom), a BenchmarkSystem otherwise.

    Raises
    ------
    ConfigError
        For an unknown name, variant or parameter.

    Examples
    --------
    >>> from charcurves.systems import SYSTEM_NAMES, get_system
    >>> SYSTEM_NAMES
    ('duffing', 'stick-slip', 'van-der-pol', 'first-order', 'two-dof')
    >>> system = get_system("stick_slip", variant="smooth")
    >>> system.name, system.friction
    ('stick-slip', 'tanh')
    >>> get_system("duffing", alpha=-1.05).parameters()["alpha"]
    -1.05
    """
    key = str(name).strip().lower().replace("_", "-") if isinstance(name, str) else name
    cls = _REGISTRY.get(key) if isinstance(key, str) else None
    if cls is None:
        raise ConfigError(f"unknown system {name!r}; choose one of {', '.join(map(repr, SYSTEM_NAMES))}")
    fields = [f for f in cls.__dataclass_fields__ if f != "variant"]
    unknown = sorted(set(overrides) - set(fields))
    if unknown:
        raise ConfigError(
            f"unknown {cls.name} parameter(s) {', '.join(map(repr, unknown))}; valid ones are {', '.join(fields)}"
        )
    return cls(variant=variant, **overrides)
