"""Model selection on a Ray cluster: the bootstrap ensembles of every candidate family fitted as Ray
tasks, one per family, and returned to the driver as saved models (bytes), like the sweeps' models.

A fitted model holds compiled closed forms that do not pickle, and a worker's disk is not the
driver's: the worker saves each model into its own temporary folder and returns the files; the
driver loads them from a temporary folder of its own. A saved and reloaded model evaluates bit for
bit as the fitted one (``tests/test_model_files.py``), so the loops see the same numbers as a
selection run here (tested on a two-node cluster in ``tests/test_cluster.py``).
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Mapping
from typing import Any

from ._executors import cancel_all, ray_session
from ._models import model_files, write_model_files

__all__ = ["ray_ensemble_fitter"]


def _fit_family(estimator, trajectories, n_members: int) -> list[dict]:
    """Worker side: the family's ensembles, each as ``{"point", "members": model files, "record", "kind"}``."""
    from ..fitting import fit_ensembles

    out = []
    for ens in fit_ensembles(estimator, trajectories, n_members, kind="bootstrap"):
        out.append({"point": model_files(ens.point), "members": [model_files(m) for m in ens.members],
                    "record": ens.record, "kind": ens.kind})
    return out


def _load(files: dict[str, bytes]):
    from ..model import load_model

    with tempfile.TemporaryDirectory(prefix="charcurves-remote-") as tmp:
        path = os.path.join(tmp, "model")
        write_model_files(path, files)
        return load_model(path)


def ray_ensemble_fitter(address: str | None = None, *, num_cpus: int | None = None,
                        init_kwargs: Mapping[str, Any] | None = None, threads: int = 1):
    """A ``fit`` for :func:`charcurves.selection.select_family` that fits each family's ensembles as
    one Ray task (``threads`` CPUs each) on the cluster at ``address`` (or ``RAY_ADDRESS``), or on a
    private Ray instance of ``num_cpus`` without one.

    Examples
    --------
    >>> from charcurves.experiments import ray_ensemble_fitter
    >>> fit = ray_ensemble_fitter("auto")   # connects only when called
    >>> callable(fit)
    True
    """

    def fit(estimators, trajectories, n_members):
        from ..fitting import Ensemble

        trajectories = list(trajectories)
        with ray_session(address, num_cpus, init_kwargs) as ray:
            task = ray.remote(num_cpus=threads, max_retries=0)(_fit_family)
            refs = [task.remote(est, trajectories, n_members) for est in estimators]
            try:
                shipped = ray.get(refs)
            except BaseException:
                cancel_all(ray, refs)
                raise
        return [[Ensemble(point=_load(e["point"]), members=[_load(m) for m in e["members"]], record=e["record"],
                          kind=e["kind"]) for e in family] for family in shipped]

    return fit
