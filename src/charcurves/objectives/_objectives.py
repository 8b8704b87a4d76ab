"""Objectives of a fit: equation error, output error and the choice between them, as objects
(the interface they share: :class:`~charcurves.objectives.Objective`, in :mod:`._base`).

* :class:`EquationError` regresses the template's equation on the record's derivatives (given,
  or estimated by the differentiator): the paper's loss, fast, exact when the derivatives are.
* :class:`OutputError` starts from the equation-error fit and refits every curve, the gain, the
  constants and the initial state of each record segment to the free-run simulation of the
  measured states (multiple shooting). It is what a measured record needs: there only the state
  is measured, its derivatives are estimated from noisy data, and equation error inherits their
  errors -- a bias in the curves and in their arguments (errors in variables) -- while the free
  run fits the measurement itself.
* :class:`Auto` is equation error, then output error on the records whose derivatives were
  estimated (except under the paper's preset, whose protocol is equation error).

A new objective of the library is a subclass of ``Objective`` in a file of its own, registered by
adding its class to ``_REGISTRY`` below (which gives its name to ``objective=`` and ``--objective``).
"""

from __future__ import annotations

import numpy as np

from .._errors import ConfigError
from ..train import get_preset
from ._base import Objective
from ._output_error import output_error_fit

__all__ = ["Auto", "EquationError", "OutputError", "OBJECTIVES", "resolve_objective", "refine_output_error"]


class EquationError(Objective):
    """Fit the equation to the derivatives of the record (given or estimated).

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.systems import get_system
    >>> measured = cc.corrupt(get_system("duffing").simulate(t_end=20.0, n_points=500), 30, on="state", seed=0)
    >>> model = cc.fit(measured, method="parametric", basis="f1=z; f2=z, z**3", objective=cc.EquationError())
    >>> model.info["settings"]["objective"], model.curves["f2"].coefficients.round(2).tolist()
    ('equation-error', [-1.0, 1.0])
    """

    name = "equation-error"

    def __init__(self):
        pass

    def refines(self, estimated: bool, preset) -> bool:
        """Never: the equation-error start is the fit."""
        return False

    def refine(self, start, prepared, measured, *, preset, progress=None):
        return start


