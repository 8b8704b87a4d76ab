"""Objectives of a fit: equation error and output error, as objects.

* :class:`EquationError` regresses the template's equation on the record's derivatives (given,
  or estimated by the differentiator): the paper's loss, fast, exact when the derivatives are.
* :class:`OutputError` starts from the equation-error fit and refits every curve, the gain, the
  constants and the initial state of each record segment to the free-run simulation of the
  measured states (multiple shooting). It is what a measured record needs: there only the state
  is measured, its derivatives are estimated from noisy data, and equation error inherits their
  errors -- a bias in the curves and in their arguments (errors in variables) -- while the free
  run fits the measurement itself.
"""

from __future__ import annotations

import inspect

import numpy as np

from .._errors import ConfigError
from .._params import Params

__all__ = ["Auto", "EquationError", "OutputError", "OBJECTIVES", "resolve_objective", "runs_output_error"]

#: Names accepted by ``objective=`` (and the CLI's ``--objective``).
OBJECTIVES = ("auto", "equation-error", "output-error")


class _Objective(Params):
    name = ""

    def __repr__(self) -> str:
        sig = inspect.signature(type(self).__init__)
        shown = [f"{n}={getattr(self, n)!r}" for n in self._param_names()
                 if getattr(self, n) != sig.parameters[n].default]
        return f"{type(self).__name__}({', '.join(shown)})"

    def __eq__(self, other) -> bool:
        return type(self) is type(other) and self.get_params() == other.get_params()


class EquationError(_Objective):
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


class OutputError(_Objective):
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
        the template couples equations (two-DOF), whose fits converge slowly. Every template gets
        Nielsen's damping rule (docs/measured-records.md, docs/zoo.md).
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


class Auto(_Objective):
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


#: ``refine_options`` of the older API -> OutputError parameters
_REFINE_KEYS = {"hold": "hold", "substeps": "substeps", "segment_length": "segment_length", "max_nfev": "max_iter",
                "time_budget": "time_budget"}


def runs_output_error(mode: str, estimated: bool, preset_name: str) -> bool:
    """Whether the fit of one record goes on from equation error to output error: when it is asked
    (``mode`` "output-error"), or with "auto" on a record whose derivatives were estimated (equation
    error on differentiated columns is biased by the noise on the state), except under the paper's
    preset (its protocol is equation error). ``mode`` is :func:`resolve_objective`'s."""
    return mode == "output-error" or (mode == "auto" and bool(estimated) and preset_name != "paper")


def resolve_objective(objective, refine=None, refine_options=None) -> tuple[str, OutputError]:
    """``(mode, OutputError settings)``: mode is "auto", "equation-error" or "output-error"."""
    if refine is not None:
        legacy = {"none": "equation-error", "output-error": "output-error", "auto": "auto"}
        if refine not in legacy:
            raise ConfigError(f"unknown refine {refine!r}; choose one of {', '.join(legacy)}")
        if objective not in ("auto", None) and not isinstance(objective, _Objective) and legacy[refine] != objective:
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
    if isinstance(objective, OutputError):
        settings = objective
        mode = "output-error"
    elif isinstance(objective, Auto):
        if objective.output_error is not None and not isinstance(objective.output_error, OutputError):
            raise ConfigError(f"Auto(output_error=...) takes an OutputError(...), got {objective.output_error!r}")
        settings = objective.output_error if objective.output_error is not None else settings
        mode = "auto"
    elif isinstance(objective, EquationError):
        mode = "equation-error"
    elif isinstance(objective, str) and objective in OBJECTIVES:
        mode = objective
    elif objective is None:
        mode = "auto"
    else:
        raise ConfigError(f"unknown objective {objective!r}; choose one of {', '.join(OBJECTIVES)}, EquationError(), "
                          "OutputError(...) or Auto(...)")
    settings.check()
    return mode, settings
