"""Model selection with its ensembles fitted as Ray tasks (a private one-CPU Ray instance): the fast
tier's check of `select --address`, whose run on a real two-node cluster is in the slow tier
(tests/test_cluster.py)."""

from __future__ import annotations

import pytest

import charcurves as cc
from charcurves.selection import select_family, split_record
from charcurves.systems import get_system

# Ray finds an instance running on this machine (/tmp/ray): every test that starts or joins one runs on
# one xdist worker, one after the other (--dist loadgroup in pyproject.toml)
pytestmark = pytest.mark.xdist_group("ray")


def test_select_with_ray_tasks_gives_the_report_of_a_selection_here(monkeypatch):
    ray = pytest.importorskip("ray", reason="ray is not importable (pip install ray)")
    from charcurves.experiments import ray_ensemble_fitter

    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    if ray.is_initialized():
        ray.shutdown()
    halves = split_record(cc.corrupt(get_system("duffing").simulate(t_end=20.0, n_points=500), 20, seed=0), 2)
    args = dict(method="poly-cc", n_members=3, snr_db=20, all_families=True, random_state=3)
    here = select_family(halves, ["separable", "position-damping"], **args)
    there = select_family(halves, ["separable", "position-damping"],
                          fit=ray_ensemble_fitter(num_cpus=1, init_kwargs={"object_store_memory": 80 * 1024**2}),
                          **args)
    assert not ray.is_initialized()  # the fitter shut down the instance it started
    assert here.accepted == there.accepted == "separable"
    mine, theirs = here.to_dict()["families"], there.to_dict()["families"]
    assert [f["family"] for f in theirs] == ["separable", "position-damping"]
    for a, b in zip(mine, theirs):
        assert a["verdict"] == b["verdict"] and a["rejected_by"] == b["rejected_by"]
        for loop in ("inner", "middle", "outer"):  # the models came back as files: the same numbers
            _same(a[loop]["statistic"], b[loop]["statistic"], (a["family"], loop))
            _same(a[loop]["figures"], b[loop]["figures"], (a["family"], loop))


def _same(a, b, where):
    """Equal structure, floats to 1e-9 relative, everything else exactly."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and sorted(a) == sorted(b), where
        for key in a:
            _same(a[key], b[key], (*where, key))
    elif isinstance(a, (list, tuple)):
        assert isinstance(b, (list, tuple)) and len(a) == len(b), where
        for k, (x, y) in enumerate(zip(a, b)):
            _same(x, y, (*where, k))
    elif isinstance(a, float):
        assert b == pytest.approx(a, rel=1e-9, abs=1e-12), where
    else:
        assert a == b, where
