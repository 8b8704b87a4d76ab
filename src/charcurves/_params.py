"""One parameter contract for every settings object of charcurves (scikit-learn's rule).

Curves, templates, differentiators, objectives, method presets and the estimator store their
constructor arguments under the same names and inherit :class:`Params`: ``get_params(deep=True)``
lists them, a part's own parameters as ``part__name``; ``set_params(part__name=value)`` is routed
to the part that owns it. ``sklearn.base.clone`` works on each of them (scikit-learn is not needed).
"""

from __future__ import annotations

import inspect
from typing import Any

from ._errors import ConfigError

__all__ = ["Params"]


class Params:
    """Base of settings objects: ``__init__`` stores its arguments as attributes of the same names.

    Examples
    --------
    >>> from charcurves.curves import Polynomial
    >>> from charcurves.templates import Separable
    >>> template = Separable(f1=Polynomial(degree=3))
    >>> template.set_params(f1__degree=5).get_params()["f1__degree"]
    5
    >>> template.set_params(f1__colour="red")
    Traceback (most recent call last):
    ...
    charcurves._errors.ConfigError: Polynomial has no parameter 'colour'; valid: degree, symmetry, rescaling, basis, expand_tol
    """

    def _param_names(self) -> list[str]:
        """The constructor's named arguments (``*args`` and ``**kwargs`` are not parameters)."""
        sig = inspect.signature(type(self).__init__)
        return [p.name for p in sig.parameters.values()
                if p.name != "self" and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]

    def get_params(self, deep: bool = True) -> dict[str, Any]:
        """``{name: value}`` of the constructor's arguments; with ``deep``, also ``part__name`` of
        every part that has parameters of its own."""
        out: dict[str, Any] = {}
        for name in self._param_names():
            value = getattr(self, name)
            out[name] = value
            if deep and hasattr(value, "get_params") and not isinstance(value, type):
                out.update({f"{name}__{k}": v for k, v in value.get_params(deep=True).items()})
        return out

    def set_params(self, **params: Any) -> Any:
        """Set parameters by name; ``part__name`` is set on the part (``self.part``) that owns it."""
        if not params:
            return self
        valid = self._param_names()
        nested: dict[str, dict[str, Any]] = {}
        direct: dict[str, Any] = {}
        for key, value in params.items():
            head, sep, rest = key.partition("__")
            if head not in valid:
                raise ConfigError(f"{type(self).__name__} has no parameter {head!r}; valid: {', '.join(valid)}")
            if sep:
                nested.setdefault(head, {})[rest] = value
            else:
                direct[head] = value
        for key, value in direct.items():  # a part given with its own parameters: the part first
            setattr(self, key, value)
        if direct:
            self._params_changed()
        for head, sub in nested.items():
            part = getattr(self, head)
            if part is None or isinstance(part, type) or not hasattr(part, "set_params"):
                first = next(iter(sub))
                raise ConfigError(f"{type(self).__name__}.{head} is {part!r}, which has no parameters of its own; "
                                  f"give {head}= an object first (e.g. set_params({head}=...)), then {head}__{first}")
            part.set_params(**sub)
        return self

    def _params_changed(self) -> None:
        """Called after ``set_params`` changed parameters of this object (subclasses re-check them)."""
