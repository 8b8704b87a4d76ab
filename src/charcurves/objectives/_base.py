"""The interface of an objective: what a fit does after its equation-error start.

Every fit starts by equation error (the template's equation regressed on the record's given or
estimated derivatives, :mod:`charcurves.fitting`'s one fitting path). An :class:`Objective` then
says, for each record, whether it goes on from that start (:meth:`Objective.refines`) and how
(:meth:`Objective.refine`). :class:`~charcurves.objectives.EquationError` stops at the start,
:class:`~charcurves.objectives.OutputError` refits the free-run simulation to the measured states
(multiple shooting), :class:`~charcurves.objectives.Auto` chooses per record. A new objective is a
subclass with a ``name`` and these two methods; the estimator takes it as ``objective=`` with no
edit to the library (docs/architecture.md).
"""

from __future__ import annotations

import abc
import inspect
from typing import Any

from .._errors import ConfigError
from .._params import Params

__all__ = ["Objective"]


class Objective(Params, abc.ABC):
    """What a fit does after its equation-error start (subclass it for a new objective).

    A subclass sets ``name`` (the string ``result.json`` stores as ``settings.objective_requested``,
    and as ``settings.objective`` of the records it refines), stores its constructor's arguments
    under the same names (the parameter contract of :class:`~charcurves._params.Params`), and
    implements :meth:`refines` and :meth:`refine`. The estimator calls them for each record; Ctrl-C,
    post-SR (whose closed forms the objective refines again) and the settings record are the
    estimator's.

    Examples
    --------
    An objective that keeps the equation-error start and notes that it ran:

    >>> import charcurves as cc
    >>> from charcurves.systems import get_system
    >>> class Noted(cc.Objective):
    ...     name = "noted"
    ...     def refines(self, estimated, preset):
    ...         return True
    ...     def refine(self, start, prepared, measured, *, preset, progress=None):
    ...         start.info["noted"] = True
    ...         return start
    >>> model = cc.fit(get_system("duffing").simulate(), method="poly-cc", objective=Noted())
    >>> model.info["noted"], model.info["settings"]["objective"], model.info["settings"]["objective_requested"]
    (True, 'noted', 'noted')
    """

    #: The objective's name in ``result.json`` (``settings.objective``) and, for the library's own
    #: objectives, the string ``objective=`` and the CLI's ``--objective`` accept.
    name: str = ""

    @abc.abstractmethod
    def refines(self, estimated: bool, preset: Any) -> bool:
        """Whether the fit of a record goes on from its equation-error start.

        Parameters
        ----------
        estimated : bool
            The record's derivatives were estimated by the differentiator (False: given as columns).
        preset : TrainingPreset
            The fit's training preset (``preset.name`` is "default", "paper", ...).
        """

    @abc.abstractmethod
    def refine(self, start, prepared, measured, *, preset, progress=None):
        """The model of one record, fitted from its equation-error start (called where :meth:`refines`).

        Parameters
        ----------
        start : FittedModel
            The equation-error fit (or, after post-SR, the model of closed forms) to start from.
        prepared : Trajectory or MultiTrajectory
            The record with the derivatives the start used.
        measured : Trajectory or MultiTrajectory
            The record as given to ``fit``.
        preset : TrainingPreset
        progress : callable, optional
            The estimator's progress callback.

        Returns
        -------
        FittedModel
            The refined model (``start`` itself when there is nothing to change). A model with
            ``info["interrupted"]`` stops the stage for the records after it (Ctrl-C).
        """

    def applied(self, estimated: bool, preset: Any) -> str:
        """The objective that shaped a record's fit, as ``settings.objective`` stores it: this one's
        ``name`` where it refines the start, else "equation-error"."""
        return self.name if self.refines(estimated, preset) else "equation-error"

    def start_preset(self, preset: Any, estimated: list[bool]) -> Any:
        """The training preset of the equation-error start of the records (``estimated``: one flag
        each); the fit's own by default. An objective that chooses among the start's ensemble
        members itself may keep them all here."""
        return preset

    def check(self) -> None:
        """Refuse settings that cannot run (ConfigError naming the setting and the fix)."""
        if not isinstance(self.name, str) or not self.name.strip():
            raise ConfigError(f"objective {type(self).__name__} has no name; set the class attribute name "
                              "(the string result.json stores as settings.objective)")

    def __repr__(self) -> str:
        sig = inspect.signature(type(self).__init__)
        shown = [f"{n}={getattr(self, n)!r}" for n in self._param_names()
                 if getattr(self, n) != sig.parameters[n].default]
        return f"{type(self).__name__}({', '.join(shown)})"

    def __eq__(self, other) -> bool:
        return type(self) is type(other) and self.get_params() == other.get_params()

    __hash__ = None  # type: ignore[assignment]  # equal objects compare by settings (mutable)
