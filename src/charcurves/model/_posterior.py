"""What the posterior of a fit gives a user: pointwise credible bands of the curves, standard
deviations and correlations of the gain, free constants and scalars, in the same layout as the
bootstrap bands of :mod:`charcurves.selection` (``model.bands``) and in ``result.json``
``uncertainty``.

A posterior exists where the fit that produced the model computed one: the least-squares fits of
Poly-CC, parametric bases and any LinearCurve, and the sparse SINDy fits on the terms they kept
(``train._posterior_linear``); the gradient-trained fits, NN-CC and NN-CC+sym, by the Laplace
approximation (``train._posterior_network``); output-error refinements, with the segment initial
states marginalised (``objectives._posterior_oe``); post-SR closed forms' constants
(:func:`charcurves.fitting.closed_form_posterior`). It is saved with the model
(:class:`._posterior_store.StoredPosterior`). A model whose curves were replaced afterwards
without a posterior of its own has none, and asking for a band says so.
"""

from __future__ import annotations

from statistics import NormalDist
from typing import Any

import numpy as np

from .._errors import ConfigError

__all__ = ["model_posterior", "curve_band", "posterior_bands", "uncertainty_summary", "scalar_lines"]


def _level(level) -> float:
    if isinstance(level, bool) or not isinstance(level, (int, float)) or not (0.0 < float(level) < 1.0):
        raise ConfigError(f"band level must be between 0 and 1 (e.g. 0.95), got {level!r}")
    return float(level)


def model_posterior(model):
    """The posterior of ``model``'s fit, or None where the fit computed none or the curves changed since.

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.model import model_posterior
    >>> from charcurves.systems import get_system
    >>> model = cc.fit(cc.corrupt(get_system("duffing").simulate(), 20, seed=0), method="poly-cc")
    >>> model_posterior(model).kind
    'hac'
    >>> model.curves["f2"].shift += 1.0  # the curve is no longer the one the fit made
    >>> model_posterior(model) is None
    True
    """
    post = getattr(model, "posterior", None)
    if post is None or not post.check_against(model):  # a few points per curve: checked on every call
        return None
    return post


def sup_t_factor(G, var, level: float = 0.95, draws: int = 4000) -> float:
    """The sup-t multiplier of a Gaussian ``value + G u`` (``u`` standard normal) with pointwise
    variances ``var``: the ``level`` quantile of ``max |G u| / sd`` over seeded draws, so that ``value
    +- c sd`` holds every point at once with probability ``level``; ``inf`` where a variance is
    infinite, 1 where no point has any width (gauge points only).

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.model import sup_t_factor
    >>> bool(abs(sup_t_factor(np.eye(1), np.ones(1)) - 1.96) < 0.05)   # one point: the pointwise 1.96
    True
    >>> bool(1.96 < sup_t_factor(np.eye(50), np.ones(50)) < 3.5)   # 50 independent points: wider
    True
    """
    if not 0.0 < float(level) < 1.0 or int(draws) < 1:
        raise ConfigError(f"simultaneous_factor needs 0 < level < 1 and draws >= 1, got level={level!r}, "
                          f"draws={draws!r}")
    G, var = np.asarray(G, dtype=float), np.asarray(var, dtype=float)
    if not np.all(np.isfinite(var)):
        return float("inf")
    keep = var > 0
    if not np.any(keep):
        return 1.0
    sd = np.sqrt(var[keep])
    W = np.random.default_rng(0).standard_normal((G.shape[1], int(draws)))
    peaks = np.max(np.abs(G[keep] @ W) / sd[:, None], axis=0)
    return float(np.quantile(peaks, level))


def posterior_label(post) -> str:
    """The ``result.json`` ``uncertainty.method`` of a posterior (networks and output error name it
    ``label``; least-squares, post-SR and stored posteriors ``method``)."""
    return str(getattr(post, "label", None) or getattr(post, "method", "laplace (least squares)"))


