"""Units of work: which jobs of a sweep run together (batched networks, methods that share a fit)."""

from __future__ import annotations

import json
from collections.abc import Sequence

from .._errors import ConfigError
from ._runner import Job

__all__ = ["plan_units"]


def plan_units(jobs: Sequence[Job], *, batch: str | int = "level", max_batch: int | None = None) -> list[list[Job]]:
    """Group jobs into units of work: neural jobs of one (system, variant, method, noise target, preset, config,
    tag) and record length are batched (``batch="level"``: per SNR level; ``"all"``: across levels; an int: that
    many realisations at most; ``"none"``: no batching), other methods run one job per unit.

    A method that extends another's fit (:func:`charcurves.fitting.shared_fit_base`: "X+post-sr" and X,
    "sr-cc+refit" and "sr-cc") shares its unit with that method's jobs on the same records, so the work they
    have in common is done once (:func:`run_unit`).

    Examples
    --------
    >>> from charcurves.experiments import Sweep, plan_units
    >>> [len(u) for u in plan_units(Sweep(methods=["parametric", "nn-cc"], snr_db=[20], realizations=3).jobs())]
    [1, 1, 1, 3]
    >>> units = plan_units(Sweep(methods=["nn-cc", "nn-cc+post-sr"], snr_db=[20], realizations=2).jobs())
    >>> [[j.method for j in u] for u in units]
    [['nn-cc', 'nn-cc', 'nn-cc+post-sr', 'nn-cc+post-sr']]
    """
    from ..fitting import METHODS, shared_fit_base

    positive_int = isinstance(batch, int) and not isinstance(batch, bool) and batch >= 1
    if batch not in ("level", "all", "none") and not positive_int:
        raise ConfigError(f"batch must be 'level', 'all', 'none' or a positive int, got {batch!r}")
    cap = max_batch if max_batch is not None else (batch if isinstance(batch, int) else None)
    present = {j.method for j in jobs}
    groups: dict[tuple, list[Job]] = {}
    order: list[tuple] = []
    for j in jobs:
        base = shared_fit_base(j.method)
        family = base if base in present else j.method
        shared = _shared_config(j.config)
        neural = METHODS.get(j.method, {}).get("representation") == "neural"
        if not neural or batch == "none":
            k: tuple = ("single", j.system, j.variant, family, j.noise_on, float(j.snr_db), int(j.realization),
                        j.preset, shared, j.tag)
        else:
            k = (j.system, j.variant, family, j.noise_on, j.preset, shared, j.tag, j.n_points)
            if batch != "all":
                k = k + (j.snr_db,)
        if k not in groups:
            groups[k] = []
            order.append(k)
        groups[k].append(j)
    units = []
    for k in order:
        g = groups[k]
        if cap is None:
            units.append(g)
            continue
        # at most ``cap`` records a unit: the jobs of the same records (the methods sharing a fit) stay together
        records = list(dict.fromkeys((j.snr_db, j.realization) for j in g))
        for i in range(0, len(records), int(cap)):
            chunk = set(records[i:i + int(cap)])
            units.append([j for j in g if (j.snr_db, j.realization) in chunk])
    return units


def _shared_config(config: str) -> str:
    """A job's config without the settings of symbolic regression (those of post-SR apply after the shared fit)."""
    cfg = json.loads(config)
    fit = dict(cfg.get("fit") or {})
    fit.pop("sr_options", None)
    cfg["fit"] = fit
    return json.dumps(cfg, sort_keys=True, separators=(",", ":"))