class OutputError(Objective):
    """Fit the free-run simulation of the template to the measured states (multiple shooting).

    Parameters
    ----------
    segment_length : int, optional
        Samples per shooting segment (default: chosen from the record, see docs/measured-records.md).
    continuity : float
        Weight of the continuity residuals joining consecutive segments (0: independent segments;
        large: one free run of the whole record).
    substeps : int, optional
        RK4 steps per sample interval (default: chosen from the record's samples per period).
    hold : {"linear", "zoh", "bandlimited"}
        The input between its samples.
    max_iter : int, optional
        Levenberg-Marquardt iterations at most; each member stops earlier once converged (see
        ``tol``). Default: 40 for templates of one equation whose curves enter additively (the
        separable family: more iterations let free networks fit the noise), 120 where a curve is
        multiplied by a state (van der Pol's ``f1(x) x'``, the first-order family's ``f2(x) x'``) or
        the template couples equations (two-DOF), whose fits converge slowly; those templates also
        get Nielsen's damping rule (docs/measured-records.md, docs/zoo-defaults.md).
    tol : float
        A member stops when the relative decrease of its loss summed over its last 4 iterations is
        below this, or at once at a step whose loss changed by less than this (relative) where the
        linear model predicts no larger decrease (MINPACK's ftol test): a refused step, or an
        accepted one after which no relevance decay moved by more than 1 %.
    max_segments : int
        Longer records use this many segments spread over the record (the rest is not simulated).
        256 segments of 64 samples are 16 320 samples: on the Silverbox's 65 062-sample split every
        coefficient comes within 2 % of the published value (k3 −1.66 %; with 64 segments −2.43 %)
        for an output-error stage about 4.5 times as long (docs/silverbox.md).
    time_budget : float
        Seconds; training stops at the next iteration after it is spent.
    bayesian : bool
        Bayesian regularisation (MacKay's evidence, re-estimated at every step): the network
        weights in the preset's groups, as the default equation-error training does, and every
        coefficient of a linear or closed-form curve in a group of its own (automatic relevance
        determination: terms the record does not support shrink to 0); otherwise a fixed tiny decay.

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.systems import get_system
    >>> measured = cc.corrupt(get_system("duffing").simulate(t_end=20.0, n_points=500), 30, on="state", seed=0)
    >>> objective = cc.OutputError(segment_length=16, substeps=1, max_iter=2)  # a short run
    >>> model = cc.fit(measured, method="parametric", basis="f1=z; f2=z, z**3", objective=objective)
    >>> model.info["output_error"]["status"], model.curves["f2"].coefficients.round(2).tolist()
    ('ok', [-1.0, 1.0])
    """

    name = "output-error"

    def __init__(self, segment_length: int | None = None, continuity: float = 10.0, substeps: int | None = None,
                 hold: str = "linear", max_iter: int | None = None, tol: float = 1e-6, max_segments: int = 256,
                 time_budget: float = 600.0, bayesian: bool = True):
        self.segment_length = segment_length
        self.continuity = continuity
        self.substeps = substeps
        self.hold = hold
        self.max_iter = max_iter
        self.tol = tol
        self.max_segments = max_segments
        self.time_budget = time_budget
        self.bayesian = bayesian

    def check(self) -> None:
        from ..data import HOLDS, check_hold

        def pos_int(name, value, low):
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
                raise ConfigError(f"OutputError {name} must be an integer >= {low}, got {value!r}")

        from .._bounds import check_number

        if self.segment_length is not None:
            check_number("segment_length", self.segment_length, label="OutputError segment_length (--segment-length)")
        if self.hold not in HOLDS:
            raise ConfigError(f"unknown input hold {self.hold!r}; choose one of {', '.join(HOLDS)}")
        check_hold(self.hold, 1 if self.substeps is None else self.substeps)
        if self.max_iter is not None:
            pos_int("max_iter", self.max_iter, 1)
        pos_int("max_segments", self.max_segments, 1)
        for name in ("continuity", "tol"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v) or v < 0:
                raise ConfigError(f"OutputError {name} must be a non-negative number, got {v!r}")
        b = self.time_budget
        if isinstance(b, bool) or not isinstance(b, (int, float)) or not b > 0:
            raise ConfigError(f"time_budget must be a positive number of seconds, got {b!r}")

    def refines(self, estimated: bool, preset) -> bool:
        """Always: output error is what was asked for, on every record."""
        return True

    def refine(self, start, prepared, measured, *, preset, progress=None):
        """Multiple shooting from the start (:func:`~charcurves.objectives.output_error_fit`); a model or
        record it cannot run on is an error (ConfigError/DataError), as output error was asked for."""
        return output_error_fit(start, prepared, measured, self, preset=preset, progress=progress, strict=True)

    def start_preset(self, preset, estimated: list[bool]):
        """Every member of a mean-combined ensemble start goes on to output error, which chooses the
        members afterwards (by AIC, where a start that fits the noise with more effective parameters
        loses): keep them all in the start (post-SR comes after output error, so a +post-sr fit keeps
        them too)."""
        return preset.replace(combine_tol=float("inf")) if preset.combine == "mean" else preset


class Auto(Objective):
    """Equation error, then output error on records whose derivatives were estimated (``objective="auto"``).

    Parameters
    ----------
    output_error : OutputError, optional
        The settings of the output-error stage (None: ``OutputError()``).

    Examples
    --------
    >>> from charcurves.fitting import Auto, OutputError
    >>> Auto(output_error=OutputError(hold="zoh")).get_params()["output_error__hold"]
    'zoh'
    """

    name = "auto"

    def __init__(self, output_error: OutputError | None = None):
        self.output_error = output_error

    def settings(self) -> OutputError:
        """The output-error stage's objective (``output_error``, or ``OutputError()``)."""
        return OutputError() if self.output_error is None else self.output_error

    def refines(self, estimated: bool, preset) -> bool:
        """On records whose derivatives were estimated (equation error on differentiated columns is
        biased by the noise on the state), except under the paper's preset (its protocol is
        equation error)."""
        return bool(estimated) and preset.name != "paper"

    def applied(self, estimated: bool, preset) -> str:
        return OutputError.name if self.refines(estimated, preset) else EquationError.name

    def refine(self, start, prepared, measured, *, preset, progress=None):
        """Output error with this objective's settings; a model or record it cannot run on keeps the
        equation-error start, with the reason in ``info["output_error"]`` and a warning."""
        return output_error_fit(start, prepared, measured, self.settings(), preset=preset, progress=progress,
                                strict=False)

    def start_preset(self, preset, estimated: list[bool]):
        """As :class:`OutputError`'s where every record goes on to output error, else the fit's."""
        if all(self.refines(e, preset) for e in estimated):
            return self.settings().start_preset(preset, estimated)
        return preset

    def check(self) -> None:
        super().check()
        if self.output_error is not None and not isinstance(self.output_error, OutputError):
            raise ConfigError(f"Auto(output_error=...) takes an OutputError(...), got {self.output_error!r}")
        self.settings().check()


