"""Sweeps on a real two-node Ray cluster (issue 25): the workers return rows and saved models (as bytes)
to the driver, which alone writes the output folder.

The head node has no CPUs (as on a production cluster), so every task runs on the other node. An
audit hook installed in every worker process of the cluster refuses any write under the output
folder; a control task shows that the hook does refuse one.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

ray = pytest.importorskip("ray", reason="ray is not importable (pip install ray): the cluster executor cannot be "
                                        "tested")

from charcurves.experiments import ResultsStore, Sweep, run_sweep  # noqa: E402
from charcurves.fitting import PRESETS  # noqa: E402

# Ray finds a cluster running on this machine (/tmp/ray): every test that starts or joins one runs on one
# xdist worker, one after the other (--dist loadgroup in pyproject.toml). The slow tier: a two-node
# cluster takes minutes of wall time; the fast tier checks the Ray executor's rows
# (tests/test_experiments.py) and a selection fitted as Ray tasks (tests/test_ray_select.py).
pytestmark = [pytest.mark.xdist_group("ray"), pytest.mark.slow]

TINY = PRESETS["default"].replace(n_starts=1, adam_steps=20, lm_max_iter=3)


def _forbid_writes_under(root: str):
    """A worker_process_setup_hook: an audit hook raising PermissionError for any write under ``root``."""
    def hook():
        import os as _os
        import sys as _sys

        prefix = _os.path.abspath(root) + _os.sep
        writes = {"os.mkdir", "os.rename", "os.replace", "os.remove", "os.rmdir", "os.symlink", "os.link",
                  "os.truncate", "os.chmod", "shutil.rmtree", "tempfile.mkstemp", "tempfile.mkdtemp"}

        def inside(path) -> bool:
            try:
                p = _os.path.abspath(_os.fsdecode(path))
            except TypeError:
                return False
            return p == prefix[:-1] or p.startswith(prefix)

        def audit(event, args):
            if event == "open" and args and isinstance(args[0], (str, bytes, _os.PathLike)):
                mode, flags = args[1], args[2] if len(args) > 2 else 0
                writing = (isinstance(mode, str) and any(c in mode for c in "wax+")) or \
                    (isinstance(flags, int) and flags & (_os.O_WRONLY | _os.O_RDWR | _os.O_CREAT))
                if writing and inside(args[0]):
                    raise PermissionError(f"a worker wrote into the driver's output folder: {args[0]}")
            elif event in writes and any(inside(a) for a in args if isinstance(a, (str, bytes, _os.PathLike))):
                raise PermissionError(f"a worker wrote into the driver's output folder ({event}: {args})")

        _sys.addaudithook(audit)

    return hook


@pytest.fixture(scope="module")
def cluster():
    from ray.cluster_utils import Cluster

    if ray.is_initialized():
        ray.shutdown()
    c = Cluster(initialize_head=True, head_node_args={"num_cpus": 0, "object_store_memory": 80 * 1024**2,
                                                      "include_dashboard": False})
    node = c.add_node(num_cpus=2, object_store_memory=80 * 1024**2)
    c.wait_for_nodes()
    try:
        yield c, node.node_id
    finally:
        if ray.is_initialized():
            ray.shutdown()
        c.shutdown()


def test_a_two_node_cluster_returns_rows_and_models_and_no_worker_writes_the_output(cluster, tmp_path):
    c, worker_node = cluster
    out = tmp_path / "out"
    runtime_env = {"worker_process_setup_hook": _forbid_writes_under(str(out)), "env_vars": {"OMP_NUM_THREADS": "1"}}
    sweep = Sweep(systems=["duffing"], methods=["parametric", "nn-cc"], snr_db=[20], realizations=2, preset=TINY)
    rep = run_sweep(sweep, out / "results.sqlite", executor="ray", address=c.address, save_models=str(out / "models"),
                    progress=False, ray_init_kwargs={"runtime_env": runtime_env})
    assert (rep.n_jobs, rep.n_ok, rep.n_failed) == (4, 4, 0) and not ray.is_initialized()
    from charcurves import load_model
    from charcurves.metrics import curve_errors
    from charcurves.systems import get_system

    truth = get_system("duffing").true_curves()
    with ResultsStore(out / "results.sqlite") as store:
        rows = store.rows()
    assert len(rows) == 4 and all(r["status"] == "ok" and r["error"] is None for r in rows)
    assert {r["extra"]["ray_node"] for r in rows} == {worker_node}  # the head has no CPU: all ran elsewhere
    assert sorted(os.listdir(out / "models")) == sorted(os.path.basename(r["extra"]["model_path"]) for r in rows)
    for r in rows:
        assert r["extra"]["model_path"].startswith("models/") and "model_files" not in str(r["extra"])
        model = load_model(out / r["extra"]["model_path"])  # the very model the worker scored
        err = curve_errors(model, truth)
        np.testing.assert_allclose([err["f1"], err["f2"]], [r["rmse_f1"], r["rmse_f2"]], rtol=1e-12)
    # a rerun against the cluster finds every job stored and starts no task
    again = run_sweep(sweep, out / "results.sqlite", executor="ray", address=c.address,
                      save_models=str(out / "models"), progress=False)
    assert (again.n_skipped, again.n_run) == (4, 0)


def test_the_audit_hook_refuses_a_worker_write_into_the_output_folder(cluster, tmp_path):
    """The control: without it, the test above could pass with a hook that refuses nothing."""
    c, _ = cluster
    out = tmp_path / "out"
    out.mkdir()
    ray.init(address=c.address, runtime_env={"worker_process_setup_hook": _forbid_writes_under(str(out))},
             logging_level="warning")
    try:
        @ray.remote(num_cpus=1, max_retries=0)
        def write(path):
            with open(path, "w") as fh:
                fh.write("x")

        with pytest.raises(ray.exceptions.RayTaskError, match="a worker wrote into the driver's output folder"):
            ray.get(write.remote(str(out / "f.txt")))
        ray.get(write.remote(str(tmp_path / "elsewhere.txt")))  # outside the folder: allowed
    finally:
        ray.shutdown()
    assert os.listdir(out) == [] and (tmp_path / "elsewhere.txt").read_text() == "x"


def test_benchmark_runs_on_the_cluster_named_by_ray_address(cluster, tmp_path, monkeypatch, capsys):
    """Issue 25: with RAY_ADDRESS set, `charcurves benchmark --executor ray` died with Ray's "num_cpus and
    num_gpus must not be provided"; now RAY_ADDRESS alone picks the Ray executor and that cluster."""
    import pandas as pd

    from charcurves.cli import main

    c, worker_node = cluster
    monkeypatch.setenv("RAY_ADDRESS", c.address)
    out = tmp_path / "bench"
    code = main(["benchmark", "--out", str(out), "--systems", "duffing", "--methods", "parametric", "--snr", "20",
                 "--realizations", "1", "--skip", "forward,lyapunov,miw,sensitivity,appendix-f", "--quiet"])
    assert code == 0, capsys.readouterr().err
    df = pd.read_csv(out / "results.csv")
    assert len(df) == 1 and df["status"].tolist() == ["ok"] and df["rmse_f2"].iloc[0] < 1e-2
    with ResultsStore(out / "results.sqlite") as store:
        (row,) = store.rows()
    assert row["extra"]["ray_node"] == worker_node and (out / row["extra"]["model_path"] / "model.json").is_file()
    assert not ray.is_initialized()


