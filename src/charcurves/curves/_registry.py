"""Fitted curves by kind: how model files name a curve class, and how they are read back."""

from __future__ import annotations

from typing import Any

from .._errors import ModelFileError
from ._fitted import BasisFittedCurve, FittedCurve, LinearFittedCurve, NeuralFittedCurve, SymbolicFittedCurve

__all__ = ["curve_from_spec", "register_curve_kind"]

# kind -> a FittedCurve subclass with a ``from_spec`` classmethod
_KINDS: dict[str, Any] = {"neural": NeuralFittedCurve, "basis": BasisFittedCurve, "symbolic": SymbolicFittedCurve,
                          "linear": LinearFittedCurve}


def register_curve_kind(cls) -> None:
    """Make a FittedCurve subclass loadable from model files (by its ``kind``).

    Examples
    --------
    >>> from charcurves.curves import SymbolicFittedCurve, curve_from_spec, register_curve_kind
    >>> class Checked(SymbolicFittedCurve):  # a closed form with its own kind in model files
    ...     kind = "checked-symbolic"
    >>> register_curve_kind(Checked)
    >>> spec, arrays = Checked("f2", "x", (-2.0, 2.0), "z**3").to_spec()
    >>> type(curve_from_spec(spec, arrays)).__name__
    'Checked'
    """
    _KINDS[cls.kind] = cls


def curve_from_spec(d: dict, arrays: dict) -> FittedCurve:
    """A fitted curve from its ``to_spec()`` description and arrays (how model files are read).

    Examples
    --------
    >>> from charcurves.curves import BasisFittedCurve, curve_from_spec
    >>> spec, arrays = BasisFittedCurve("f2", "x", (-2.0, 2.0), ["z", "z**3"], [-1.0, 1.0]).to_spec()
    >>> curve = curve_from_spec(spec, arrays)
    >>> type(curve).__name__, float(curve(2.0))
    ('BasisFittedCurve', 6.0)
    """
    kind = d.get("kind")
    if kind not in _KINDS:
        raise ModelFileError(f"unknown curve kind {kind!r} in the model file; it may come from a newer charcurves")
    return _KINDS[kind].from_spec(d, arrays)
