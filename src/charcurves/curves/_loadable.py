"""The user-written representations that model files may rebuild, by class name.

Model files never import code: a saved ``LinearFittedCurve`` names its representation, and only the
classes put here by :func:`~charcurves.curves.register_curve` (which checks them) are rebuilt. Below
both the representations (``_base``) and the fitted curves (``_fitted``), which use the table.
"""

from __future__ import annotations

from .._errors import ModelFileError

__all__ = ["remember_curve", "registered_curve"]

_REGISTRY: dict[str, type] = {}


def remember_curve(cls: type) -> type:
    """Put a representation class in the table of loadable ones, under its class name."""
    _REGISTRY[cls.__name__] = cls
    return cls


def registered_curve(name: str) -> type:
    """The registered LinearCurve subclass of that name (ModelFileError when unknown)."""
    if name not in _REGISTRY:
        raise ModelFileError(f"the model uses the curve representation {name!r}, which is not registered in this "
                             "process; import its module and call charcurves.curves.register_curve on it before "
                             "loading")
    return _REGISTRY[name]