#: The library's objectives by name: what ``objective="..."`` and the CLI's ``--objective`` build. A
#: new objective of the library adds its class here.
_REGISTRY: dict[str, type[Objective]] = {c.name: c for c in (Auto, EquationError, OutputError)}

#: Names accepted by ``objective=`` (and the CLI's ``--objective``).
OBJECTIVES = tuple(_REGISTRY)

#: ``refine_options`` of the older API -> OutputError parameters
_REFINE_KEYS = {"hold": "hold", "substeps": "substeps", "segment_length": "segment_length", "max_nfev": "max_iter",
                "time_budget": "time_budget"}


def resolve_objective(objective, refine=None, refine_options=None) -> Objective:
    """The objective object of an ``objective=`` setting (a name of :data:`OBJECTIVES`, None for
    "auto", or an :class:`Objective`), with the older ``refine=`` ("none" is equation error) and
    ``refine_options=`` (the output-error settings of a name; an object keeps its own), checked.

    Examples
    --------
    >>> from charcurves.objectives import resolve_objective
    >>> resolve_objective("output-error", refine_options={"hold": "zoh"}), resolve_objective(None, refine="none")
    (OutputError(hold='zoh'), EquationError())
    """
    if refine is not None:
        legacy = {"none": "equation-error", "output-error": "output-error", "auto": "auto"}
        if refine not in legacy:
            raise ConfigError(f"unknown refine {refine!r}; choose one of {', '.join(legacy)}")
        if objective not in ("auto", None) and not isinstance(objective, Objective) and legacy[refine] != objective:
            raise ConfigError("give the objective once: refine= is the older name of objective=")
        objective = legacy[refine] if objective in ("auto", None) else objective
    settings = OutputError()
    if refine_options is not None:
        if not isinstance(refine_options, dict):
            raise ConfigError(f"refine_options must be a dict such as {{'hold': 'linear'}}, got "
                              f"{type(refine_options).__name__}")
        unknown = sorted(set(refine_options) - set(_REFINE_KEYS))
        if unknown:
            raise ConfigError(f"unknown refine option {unknown[0]!r}; valid: {', '.join(_REFINE_KEYS)}")
        settings.set_params(**{_REFINE_KEYS[k]: v for k, v in refine_options.items()})
        settings.check()
    if objective is None:
        objective = "auto"
    if isinstance(objective, str) and objective in _REGISTRY:
        cls = _REGISTRY[objective]
        if cls is OutputError:
            objective = settings
        elif cls is Auto:
            objective = Auto(output_error=settings if refine_options is not None else None)
        else:
            objective = cls()
    elif isinstance(objective, Auto) and objective.output_error is None and refine_options is not None:
        objective = Auto(output_error=settings)
    elif not isinstance(objective, Objective):
        raise ConfigError(f"unknown objective {objective!r}; choose one of {', '.join(OBJECTIVES)}, EquationError(), "
                          "OutputError(...), Auto(...) or an instance of a subclass of Objective")
    objective.check()
    return objective


def refine_output_error(model, traj, *, hold: str = "linear", substeps: int = 4, segment_length: int = 256,
                        max_nfev: int = 60, time_budget: float = 600.0):
    """Output error of a fitted model on its record (the older entry point; see :func:`output_error_fit`).

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.fitting import refine_output_error
    >>> from charcurves.systems import get_system
    >>> clean = get_system("duffing").simulate(t_end=20.0, n_points=500)
    >>> record = cc.estimate_derivatives(cc.corrupt(clean, 30, on="state", seed=0))
    >>> start = cc.fit(record, method="parametric", basis="f1=z; f2=z, z**3")
    >>> model = refine_output_error(start, record, substeps=1, segment_length=32, max_nfev=2)  # a short run
    >>> model.info["output_error"]["status"], model.curves["f2"].coefficients.round(2).tolist()
    ('ok', [-1.0, 1.0])
    """
    settings = OutputError(segment_length=segment_length, substeps=substeps, hold=hold, max_iter=max_nfev,
                           time_budget=time_budget)
    settings.check()
    return output_error_fit(model, traj, traj, settings, preset=get_preset("default"), strict=True)
