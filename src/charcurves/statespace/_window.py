"""The benchmarks' initialisation window for models with hidden states.

The nonlinear benchmarks estimate a test record's initial state from its first N samples only and
count the RMSE after them. For a :class:`~._model.StateSpaceModel` the initial state holds
every ODE state, hidden ones included: :func:`estimate_window_state` fits it by the model's own free
run over the window (a small least-squares problem, ``scipy.optimize.least_squares``, one parameter
per ODE state); :func:`window_free_run_error` then free-runs the whole record from it and counts the
RMSE after the window (``validate --init-window N``).
"""

from __future__ import annotations

import itertools

import numpy as np

from .._errors import ConfigError

__all__ = ["check_window", "estimate_window_state", "window_free_run_error", "window_state"]

#: samples left after the window to count the RMSE on (as the separable family's ``validate``)
MIN_COUNTED = 16
#: hidden-state values tried per hidden entry before the least squares (grid over the curves' domains)
GRID = 7


def check_window(init_window, n: int) -> int:
    """The samples an initialisation window takes; ConfigError unless ``2 <= N <= n - 16`` (the
    separable family's rule and message, ``charcurves.simulate.free_run_error``)."""
    if isinstance(init_window, bool) or not isinstance(init_window, (int, np.integer)) or \
            not 2 <= int(init_window) <= n - MIN_COUNTED:
        raise ConfigError(f"the initialisation window must be a whole number of samples from 2 to {n - MIN_COUNTED} "
                          f"(the record has {n}; at least {MIN_COUNTED} are left to count the RMSE on), got "
                          f"{init_window!r}; give e.g. --init-window 100")
    return int(init_window)


def _runner(model, cols, dt, n):
    """``run(y0 (B, D)) -> (B, n, D)``: free runs of the first ``n`` samples from ``B`` initial states."""
    from ._simulate import _Simulated, simulate_states

    fm = model._forward()
    head = {k: np.asarray(v, dtype=float)[:n] for k, v in cols.items()}
    sub, hold = int(model.info["substeps"]), model.info["hold"]
    scalars0 = {k: float(v) for k, v in (model.info.get("scalars") or {}).items()}

    def run(y0):
        B = y0.shape[0]
        curves = [_Simulated(c, B) for c in model.curves.values()]
        gain = np.full(B, model.gain) if model.structure.free_gain else model.gain
        scalars = {k: np.full(B, v) for k, v in scalars0.items()}
        with np.errstate(all="ignore"):
            return simulate_states(fm, curves, gain, y0, head, dt, sub, hold, scalars=scalars)
    return fm, run


def _first_guess(model, fm, cols, dt, n):
    """Measured entries (and their derivatives) from a quadratic through the window's first samples,
    hidden entries at their fitted initial values; the scales of the parameters; the candidate
    values of each hidden entry (its fitted value and a grid over the domain of the curves of it)."""
    measured = model.info["measured"]
    y0 = np.array([float(model.initial_state.get(name, 0.0)) for name in fm.layout])
    scale = np.ones(fm.n_state)
    grids: dict[int, np.ndarray] = {}
    m = min(n, 8)
    for d, name in enumerate(fm.layout):
        base, _, k = name.partition("__d")
        if base in measured:
            x = np.asarray(cols[measured[base]], dtype=float)[:n]
            coef = np.polyfit(np.arange(m) * dt, x[:m], min(2, m - 1))
            y0[d] = float(np.polyval(np.polyder(coef, int(k or 0)), 0.0))
            size = float(np.std(np.gradient(x, dt) if k else x)) if n > 2 else 0.0
            scale[d] = size if size > 0 else max(abs(y0[d]), 1.0)
            continue
        lo, hi = [], []
        for c in model.curves.values():
            if c.argument == name:
                lo.append(float(c.domain[0]))
                hi.append(float(c.domain[1]))
        if lo:
            a, b = min(lo), max(hi)
            grids[d] = np.unique(np.concatenate([[y0[d]], np.linspace(a, b, GRID)]))
            scale[d] = max(0.5 * (b - a), 1e-12)
        else:
            scale[d] = max(abs(y0[d]), 1.0)
    return y0, scale, grids


