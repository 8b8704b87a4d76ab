"""The fitted state-space model with hidden states: its curves, free runs and initial states.

:class:`StateSpaceModel` is what :func:`~._fit.fit_state_space` returns; its free runs use
:mod:`._simulate` (re-exported here: :func:`record_table`, :func:`build_problem`,
:func:`simulate_states`) and start, by default, from :func:`~._window.estimate_window_state`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ._simulate import _Simulated, build_problem, record_table, simulate_states

__all__ = ["StateSpaceModel", "build_problem", "record_table", "simulate_states", "load_model", "METHOD",
           "FREE_RUN_STARTS", "START_WINDOW"]

#: how a free run of a record without a given initial state starts (``simulate(record, start=...)``):
#: ``"window"`` (default) the whole state, hidden entries included, fitted to the record's first
#: :data:`START_WINDOW` samples (:func:`~._window.estimate_window_state`); ``"first-samples"`` the
#: measured entries from a quadratic through the first 8 samples (derivatives by differentiating it),
#: hidden ones at their fitted initial values; ``"fitted"`` the fitted initial state (the training
#: record's own start)
FREE_RUN_STARTS = ("window", "first-samples", "fitted")
#: samples of the default start's window: the separable family's default (``validate`` without
#: ``--init-window``); on the grey-box cases 50 samples or fewer leave the two-DOF system's hidden
#: mass poorly pinned (benchmarks/results/greybox/PROVENANCE.md, section d2-start)
START_WINDOW = 128


class StateSpaceModel:
    """A state-space template fitted with hidden states (see :func:`~charcurves.fitting.fit_state_space`).

    Attributes
    ----------
    curves : dict
        Curve name -> fitted curve (callable on its argument), in the gauge ``info["gauge_conditions"]``.
    gain : float
    initial_state : dict
        The ODE state at the record's first sample (hidden states included), as estimated.
    info : dict
        ``start`` (which start of the fit ran), ``stages`` (segment length and loss per stage), ``hidden``,
        ``gauge_freedoms``, ``gauge_conditions``, ``free_run_rmse`` (one free run of the record from
        the default start, the state fitted to its first 128 samples, every sample counted;
        ``free_run_start`` says so), ``free_run_rmse_fitted_start`` (from :attr:`initial_state`),
        ``seconds``, ``cpu_seconds``.

    Examples
    --------
    >>> from charcurves.fitting import fit_state_space
    >>> from charcurves.systems import TwoTank
    >>> from charcurves.templates import StateSpace
    >>> record = TwoTank().simulate(n_points=81, t_end=160.0, seed=0)
    >>> template = StateSpace("x1' = g*F - f1(x1); x2' = f1(x1) - f2(x2)", measured={"x2": "x"})
    >>> model = fit_state_space(template, record, n_starts=1, degree=2, schedule=(16,), max_iter=5, substeps=1)
    >>> sorted(model.simulate(record)), model.initial_state["x1"]
    (['x1', 'x2'], 0.0)
    """

    def __init__(self, template, structure, curves: dict, gain: float, initial_state: dict, info: dict):
        self.template, self.structure = template, structure
        self.curves, self.gain = curves, float(gain)
        self.initial_state, self.info = dict(initial_state), dict(info)

    def _forward(self):
        from ..templates import ForwardModel

        return ForwardModel(self.structure)

    def simulate(self, record, initial: dict | None = None, start: str = "window") -> dict[str, np.ndarray]:
        """One free run over ``record``'s input from ``initial`` (every ODE state), or else from the
        start ``start`` estimates (:data:`FREE_RUN_STARTS`; default the whole state fitted to the
        record's first :data:`START_WINDOW` samples): every state."""
        fm = self._forward()
        cols, dt = record_table(record, self.info["measured"], self.structure.forces)
        y0 = self.start_state(record, start) if initial is None else \
            np.array([initial[n] for n in fm.layout], dtype=float)
        free = self.structure.free_gain
        gain = np.array([self.gain]) if free else self.gain
        scalars = {k: np.array([float(v)]) for k, v in (self.info.get("scalars") or {}).items()}
        X = simulate_states(fm, [_Simulated(c) for c in self.curves.values()], gain, y0[None], cols, dt,
                            int(self.info["substeps"]), self.info["hold"], scalars=scalars)[0]
        return {name: X[:, d] for d, name in enumerate(fm.layout)}

    def start_state(self, record, start: str = "window") -> np.ndarray:
        """The ODE state (in the forward model's layout) a free run of ``record`` starts from, as
        ``start`` (:data:`FREE_RUN_STARTS`) estimates it; reads the record's first samples only."""
        from .._errors import ConfigError

        if start not in FREE_RUN_STARTS:
            raise ConfigError(f"the free run's start must be one of {', '.join(FREE_RUN_STARTS)}, got {start!r}")
        fm = self._forward()
        cols, dt = record_table(record, self.info["measured"], self.structure.forces)
        y0 = np.array([self.initial_state[n] for n in fm.layout], dtype=float)
        n = len(cols["t"])
        if start == "fitted":
            return y0
        if start == "window" and n >= 2:
            from ._window import window_state

            state = window_state(self, cols, dt, min(START_WINDOW, n))
            return np.array([state[name] for name in fm.layout], dtype=float)
        m = min(8, n)
        for d, name in enumerate(fm.layout):
            base, _, k = name.partition("__d")
            if base in self.info["measured"]:
                x = np.asarray(cols[self.info["measured"][base]], dtype=float)[:m]
                y0[d] = np.polyval(np.polyder(np.polyfit(np.arange(m) * dt, x, min(2, m - 1)), int(k or 0)), 0.0)
        return y0

    def start_values(self, record, start: str = "window") -> dict[str, float]:
        """:meth:`start_state` as ODE state -> value (hidden states included)."""
        return dict(zip(self._forward().layout, self.start_state(record, start).tolist()))

    @staticmethod
    def start_description(start: str, n: int) -> str:
        """What ``start`` does on a record of ``n`` samples, in words (result.json, validate)."""
        if start == "window" and n >= 2:
            return (f"initial state (hidden states included) fitted to the first {min(START_WINDOW, n)} samples, "
                    "the RMSE over all")
        if start == "fitted":
            return "from the fitted initial state (the training record's start)"
        return "from the record's first samples, hidden states at their fitted initial values"

    def free_run_rmse(self, record, initial: dict | None = None, start: str = "window") -> dict[str, float]:
        """RMSE of one free run (``initial``, or ``start``: as :meth:`simulate`) against each measured
        column of ``record``, every sample counted (inf when it diverges)."""
        cols, _ = record_table(record, self.info["measured"], self.structure.forces)
        sim = self.simulate(record, initial, start=start)
        out = {}
        for state, column in self.info["measured"].items():
            err = sim[state] - cols[column]
            out[state] = float(np.sqrt(np.mean(err ** 2))) if np.isfinite(err).all() else float("inf")
        return out

    def summary(self) -> dict[str, Any]:
        """What ``result.json`` holds: the template, gain, initial state, gauges and the fit's report."""
        return {"method": METHOD, "equation": getattr(self.template, "written", self.structure.text), "gain": self.gain,
                "initial_state": self.initial_state,
                "curves": {n: {"argument": c.argument, "domain": list(c.domain)} for n, c in self.curves.items()},
                **{k: v for k, v in self.info.items()}}

    # ------------------------------------------------------------------ files
    def to_fitted(self):
        """The model as a :class:`~charcurves.model.FittedModel` (family ``state-space``), the form
        model files hold: the template as written with its measured map and hidden initial values,
        the curves, the gain, ``info["initial_state"]``, ``substeps`` and ``hold`` of the free run."""
        from ..model import FittedModel

        stages = self.info.get("stages") or []
        best = int(self.info.get("best_start", 0))
        last = stages[-1]["loss"] if stages else []  # post-SR refits the best start alone: one entry
        loss = float(last[best if best < len(last) else -1]) if last else float("nan")
        info = {**self.info, "initial_state": dict(self.initial_state)}
        return FittedModel(self.structure, METHOD, self.curves, self.gain, 0.0, loss, info)

    def save(self, directory) -> None:
        """Write the model files (``model.json`` and ``arrays.safetensors``, docs/model-format.md);
        :func:`~charcurves.load_model` reads them back as a StateSpaceModel whose free runs equal
        this one's to the last bit."""
        self.to_fitted().save(directory)

    @classmethod
    def from_fitted(cls, model) -> StateSpaceModel:
        """The StateSpaceModel a loaded model file of family ``state-space`` holds."""
        from .._errors import ModelFileError
        from ..templates import StateSpace

        info = dict(model.info)
        missing = [k for k in ("initial_state", "measured", "substeps", "hold") if k not in info]
        if missing:
            raise ModelFileError(f"the state-space model file lacks info.{missing[0]}; the model file is incomplete, "
                                 "re-fit the model")
        template = StateSpace.from_dict(model.template.to_dict())
        initial_state = {str(k): float(v) for k, v in info.pop("initial_state").items()}
        return cls(template, model.template, dict(model.curves), model.gain, initial_state, info)

    def __repr__(self) -> str:
        return f"StateSpaceModel({self.structure.text!r}, hidden={self.info.get('hidden')})"


#: ``method`` of a state-space model in its files and result.json.
METHOD = "state-space"


def load_model(directory):
    """Read a model written by ``save``: a :class:`StateSpaceModel` for a state-space template with
    hidden states, else the :class:`~charcurves.model.FittedModel` (as :func:`charcurves.model.load_model`).

    Examples
    --------
    >>> import os, tempfile
    >>> import charcurves as cc
    >>> from charcurves.systems import get_system
    >>> path = os.path.join(tempfile.mkdtemp(), "model")
    >>> cc.fit(get_system("duffing").simulate(), method="parametric", basis="f1=z; f2=z, z**3").save(path)
    >>> type(cc.load_model(path)).__name__
    'FittedModel'
    """
    from ..model import load_model as load_fitted

    model = load_fitted(directory)
    if model.template.family == "state-space":
        return StateSpaceModel.from_fitted(model)
    return model
