"""Uncertainty bands of fitted curves, from an ensemble of refits (:func:`charcurves.fitting.fit_ensemble`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .._errors import ConfigError
from ..fitting import Ensemble

__all__ = ["curve_bands", "attach_bands", "band_coverage"]


def curve_bands(ensemble: Ensemble, *, level: float = 0.95, n_grid: int = 200) -> dict[str, dict]:
    """Bands ``point ± z·sd`` of each curve over its training range.

    ``sd`` is the members' standard deviation at each grid point and ``z`` the two-sided normal
    quantile of ``level``; with few members a normal band is steadier than member quantiles.
    Returns ``{name: {"z", "lo", "hi", "center", "sd", "level", "members", "kind"}}`` (lists).

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.selection import curve_bands, fit_ensemble
    >>> from charcurves.systems import get_system
    >>> record = cc.corrupt(get_system("duffing").simulate(t_end=20.0, n_points=500), 20, seed=0)
    >>> bands = curve_bands(fit_ensemble(cc.CharacteristicCurves.from_method(method="poly-cc"), record, 4), level=0.95)
    >>> sorted(bands), len(bands["f2"]["z"]), bands["f2"]["members"]
    (['f1', 'f2'], 200, 4)
    """
    if not (0.0 < float(level) < 1.0):
        raise ConfigError(f"band level must be between 0 and 1 (e.g. 0.95), got {level!r}")
    from statistics import NormalDist

    zq = NormalDist().inv_cdf(0.5 + float(level) / 2.0)
    out = {}
    for name, curve in ensemble.point.curves.items():
        lo_d, hi_d = curve.domain
        z = np.linspace(lo_d, hi_d, int(n_grid))
        center = np.asarray(curve(z), dtype=float)
        values = ensemble.curve_values(name, z)
        sd = values.std(axis=0, ddof=1)
        out[name] = {
            "argument": curve.argument,
            "z": z.tolist(),
            "lo": (center - zq * sd).tolist(),
            "hi": (center + zq * sd).tolist(),
            "center": center.tolist(),
            "sd": sd.tolist(),
            "level": float(level),
            "members": len(ensemble.members),
            "kind": ensemble.kind,
        }
    return out


def attach_bands(model, bands: dict) -> None:
    """Keep ``bands`` with the model: ``result_dict`` writes them and ``plot_curves`` draws them.

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.selection import attach_bands, curve_bands, fit_ensemble
    >>> from charcurves.systems import get_system
    >>> record = cc.corrupt(get_system("duffing").simulate(t_end=20.0, n_points=500), 20, seed=0)
    >>> ensemble = fit_ensemble(cc.CharacteristicCurves.from_method(method="poly-cc"), record, 3)
    >>> attach_bands(ensemble.point, curve_bands(ensemble))
    >>> sorted(ensemble.point.bands)  # result_dict() writes them, plot_curves draws them
    ['f1', 'f2']
    """
    model.bands = bands


def band_coverage(bands: dict, truth: dict, *, names: Sequence[str] | None = None) -> dict[str, float]:
    """Fraction of grid points where the true curve lies inside the band, per curve.

    Only meaningful where the gauge of the truth matches the fit's (the separable family's
    f2(0) = 0 holds for the benchmark systems).

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.selection import band_coverage, curve_bands, fit_ensemble
    >>> from charcurves.systems import get_system
    >>> system = get_system("duffing")
    >>> record = cc.corrupt(system.simulate(), 20, seed=0)
    >>> bands = curve_bands(fit_ensemble(cc.CharacteristicCurves.from_method(method="poly-cc"), record, 4))
    >>> {name: cover > 0.5 for name, cover in band_coverage(bands, system.true_curves()).items()}
    {'f1': True, 'f2': True}
    """
    out = {}
    for name in names or bands:
        b = bands[name]
        z = np.asarray(b["z"])
        y = np.asarray(truth[name](z), dtype=float)
        out[name] = float(np.mean((y >= np.asarray(b["lo"])) & (y <= np.asarray(b["hi"]))))
    return out