def curve_band(model, name: str, z, level: float = 0.95) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(value, lo, hi)``: the pointwise ``level`` credible band of curve ``name`` at ``z``.

    Examples
    --------
    >>> import numpy as np
    >>> import charcurves as cc
    >>> from charcurves.systems import get_system
    >>> record = cc.corrupt(get_system("duffing").simulate(), 20, seed=0)
    >>> model = cc.fit(record, method="parametric", basis="f1=z; f2=z, z**3")
    >>> value, lo, hi = model.curve_band("f2", np.array([0.0, 1.0]))
    >>> bool(lo[0] == hi[0] == 0.0), bool(lo[1] < value[1] < hi[1])  # f2(0) = 0 is the gauge: no width
    (True, True)
    """
    level = _level(level)
    if name not in model.curves:
        raise ConfigError(f"unknown curve {name!r}; the model has {', '.join(model.curves)}")
    post = model_posterior(model)
    if post is None:
        raise ConfigError(f"this {model.method} model has no posterior (it exists for poly-cc, parametric, "
                          "sindy-cc, nn-cc and nn-cc+sym fits, by equation or output error, and post-SR closed "
                          "forms); use charcurves.selection.fit_ensemble for bootstrap bands")
    value, sd = post.curve_sd(name, z)
    unbounded = ~np.isfinite(sd)
    if np.any(unbounded):  # outside a stored posterior's range (or a direction the record leaves open) the
        # band is infinite; its centre is still the model's curve, not the value at the range's end
        value = np.where(unbounded, np.asarray(model.curves[name](np.asarray(z, dtype=float)), dtype=float), value)
    zq = NormalDist().inv_cdf(0.5 + level / 2.0)
    return value, value - zq * sd, value + zq * sd


def posterior_bands(model, *, level: float = 0.95, n_grid: int = 200) -> dict[str, dict]:
    """Bands of every curve on a grid over its training range, in the layout of
    :func:`charcurves.selection.curve_bands` (``kind`` "posterior (hac)"); {} without a posterior.

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.fitting import posterior_bands
    >>> from charcurves.systems import get_system
    >>> model = cc.fit(cc.corrupt(get_system("duffing").simulate(), 20, seed=0), method="poly-cc")
    >>> bands = posterior_bands(model, level=0.95)
    >>> sorted(bands), len(bands["f2"]["z"]), bands["f2"]["kind"]
    (['f1', 'f2'], 200, 'posterior (hac)')
    """
    level = _level(level)
    post = model_posterior(model)
    if post is None:
        return {}
    zq = NormalDist().inv_cdf(0.5 + level / 2.0)
    out = {}
    for name, curve in model.curves.items():
        z = np.linspace(curve.domain[0], curve.domain[1], int(n_grid))
        value, sd = post.curve_sd(name, z)
        out[name] = {"argument": curve.argument, "z": z.tolist(), "center": value.tolist(), "sd": sd.tolist(),
                     "lo": (value - zq * sd).tolist(), "hi": (value + zq * sd).tolist(), "level": level,
                     "members": 0, "kind": f"posterior ({post.kind})"}
    return out


def uncertainty_summary(model, *, level: float = 0.95) -> dict[str, Any] | None:
    """``result.json`` ``uncertainty``: how the posterior was made and each scalar's mean, sd and
    correlations, and each curve's band on 51 points of its range; None without a posterior.

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.fitting import uncertainty_summary
    >>> from charcurves.systems import get_system
    >>> record = cc.corrupt(get_system("duffing").simulate(), 20, seed=0)
    >>> u = uncertainty_summary(cc.fit(record, method="poly-cc", free_gain=True))
    >>> u["covariance"], sorted(u["scalars"]), sorted(u["curves"]["f2"])
    ('hac', ['gain'], ['hi', 'lo', 'sd', 'z'])
    >>> f"{u['scalars']['gain']['mean']:.3f} +- {u['scalars']['gain']['sd']:.3f}"
    '1.005 +- 0.004'
    """
    post = model_posterior(model)
    if post is None:
        return None
    stats = post.scalar_stats()
    zq = NormalDist().inv_cdf(0.5 + _level(level) / 2.0)
    curves = {}
    for name, curve in model.curves.items():
        z = np.linspace(curve.domain[0], curve.domain[1], 51)
        value, sd = post.curve_sd(name, z)
        curves[name] = {"z": z.tolist(), "sd": sd.tolist(), "lo": (value - zq * sd).tolist(),
                        "hi": (value + zq * sd).tolist()}
    return {"method": posterior_label(post), "covariance": post.kind, "hac_bandwidth": post.bandwidth,
            "noise_variance": post.noise_variance, "condition_number": post.condition_number, "level": level,
            "scalars": {k: {"mean": stats["mean"][k], "sd": stats["sd"][k]} for k in stats["names"]},
            "correlation": {"names": stats["names"], "matrix": stats["correlation"]}, "curves": curves,
            "warnings": post.warnings()}


def _pm(mean: float, sd: float) -> str:
    if not np.isfinite(sd):
        return f"{mean:.6g} ± inf"
    digits = max(2, int(np.floor(np.log10(abs(mean)))) - int(np.floor(np.log10(sd))) + 2) if sd > 0 and mean else 3
    return f"{mean:.{digits}g} ± {sd:.2g}"


def scalar_lines(model) -> list[str]:
    """summary.txt lines: each learned scalar with its posterior sd (1 sigma); a learned gain g on
    the force side also as the mass it means, M = 1/g.

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.fitting import scalar_lines
    >>> from charcurves.systems import get_system
    >>> record = cc.corrupt(get_system("duffing").simulate(), 20, seed=0)
    >>> model = cc.fit(record, method="poly-cc", free_gain=True)
    >>> print(scalar_lines(model)[0])
      gain g = 1.0045 ± 0.0037 (1 sd, posterior); 1/g = 0.9955 ± 0.0036
    """
    post = model_posterior(model)
    if post is None:
        return []
    stats = post.scalar_stats()
    lines = []
    for k in stats["names"]:
        m, s = stats["mean"][k], stats["sd"][k]
        label = "gain g" if k == "gain" else ("free constant b" if k == "offset" else k)
        line = f"  {label} = {_pm(m, s)} (1 sd, posterior)"
        if k == "gain" and model.template.free_gain and m != 0:
            line += f"; 1/g = {_pm(1.0 / m, s / m**2)}"
        lines.append(line)
    return lines