def test_select_on_the_cluster_gives_the_report_of_a_selection_here(cluster, tmp_path, monkeypatch, capsys):
    """Issue 25: `charcurves select --address` (and RAY_ADDRESS) fits every family's ensembles as Ray
    tasks on the cluster; the models come back as files, and the loops see the numbers of a run here."""
    import json

    from charcurves.cli import main
    from charcurves.data import corrupt
    from charcurves.selection import select_family
    from charcurves.systems import get_system

    c, _ = cluster
    system = get_system("van-der-pol")
    recs = [corrupt(system.simulate(x0=x0), 30.0, seed=s) for s, x0 in ((0, 1.0), (1, -0.5))]
    args = dict(method="poly-cc", n_members=3, all_families=True, all_loops=True, random_state=3)
    here = select_family(recs, ["separable", "position-damping"], **args)
    paths = []
    for k, rec in enumerate(recs):
        paths.append(str(tmp_path / f"r{k}.csv"))
        rec.to_csv(paths[-1])
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    code = main(["select", *paths, "--method", "poly-cc", "--members", "3", "--all", "--seed", "3",
                 "--address", c.address, "--out", str(tmp_path / "sel"), "--quiet"])
    assert code == 0, capsys.readouterr().err
    assert not ray.is_initialized()
    there = json.loads((tmp_path / "sel" / "selection.json").read_text())
    assert there["accepted"] == here.accepted == "position-damping"
    assert len(there["families"]) == 2
    for mine, theirs in zip(here.to_dict()["families"], there["families"]):
        assert mine["verdict"] == theirs["verdict"] and mine["rejected_by"] == theirs["rejected_by"]
        for loop in ("inner", "middle", "outer"):
            a, b = mine[loop]["figures"], theirs[loop]["figures"]
            for key, value in a.items():
                if isinstance(value, float):
                    assert b[key] == pytest.approx(value, rel=1e-9, abs=1e-12), (mine["family"], loop, key)