def estimate_window_state(model, record, n_fit: int) -> dict[str, float]:
    """The initial state (every ODE state, hidden ones included) whose free run best fits the first
    ``n_fit`` samples of ``record``'s measured columns; no later sample is read.

    Hidden entries start from a grid over the range of the curves of that state (and its fitted
    initial value), the best of which (one batched free run) starts the least squares.

    Examples
    --------
    >>> from charcurves.fitting import estimate_window_state, fit_state_space
    >>> from charcurves.systems import TwoTank
    >>> from charcurves.templates import StateSpace
    >>> record = TwoTank().simulate(n_points=81, t_end=160.0, seed=0)
    >>> template = StateSpace("x1' = g*F - f1(x1); x2' = f1(x1) - f2(x2)", measured={"x2": "x"})
    >>> model = fit_state_space(template, record, n_starts=1, degree=2, schedule=(16,), max_iter=5, substeps=1)
    >>> state = estimate_window_state(model, record.slice(slice(20, 81)), 20)
    >>> sorted(state)  # every ODE state, the hidden x1 included
    ['x1', 'x2']
    """
    from ._simulate import record_table

    cols, dt = record_table(record, model.info["measured"], model.structure.forces)
    n = check_window(n_fit, len(cols["t"]))
    return window_state(model, cols, dt, n)


def window_state(model, cols: dict, dt: float, n: int) -> dict[str, float]:
    """:func:`estimate_window_state` on the columns of :func:`~._simulate.record_table` without the
    window's bounds check (``2 <= n <= len(cols["t"])``): the start of a free run that counts every sample."""
    from scipy.optimize import least_squares

    fm, run = _runner(model, cols, dt, n)
    y_start, scale, grids = _first_guess(model, fm, cols, dt, n)
    out_index = [fm.layout.index(s) for s in model.info["measured"]]
    target = np.stack([np.asarray(cols[c], dtype=float)[:n] for c in model.info["measured"].values()], axis=-1)
    spread = np.where(np.std(target, axis=0) > 0, np.std(target, axis=0), 1.0)

    def residuals(Y):  # (B, D) -> (B, n * O), diverging runs as large finite residuals
        X = run(Y)[:, :, out_index]
        r = (X - target[None]) / spread
        return np.clip(np.nan_to_num(r, nan=1e3, posinf=1e3, neginf=-1e3), -1e3, 1e3).reshape(Y.shape[0], -1)

    if grids:  # one batched run over the grid of hidden values, the best row starts the least squares
        keys = sorted(grids)
        cand = np.repeat(y_start[None], int(np.prod([grids[k].size for k in keys])), axis=0)
        for row, values in enumerate(itertools.product(*(grids[k] for k in keys))):
            cand[row, keys] = values
        cost = (residuals(cand) ** 2).sum(axis=1)
        y_start = cand[int(np.argmin(cost))]
    step = 1e-6

    def fun(q):
        return residuals((q * scale)[None])[0]

    def jac(q):  # forward differences, the D + 1 runs in one batch
        Y = np.repeat((q * scale)[None], fm.n_state + 1, axis=0)
        Y[1:] += np.diag(step * scale)
        R = residuals(Y)
        return ((R[1:] - R[0][None]) / step).T

    sol = least_squares(fun, y_start / scale, jac=jac, method="lm", xtol=1e-12, ftol=1e-12, max_nfev=200)
    return {name: float(v) for name, v in zip(fm.layout, sol.x * scale)}


def window_free_run_error(model, record, init_window: int) -> tuple[dict[str, float], dict[str, float]]:
    """The benchmarks' convention: the initial state from the first ``init_window`` samples only
    (:func:`estimate_window_state`), one free run of the whole record from it, the RMSE of each
    measured state counted after the window (inf when the run diverges).

    Returns
    -------
    rmse : dict of state to float
    initial_state : dict of ODE state to float
        The estimated state at the record's first sample (hidden states included).

    Examples
    --------
    >>> from charcurves.fitting import fit_state_space, window_free_run_error
    >>> from charcurves.systems import TwoTank
    >>> from charcurves.templates import StateSpace
    >>> record = TwoTank().simulate(n_points=81, t_end=160.0, seed=0)
    >>> template = StateSpace("x1' = g*F - f1(x1); x2' = f1(x1) - f2(x2)", measured={"x2": "x"})
    >>> model = fit_state_space(template, record, n_starts=1, degree=2, schedule=(16,), max_iter=5, substeps=1)
    >>> rmse, initial = window_free_run_error(model, record.slice(slice(20, 81)), init_window=20)
    >>> sorted(rmse), sorted(initial)
    (['x2'], ['x1', 'x2'])
    """
    from ._simulate import record_table

    cols, _ = record_table(record, model.info["measured"], model.structure.forces)
    skip = check_window(init_window, len(cols["t"]))
    initial = estimate_window_state(model, record, skip)
    sim = model.simulate(record, initial=initial)
    out = {}
    for state, column in model.info["measured"].items():
        err = sim[state][skip:] - np.asarray(cols[column], dtype=float)[skip:]
        out[state] = float(np.sqrt(np.mean(err ** 2))) if np.isfinite(err).all() else float("inf")
    return out, initial
