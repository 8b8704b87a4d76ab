"""Reference fits for records with noise on x: the peer (PySINDy's weak form) and the limit.

Two functions that the state-noise benchmarks share:

* :func:`fit_pysindy_weak` -- PySINDy 2.x's weak formulation (``WeakPDELibrary`` around a
  ``PolynomialLibrary``), run as a practitioner would on a measured record (issue 26): the state
  is ``(x, v)`` with ``v`` a Savitzky-Golay velocity of the noisy ``x``, ``F`` is the control, the
  library is polynomial of degree 5 without interactions, the optimiser STLSQ. ``f1`` and ``f2``
  are read off the ``x''`` (i.e. ``v'``) equation as minus its terms in ``v`` and in ``x``; the
  ``F`` coefficient is read (``info["gain"]``) but not divided out: the gain is taken as 1.
* :func:`fit_parametric_oe` -- charcurves' parametric fit on the true basis, refined by output
  error (``objective="output-error"``, spectral derivatives for the start): the accuracy limit that
  the same record supports with a correct closed form.

Both return an object with ``.curves`` (``{"f1": callable with .domain, "f2": ...}``), so
``charcurves.metrics.curve_errors(result, system.true_curves())`` scores them like a fitted model.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

#: The true bases of the paper's systems (stick-slip: Coulomb friction, as the sweeps use).
TRUE_BASIS = {"duffing": "f1=z; f2=z, z**3", "stick-slip": "f1=z, sign(z); f2=z"}


@dataclasses.dataclass(frozen=True)
class PolyCurve:
    """``f(z) = Σ c_k z^k`` (``k`` = 1.. len(coef)) plus ``const``, on the training ``domain``."""

    coef: tuple[float, ...]
    domain: tuple[float, float]
    const: float = 0.0

    def __call__(self, z: Any) -> np.ndarray:
        z = np.asarray(z, dtype=float)
        out = np.full(z.shape, self.const)
        for k, c in enumerate(self.coef, start=1):
            out = out + c * z**k
        return out


@dataclasses.dataclass
class PeerFit:
    """Curves of a reference fit, scored with ``charcurves.metrics.curve_errors``."""

    curves: dict[str, PolyCurve]
    info: dict[str, Any]


def fit_pysindy_weak(record, *, degree: int = 5, threshold: float = 0.1, window: int = 31,
                     order: int = 3, K: int = 100, H_xt: float | None = None, p: int = 4,
                     seed: int = 0) -> PeerFit:
    """PySINDy weak-form SINDy with control on ``(x, v_SG)`` and ``F``; the curves of its x'' law.

    Parameters
    ----------
    record : charcurves.data.Trajectory
        Uniformly sampled record with ``t, x, F`` (``v, a`` are ignored).
    degree : int
        Degree of the polynomial library (no interactions; bias included, pysindy's default).
    threshold : float
        STLSQ threshold (pysindy's default 0.1).
    window, order : int
        Savitzky-Golay window and order of the velocity state (31/3: the paper's scripts).
    K, H_xt, p : int, float or None, int
        ``WeakPDELibrary`` settings: number of test-function subdomains, their half-width
        (``None``: pysindy's default, a 20th of the record) and the test-function degree.
    seed : int
        Seeds the subdomain centres (pysindy draws them from NumPy's global generator; its state
        is restored afterwards).

    Returns
    -------
    PeerFit
        ``curves["f1"](v) = -(terms in v)``, ``curves["f2"](x) = -(terms in x)``; the constant
        term of the x'' equation, if any, goes to ``f1`` (so ``f2(0) = 0`` as charcurves' gauge);
        ``info``: the ``F`` coefficient (``"gain"``, not divided out), every coefficient by
        feature name, and the seconds the fit took.
    """
    import time
    import warnings

    import pysindy as ps
    from scipy.signal import savgol_filter

    t = np.asarray(record.t, dtype=float)
    x = np.asarray(record.x, dtype=float)
    F = np.asarray(record.F, dtype=float)
    dt = float(np.median(np.diff(t)))
    t0 = time.perf_counter()
    v = savgol_filter(x, window, order, deriv=1, delta=dt)
    state = np.random.get_state()
    np.random.seed(seed)
    try:
        library = ps.WeakPDELibrary(
            function_library=ps.PolynomialLibrary(degree=degree, include_interaction=False,
                                                  include_bias=True),
            spatiotemporal_grid=t, K=K, H_xt=H_xt, p=p, include_bias=True,
        )
        model = ps.SINDy(feature_library=library, optimizer=ps.STLSQ(threshold=threshold))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            model.fit(np.column_stack([x, v]), t=t, u=F[:, None], feature_names=["x", "v", "u"])
    finally:
        np.random.set_state(state)
    seconds = time.perf_counter() - t0
    names = model.get_feature_names()
    row = np.asarray(model.coefficients())[1]  # the v' = x'' equation
    coefs = dict(zip(names, map(float, row)))

    def powers(var: str) -> tuple[float, ...]:
        out = [0.0] * degree
        for name, c in coefs.items():
            base, _, exp = name.partition("^")
            if base == var:
                out[int(exp or 1) - 1] = -c
        return tuple(out)

    const = -coefs.get("1", 0.0)
    curves = {
        "f1": PolyCurve(powers("v"), (float(v.min()), float(v.max())), const),
        "f2": PolyCurve(powers("x"), (float(x.min()), float(x.max()))),
    }
    gain = coefs.get("u", float("nan"))
    return PeerFit(curves, {"gain": gain, "coefficients": coefs, "seconds": seconds})


def fit_parametric_oe(record, basis: str, *, seed: int = 0, derivatives: str = "spectral"):
    """Parametric fit on ``basis`` (the true one: the limit), refined by output error.

    ``CharacteristicCurves.from_method(method="parametric", basis=basis, differentiator=derivatives,
    objective="output-error")``; returns the fitted model (``.curves``, ``.info``).
    """
    import charcurves as cc

    est = cc.CharacteristicCurves.from_method(method="parametric", basis=basis, differentiator=derivatives,
                                              objective="output-error", random_state=seed, threads=1)
    return est.fit(record).model_
