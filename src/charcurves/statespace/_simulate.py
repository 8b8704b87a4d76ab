"""The pieces of a state-space model's free runs: the record's columns, the shooting problem, the runs.

:func:`record_table` reads a record's columns for a template; :func:`build_problem` lays a record
out as the multiple-shooting problem of output error (:class:`~charcurves.objectives.ShootingProblem`);
:func:`simulate_states` runs it forward. Below :mod:`._model` (the fitted model) and :mod:`._window`
(its initial-state estimate), which both use them.
"""

from __future__ import annotations

import numpy as np

from .._errors import DataError

__all__ = ["build_problem", "record_table", "simulate_states"]


def record_table(record, measured: dict, forces) -> tuple[dict, float]:
    """The columns a state-space fit reads (``t``, the measured columns, the forcings) and the
    sample step; DataError naming a missing column or non-uniform sampling."""
    from ..data import MultiTrajectory, Trajectory

    if isinstance(record, Trajectory):
        cols = {"t": record.t, "x": record.x, "F": record.F}
    elif isinstance(record, MultiTrajectory):
        cols = {"t": record.t, **record.states, **record.forces}
    else:
        raise DataError(f"expected a Trajectory or MultiTrajectory, got {type(record).__name__}")
    cols = {k: np.asarray(v, dtype=float) for k, v in cols.items()}
    have = ", ".join(cols)
    for state, column in measured.items():
        if column not in cols or column in ("t", *forces):
            raise DataError(f"measured maps {state} to the column {column!r}, which the record lacks as a state; "
                            f"its columns are {have}: give e.g. measured={{'{state}': '{next(iter(cols.keys() - {'t'}), 'x')}'}}")
    for f in forces:
        if f not in cols:
            raise DataError(f"the template's forcing {f} is not a column of the record ({have}); rename the forcing "
                            "in the equation or give that column")
    steps = np.diff(cols["t"])
    dt = float(np.median(steps))
    if not dt > 0 or float(np.max(np.abs(steps - dt))) > 1e-3 * dt:
        raise DataError("a hidden-state fit needs uniform sampling (the free run is driven by the sampled input); "
                        "resample the record onto a uniform grid")
    return cols, dt


def build_problem(fm, structure, curves, free_gain: bool, gain: float, cols: dict, dt: float, sub: int, hold: str,
                  starts, L: int, out_index, meas, scale, continuity: float, scalars=()):
    """The shooting problem of ``curves`` (list of ``(name, parametrisation, center (B,), half (B,),
    shift (B,))``) on segments ``starts`` of ``L`` samples, fitting ``meas`` ``(S, L, O)``."""
    import torch

    from ..data import stage_inputs
    from ..objectives import CurveBlock, ShootingProblem

    dtype = torch.float64
    T = lambda a: torch.as_tensor(np.asarray(a, dtype=float), dtype=dtype)  # noqa: E731
    blocks = [CurveBlock(name, param, T(np.asarray(c)[:, None]), T(np.asarray(h)[:, None]),
                         T(np.ones((len(c), 1))), T(np.asarray(s)[:, None])) for name, param, c, h, s in curves]
    idx = starts[None, :] * sub + np.arange((L - 1) * sub)[:, None]
    inputs = {}
    for f in structure.forces:
        ua, um, ub = stage_inputs(np.asarray(cols[f], dtype=float), sub, hold)
        inputs[f] = tuple(T(a[idx]) for a in (ua, um, ub))
    t = np.asarray(cols["t"], dtype=float)
    frac = np.arange((L - 1) * sub) / sub
    tt = t[starts[None, :] + np.floor(frac).astype(int)[:, None]] + (frac - np.floor(frac))[:, None] * dt
    times = tuple(T(tt + c * dt / sub) for c in (0.0, 0.5, 1.0))
    return ShootingProblem(fm, blocks, list(scalars), [], free_gain, float(gain), inputs, times, T(meas), list(out_index),
                           T(scale), dt, sub, continuity, torch.as_tensor(np.diff(starts) == L - 1, dtype=torch.bool),
                           weight_decay=1e-10)


def simulate_states(fm, curves, gain, y0, cols, dt, sub, hold, segments=None, scalars=None) -> np.ndarray:
    """Every ODE state ``(B, n, D)``: one free run of the record from ``y0`` ``(B, D)``, or with
    ``segments = (y0 (B, S, D), starts, L)`` each segment from its own initial state; ``scalars``:
    name -> ``(B,)`` values of the template's scalars."""
    import torch

    n = len(cols["t"])
    D = fm.n_state
    if segments is None:
        ys, starts, L = np.asarray(y0, dtype=float)[:, None, :], np.array([0]), n
    else:
        ys, starts, L = segments
    B, S = ys.shape[0], starts.size
    specs = [(c.name, c.param(), c.center, c.half, getattr(c, "shift", np.zeros(B))) for c in curves]
    free = np.ndim(gain) > 0
    problem = build_problem(fm, fm.template, specs, free, float(np.mean(gain)) if not free else 1.0, cols, dt, sub,
                            hold, starts, L, list(range(D)), np.zeros((S, L, D)), np.ones(D), 0.0,
                            scalars=list(scalars or {}))
    parts = [torch.as_tensor(c.theta, dtype=torch.float64) for c in curves]
    parts += [torch.as_tensor(np.broadcast_to(np.asarray(v, dtype=float), (B,))[:, None].copy()) for v in
              (scalars or {}).values()]
    if free:
        parts.append(torch.as_tensor(np.asarray(gain, dtype=float)[:, None]))
    parts.append(torch.as_tensor(ys.reshape(B, -1), dtype=torch.float64))
    with torch.no_grad():
        X, _, _ = problem.simulate(torch.cat(parts, dim=1), need_jac=False)  # (B, S, L, D)
    X = X.double().numpy()
    out = np.full((B, n, D), np.nan)
    for s, a in enumerate(starts):
        out[:, a:a + L] = X[:, s]
    return out


class _Simulated:
    """A fitted curve in the form :func:`simulate_states` takes."""

    def __init__(self, curve, B: int = 1):
        from ..curves import LinearFittedCurve, LinearParametrisation, trainable

        self.name = curve.name
        if not isinstance(curve, LinearFittedCurve):  # a network or a closed form (one member, out_scale 1)
            refit = trainable(curve)
            self._param, self.theta = refit.param, np.repeat(refit.theta[:1], B, axis=0)
            if isinstance(refit.param, LinearParametrisation):  # a basis trains in units of its largest value
                self.theta = self.theta * refit.out_scale
            self.center, self.half = np.full(B, refit.center), np.full(B, refit.half_width)
            self.shift = np.full(B, refit.shift)
            return
        self._param = LinearParametrisation(curve.representation)
        self.center, self.half = np.full(B, curve.center), np.full(B, curve.half_width)
        self.shift = np.full(B, curve.constant + curve.shift)
        self.theta = np.repeat(curve.coefficients[None], B, axis=0)

    def param(self):
        return self._param
