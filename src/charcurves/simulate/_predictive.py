"""The predictive band of a free run: the fit's posterior propagated through the simulation, plus
the measurement noise of x.

``K`` parameter sets are drawn from the posterior (each curve ``f + G u``, ``G u`` interpolated
linearly on the stored grid, the gain and the free constant moved by the same ``u``;
:class:`charcurves.model.StoredPosterior`) and simulated in one
batch beside the fitted model (``u = 0``), from the same initial state. The band at each sample is
the fitted model's free run ``± z sqrt(var_K(x) + s^2)``: ``var_K`` the variance of the drawn runs,
``s^2`` the white-noise variance of the measured x (:func:`charcurves.data.noise_variance`). Beyond
a curve's training range a drawn curve keeps the offset of the range's end (the record says
nothing there). What the band leaves out: the uncertainty of the initial state (fitted to the first
samples) and any error of the model's structure. A band that holds much less of the record than its
level is the sign of the latter.
"""

from __future__ import annotations

from statistics import NormalDist

import numpy as np

from ..data import noise_variance, rk4_sampled, stage_inputs

__all__ = ["predictive_band", "PREDICTIVE_DRAWS"]

#: Parameter sets drawn for a predictive band.
PREDICTIVE_DRAWS = 100


def predictive_band(model, traj, x0: float, v0: float, *, hold: str = "linear", substeps: int = 4,
                    draws: int = PREDICTIVE_DRAWS, level: float = 0.95, seed: int = 0, skip: int = 0,
                    time_budget: float = 120.0) -> dict | None:
    """The ``level`` predictive band of ``model``'s free run on ``traj`` and the share of the measured
    x inside it (from sample ``skip`` on); None when the model has no posterior.

    Returns a dict: ``level``, ``draws``, ``diverged`` (drawn runs that diverged, left out),
    ``noise_sd`` (of the measured x), ``inside`` (the share), ``centre``, ``lo``, ``hi`` (arrays).

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.simulate import predictive_band
    >>> from charcurves.systems import get_system
    >>> system = get_system("duffing")
    >>> model = cc.fit(cc.corrupt(system.simulate(), 20, seed=0), method="parametric", basis="f1=z; f2=z, z**3")
    >>> val = cc.corrupt(system.simulate(t_end=10.0, n_points=251), 40, on="state", seed=1)
    >>> band = predictive_band(model, val, system.x0, system.v0, substeps=2, draws=40)
    >>> band["draws"], band["inside"] > 0.9
    (40, True)
    """
    from ..model import StoredPosterior, model_posterior

    post = model_posterior(model)
    stored = None if post is None else (post if isinstance(post, StoredPosterior)
                                        else StoredPosterior.from_posterior(post, model))
    if stored is None:
        return None
    K = int(draws)
    U = np.vstack([np.zeros((1, stored.rank)), stored.sample(K, seed)])  # row 0: the fitted model itself
    names, _, Gs, s_inf = stored.scalar_factor()
    open_dirs = [n for n, bad in zip(names, s_inf) if bad and n in ("gain", "offset")]
    factors = {n: stored.curve_factor(n, stored.curves[n][0]) for n in ("f1", "f2")}  # on the stored grids
    open_dirs += [n for n in ("f1", "f2") if np.any(factors[n][2])]
    if open_dirs:  # the record leaves a direction open: a finite band would be a silent narrow one
        n_t = len(np.asarray(traj.x))
        return {"level": float(level), "draws": 0, "diverged": 0, "noise_sd": float("nan"), "inside": float("nan"),
                "centre": np.full(n_t, np.nan), "lo": np.full(n_t, -np.inf), "hi": np.full(n_t, np.inf),
                "unbounded": open_dirs}
    g = float(model.gain) + (Gs[names.index("gain")] @ U.T if "gain" in names else 0.0)
    b = float(model.offset) + (Gs[names.index("offset")] @ U.T if "offset" in names else 0.0)
    f1, f2 = model.curves["f1"], model.curves["f2"]
    moves = {}
    for name in ("f1", "f2"):  # each draw's move G(z) u_k on the stored grid, interpolated linearly
        grid = np.asarray(stored.curves[name][0], dtype=float)
        Ht = np.ascontiguousarray((factors[name][1] @ U.T).T)  # (K + 1, grid points): draw k's move at k m + i
        moves[name] = (grid, grid[1:], grid[0], grid[-1], grid.size - 2, np.diff(grid), Ht.ravel(),
                       np.arange(K + 1) * grid.size)

    # Few numpy calls per evaluation, each on the whole batch (this runs 4 times a sub-step: 65 536
    # times for a 4096-sample span). The interval i of z in the grid, clamped to [0, m - 2] (NaN: m - 2),
    # is the count of grid[1:] below z; the numbers are those of clip, searchsorted and H[i, k].
    def curve(c, name, z):
        grid, inner, g0, g1, last, dg, flat, offsets = moves[name]
        zc = np.minimum(np.maximum(z, g0), g1)
        i = np.minimum(inner.searchsorted(zc), last)
        w = (zc - grid.take(i)) / dg.take(i)
        at = i + offsets
        return np.asarray(c(z), dtype=float) + flat.take(at) * (1 - w) + flat.take(at + 1) * w

    def accel(x, v, u):
        return g * u - curve(f1, "f1", v) - curve(f2, "f2", x) - b

    ua, um, ub = stage_inputs(np.asarray(traj.F, dtype=float), substeps, hold)
    with np.errstate(all="ignore"):
        xs, _, _ = rk4_sampled(accel, ua[:, None], um[:, None], ub[:, None], np.full(K + 1, float(x0)),
                               np.full(K + 1, float(v0)), float(traj.dt), substeps, time_budget=time_budget)
    centre = xs[:, 0]
    ok = np.all(np.isfinite(xs[:, 1:]), axis=0)
    s2 = noise_variance(np.asarray(traj.x, dtype=float))
    var = np.var(xs[:, 1:][:, ok], axis=1, ddof=1) if ok.sum() > 1 else np.full(centre.shape, np.inf)
    half = NormalDist().inv_cdf(0.5 + level / 2.0) * np.sqrt(var + s2)
    lo, hi = centre - half, centre + half
    x = np.asarray(traj.x, dtype=float)
    inside = float(np.mean((x[skip:] >= lo[skip:]) & (x[skip:] <= hi[skip:]))) if np.all(np.isfinite(centre)) \
        else float("nan")
    return {"level": float(level), "draws": K, "diverged": int(K - ok.sum()), "noise_sd": float(np.sqrt(s2)),
            "inside": inside, "centre": centre, "lo": lo, "hi": hi}
