"""The benchmark's tables from a results frame: ensemble RMSE per level, the A-fits and performance
percentages, t_sep failure levels, costs and job counts (paper Tables 2-4, Figs. 9-13)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from . import _paper_values as paper

__all__ = ["ensemble_table", "a_fit_table", "performance_table", "tsep_failure_snr", "cost_table", "status_table",
           "mixed_terms_table"]

#: Stick-slip methods whose f-curves the paper fits with sqrt(bias² + (A η)²) (Table 3).
BIAS_LIMITED = ("sindy-cc", "poly-cc")
#: The scripts fit the stick-slip RMSE[x] of the NN variants at η ≤ 0.3 only (protocol §7.4).
NN_X_ETA_MAX = 0.3
NEURAL = ("nn-cc", "nn-cc+post-sr", "nn-cc+sym", "nn-cc+sym+post-sr")


def _eta(snr: float) -> float:
    return 0.0 if math.isinf(snr) else float(10.0 ** (-snr / 20.0))


def _snr_of(eta: float) -> float:
    """The SNR level (dB) of a noise fraction, the inverse of :func:`_eta` (rounded to 1e-6 dB)."""
    return math.inf if eta == 0 else round(-20.0 * math.log10(eta), 6) + 0.0


def _snr_text(s: float) -> str:
    """An SNR level as the report writes it ("∞" for the noise-free level)."""
    return "∞" if math.isinf(s) else f"{s:g}"


def _ok(df):
    return df[df["status"] == "ok"]


def ensemble_table(df, value: str, how: str = "mean") -> dict[tuple, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """``{(system, preset, method): (eta, ensemble, counts)}`` of one column over the ok rows,
    ``how`` as :func:`charcurves.metrics.ensemble_rmse` (levels in descending SNR order)."""
    from ..metrics import ensemble_by_level

    out: dict[tuple, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
    if value not in df.columns:  # e.g. rows without forward validation have no rmse_x
        return out
    ok = _ok(df)
    for key, g in ok.groupby(["system", "preset", "method"], sort=False):
        levels, ens, n = ensemble_by_level(g["snr_db"].to_numpy(float), g[value].to_numpy(float), how)
        out[key] = (np.array([_eta(s) for s in levels]), ens, n)
    return out


def a_fit_table(df, how: str = "mean") -> dict[tuple, dict[str, Any]]:
    """Slope-1 A and bias fits per (system, preset, method), the paper's Tables 2 and 3.

    Ensembles per level by ``how`` ("mean": the scripts, which reproduce the tables; "rms": the
    paper's Eq. 19). The scripts' masks are applied: SR at η ≤ 8 (Duffing) / ≤ 5 (stick-slip) and
    the stick-slip RMSE[x] of the NN variants at η ≤ 0.3.

    Returns
    -------
    dict
        ``{key: {"A": {"f1", "f2", "x"}, "bias": {"f1": (b, A), ...}, "levels": int}}`` (NaN where
        a term has no data); ``levels``: the most levels any term's fit used (after the masks).
    """
    from ..metrics import fit_bias, fit_slope_one

    out: dict[tuple, dict[str, Any]] = {}
    terms = {"f1": "rmse_f1", "f2": "rmse_f2", "x": "rmse_x"}
    tables = {t: ensemble_table(df, col, how) for t, col in terms.items()}
    keys = list(dict.fromkeys(k for tab in tables.values() for k in tab))
    for key in keys:
        system, _, method = key
        A, bias, nlev = {}, {}, 0
        for t in terms:
            eta, ens, n = tables[t].get(key, (np.array([]), np.array([]), np.array([])))
            eta_max = None
            if method == "sr":
                eta_max = paper.SR_FIT_ETA_MAX.get(system)
            if t == "x" and method in NEURAL and system == "stick-slip":
                eta_max = NN_X_ETA_MAX
            if eta.size == 0 or not np.isfinite(ens).any():
                A[t], bias[t] = float("nan"), (float("nan"), float("nan"))
                continue
            A[t] = fit_slope_one(eta, ens, eta_max=eta_max)
            bias[t] = fit_bias(eta, ens, eta_max=eta_max)
            # the levels the fit used (SR: only those within its mask, e.g. 59 of the full grid's 61)
            used = np.isfinite(ens) & (ens > 0) & (eta > 0) & (eta <= (np.inf if eta_max is None else eta_max))
            nlev = max(nlev, int(np.sum(used)))
        out[key] = {"A": A, "bias": bias, "levels": nlev}
    return out


def performance_table(fits: Mapping[tuple, Mapping[str, Any]]) -> dict[tuple, float]:
    """Performance % per (system, preset, method) against Parametric of the same system and
    preset (paper Figs. 9, 13); stick-slip SINDy-CC / Poly-CC use their bias-fit A, as the paper."""
    from ..metrics import PERFORMANCE_TERMS, performance_percent

    out = {}
    for (system, preset, method), f in fits.items():
        # Parametric does not depend on the training preset: any preset's rows serve as reference
        ref = fits.get((system, preset, "parametric")) or next(
            (v for (s, _, m), v in fits.items() if s == system and m == "parametric"), None)
        if ref is None:
            out[(system, preset, method)] = float("nan")
            continue
        a_m = _a_used(system, method, f)
        a_r = _a_used(system, "parametric", ref)
        terms = [t for t in PERFORMANCE_TERMS.get(system, ("f1", "f2"))
                 if _finite_pos(a_m.get(t)) and _finite_pos(a_r.get(t))]
        out[(system, preset, method)] = performance_percent(a_m, a_r, terms) if terms else float("nan")
    return out


def _a_used(system: str, method: str, f: Mapping[str, Any]) -> dict[str, float]:
    a = dict(f["A"])
    if system == "stick-slip" and method in BIAS_LIMITED:
        for t in ("f1", "f2"):
            a[t] = f["bias"][t][1]
        a.pop("x", None)  # the paper gives these methods only f-terms
    return a


def _finite_pos(v) -> bool:
    try:
        return v is not None and math.isfinite(float(v)) and float(v) > 0
    except (TypeError, ValueError):
        return False


def tsep_failure_snr(df, lyapunov_time: float) -> dict[tuple, float]:
    """Per (system, preset, method): the highest SNR level whose mean t_sep is below the Lyapunov
    time (the paper's "fails at SNR ≲ X"); ``-inf`` when no level fails, NaN without t_sep data."""
    out = {}
    ok = _ok(df)
    for key, g in ok.groupby(["system", "preset", "method"], sort=False):
        lv = g.groupby("snr_db")["t_sep"].mean().dropna().sort_index(ascending=False)
        if lv.empty:
            out[key] = float("nan")
            continue
        below = lv[lv < lyapunov_time]
        out[key] = float(below.index[0]) if len(below) else -math.inf
    return out


def cost_table(df) -> dict[tuple, dict[str, float]]:
    """Median fit time and median total job time (fit + validation) per (system, preset, method)."""
    out = {}
    ok = _ok(df)
    for key, g in ok.groupby(["system", "preset", "method"], sort=False):
        out[key] = {"fit_median": float(np.nanmedian(g["fit_seconds"])) if g["fit_seconds"].notna().any()
                    else float("nan"),
                    "job_median": float(np.nanmedian(g["seconds"])) if g["seconds"].notna().any() else float("nan"),
                    "total": float(np.nansum(g["seconds"])), "jobs": int(len(g))}
    return out


def status_table(df) -> dict[tuple, dict[str, int]]:
    """Jobs ok / failed and validation cases failed / run per (system, preset, method)."""
    out = {}
    for key, g in df.groupby(["system", "preset", "method"], sort=False):
        ok = g[g["status"] == "ok"]
        out[key] = {"jobs": int(len(g)), "failed_jobs": int((g["status"] != "ok").sum()),
                    "cases": int(np.nansum(ok["n_cases"].astype(float))) if len(ok) else 0,
                    "failed_cases": int(np.nansum(ok["n_failed_cases"].astype(float))) if len(ok) else 0}
    return out


def mixed_terms_table(df) -> dict[tuple, dict[str, Any]]:
    """Per (system, preset, method) whose rows record SR's mixed terms (``mixed_terms`` not NaN):
    ``{"runs": ok runs, "mixed": runs with a term mixing the curves' arguments, "levels": {snr: (mixed, runs)}}``.

    Examples
    --------
    >>> import pandas as pd
    >>> df = pd.DataFrame({"system": "duffing", "preset": "default", "method": "sr", "status": "ok",
    ...                    "snr_db": [20.0, 20.0, 0.0], "mixed_terms": [0.0, 2.0, 1.0]})
    >>> t = mixed_terms_table(df)[("duffing", "default", "sr")]
    >>> t["runs"], t["mixed"], t["levels"][0.0], t["levels"][20.0]
    (3, 2, (1, 1), (1, 2))
    """
    out: dict[tuple, dict[str, Any]] = {}
    if "mixed_terms" not in df.columns:
        return out
    ok = _ok(df)
    ok = ok[ok["mixed_terms"].notna()]
    for key, g in ok.groupby(["system", "preset", "method"], sort=False):
        levels = {float(s): (int((h["mixed_terms"] > 0).sum()), int(len(h)))
                  for s, h in g.groupby("snr_db", sort=False)}
        out[key] = {"runs": int(len(g)), "mixed": int((g["mixed_terms"] > 0).sum()),
                    "levels": dict(sorted(levels.items(), reverse=True))}
    return out
