"""The estimator's older spelling, ``CharacteristicCurves(method="nn-cc", family=..., derivatives=...)``:
accepted for one release with a FutureWarning and turned into the same objects as
:meth:`~charcurves.fitting.CharacteristicCurves.from_method` builds."""

from __future__ import annotations

import inspect
import warnings
from typing import Any

from .._errors import ConfigError
from ._method_preset import MethodPreset
from ..objectives import EquationError, Objective, resolve_objective

__all__ = ["SHORTHANDS", "LEGACY_NAMES", "from_legacy", "cli_objective", "legacy_options"]

#: the method shorthands (MethodPreset's parameters besides the method's name)
SHORTHANDS = tuple(p for p in inspect.signature(MethodPreset.__init__).parameters if p not in ("self", "name"))
#: older names of the differentiator and the objective
LEGACY_NAMES = ("derivatives", "refine", "refine_options")


def from_legacy(method, differentiator, objective, legacy: dict[str, Any]):
    """``(MethodPreset, differentiator, objective)`` of the older keyword arguments (warns once)."""
    unknown = sorted(set(legacy) - set(SHORTHANDS) - set(LEGACY_NAMES))
    if unknown:
        raise TypeError(f"CharacteristicCurves got unexpected keyword argument(s) {', '.join(map(repr, unknown))}; "
                        f"the method shorthands are {', '.join(SHORTHANDS)} (of CharacteristicCurves.from_method)")
    given = ["method"] * (method is not None) + sorted(legacy)
    warnings.warn(f"CharacteristicCurves({'=..., '.join(given)}=...) is the older spelling and goes in the next "
                  "release; use CharacteristicCurves.from_method(...) (the same arguments; derivatives= is "
                  "differentiator=, refine= is objective=)", FutureWarning, stacklevel=3)
    if isinstance(method, MethodPreset):
        raise ConfigError("give the method once: a MethodPreset, or its name with the shorthands "
                          "(CharacteristicCurves.from_method)")
    derivatives = legacy.pop("derivatives", None)
    if derivatives is not None:
        if differentiator is not None and differentiator != derivatives:
            raise ConfigError("give the differentiator once: derivatives= is the older name of differentiator=")
        differentiator = derivatives
    objective = cli_objective(objective, legacy.pop("refine", None), legacy.pop("refine_options", None))
    return MethodPreset(method, **legacy), differentiator, objective


def legacy_options(options: dict[str, Any]) -> dict[str, Any]:
    """``CharacteristicCurves.from_method`` keywords of ``options``, where the older names
    ``derivatives=``, ``refine=`` and ``refine_options=`` still work for one release (with a
    FutureWarning) as ``differentiator=`` and ``objective=``: what the shortcuts that take the
    estimator's settings as keywords (``fit``, ``select_family``, ``detect_symmetry``) pass on.

    Examples
    --------
    >>> from charcurves.fitting import legacy_options
    >>> legacy_options({"method": "poly-cc", "differentiator": "spline"})
    {'method': 'poly-cc', 'differentiator': 'spline'}
    """
    old = [k for k in LEGACY_NAMES if k in options]
    if not old:
        return options
    warnings.warn(f"{', '.join(k + '=' for k in old)} is the older spelling and goes in the next release; use "
                  "differentiator= (for derivatives=) and objective= (for refine=, refine_options=)", FutureWarning,
                  stacklevel=3)
    options = dict(options)
    derivatives = options.pop("derivatives", None)
    if derivatives is not None:
        if options.get("differentiator") not in (None, derivatives):
            raise ConfigError("give the differentiator once: derivatives= is the older name of differentiator=")
        options["differentiator"] = derivatives
    options["objective"] = cli_objective(options.get("objective"), options.pop("refine", None),
                                         options.pop("refine_options", None))
    return options


def cli_objective(objective, refine: str | None = None, refine_options: dict | None = None):
    """The objective of the command line's ``--objective``, its older name ``--refine`` ("none" is
    equation error) and the output-error settings (``--refine-hold``...; ``max_nfev`` is ``max_iter``).

    Examples
    --------
    >>> from charcurves.fitting import cli_objective
    >>> cli_objective(None, "none"), cli_objective("auto", None, {"hold": "zoh"})
    ('equation-error', Auto(output_error=OutputError(hold='zoh')))
    """
    objective = "auto" if objective is None else objective
    if refine is None and refine_options is None:
        return objective
    resolved = resolve_objective(objective, refine, refine_options)
    if isinstance(objective, Objective):
        return objective  # the object wins, as before
    if refine_options is None or isinstance(resolved, EquationError):
        return resolved.name
    return resolved  # OutputError(...) or Auto(output_error=OutputError(...)) with the settings
