"""Sweeps, the results store, forward validation sets and the ensemble metrics."""

import math
import os
import signal
import sqlite3
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from charcurves._errors import ConfigError
from charcurves.curves import SymbolicFittedCurve
from charcurves.data import corrupt
from charcurves.experiments import (
    KEY_COLUMNS,
    PAPER_SNR_DB,
    ResultsStore,
    Sweep,
    dataset_seed,
    evaluate_forward,
    make_validation_cases,
    paper_grid,
    plan_units,
    quick_grid,
    run_sweep,
    training_box,
)
from charcurves.fitting import PRESETS, FittedModel
from charcurves.metrics._ensemble import (
    curve_residuals,
    ensemble_by_level,
    ensemble_rmse,
    fit_bias,
    fit_slope_one,
    miw,
    performance_percent,
)
from charcurves.systems import get_system
from charcurves.templates import get_template

#: A neural preset that trains in a fraction of a second (the sweep machinery is under test, not accuracy).
TINY = PRESETS["default"].replace(n_starts=1, adam_steps=20, lm_max_iter=3)


def symbolic_model(f1, f2, domain=(-2, 2)):
    curves = {"f1": SymbolicFittedCurve("f1", "x'", domain, f1), "f2": SymbolicFittedCurve("f2", "x", domain, f2)}
    return FittedModel(get_template("separable"), "test", curves, 1.0, 0.0, 0.0)


def count_per_key(path):
    con = sqlite3.connect(path)
    try:
        return con.execute(f"SELECT COUNT(*), MAX(n) FROM (SELECT COUNT(*) AS n FROM results "
                           f"GROUP BY {', '.join(KEY_COLUMNS)})").fetchone()
    finally:
        con.close()


# ---------------------------------------------------------------------------- grids and seeds
def test_grids():
    g = paper_grid()
    assert g["realizations"] == 10 and len(g["snr_db"]) == 61
    assert g["snr_db"][0] == 40 and g["snr_db"][-1] == -20 and np.all(np.diff(g["snr_db"]) == -1)
    assert paper_grid(include_clean=True)["snr_db"][0] == math.inf
    assert PAPER_SNR_DB == g["snr_db"]
    assert quick_grid() == {"snr_db": (40.0, 20.0, 0.0), "realizations": 2}
    s = Sweep(systems=["duffing", "stick-slip"], methods=["parametric", "nn-cc"], **paper_grid(include_clean=True))
    assert len(s.jobs()) == 2 * 2 * 62 * 10


def test_noise_seeds_identical_across_methods_and_distinct_across_datasets():
    methods = ["parametric", "nn-cc", "nn-cc+sym", "sr-cc"]
    jobs = Sweep(systems=["duffing", "stick-slip"], methods=methods, snr_db=[40, 20, math.inf],
                 realizations=3).jobs()
    by_dataset = {}
    for j in jobs:
        seeds = (j.noise_seed, j.fit_seed, j.validation_seed)
        by_dataset.setdefault((j.system, j.snr_db, j.realization), set()).add(seeds)
    assert len(by_dataset) == 2 * 3 * 3
    assert all(len(v) == 1 for v in by_dataset.values())  # one seed triple per dataset, whatever the method
    noise = [next(iter(v))[0] for v in by_dataset.values()]
    assert len(set(noise)) == len(noise)
    # stable across processes and versions (a hash of the dataset's identity, not Python's hash())
    assert dataset_seed("noise", "duffing", "paper", "force", 20.0, 0) == 6385019594570048337
    assert dataset_seed("noise", "duffing", "paper", "force", 20, 0) == 6385019594570048337  # int or float SNR
    # validation cases are drawn afresh for each SNR level (the paper's protocol), shared by the methods
    v = {(j.system, j.snr_db, j.realization): j.validation_seed for j in jobs}
    assert all(j.validation_seed == v[(j.system, j.snr_db, j.realization)] for j in jobs)
    assert len(set(v.values())) == 2 * 3 * 3
    assert dataset_seed("validation", "duffing", "paper", None, 20.0, 0, bits=31) == \
        next(j.validation_seed for j in jobs if (j.system, j.snr_db, j.realization) == ("duffing", 20, 0))
    # the noisy datasets the methods see are the same arrays
    system = get_system("duffing")
    clean = system.simulate()
    a, b = (j for j in jobs
            if j.system == "duffing" and j.snr_db == 20 and j.realization == 1 and j.method in ("parametric", "sr-cc"))
    np.testing.assert_array_equal(corrupt(clean, 20, seed=a.noise_seed).F, corrupt(clean, 20, seed=b.noise_seed).F)


def test_sweep_validates_its_definition():
    from charcurves import ConfigError

    with pytest.raises(ConfigError, match="unknown method"):
        Sweep(methods=["nn-cc", "nope"])
    with pytest.raises(ConfigError, match="noise_on"):
        Sweep(noise_on="x")
    with pytest.raises(ConfigError, match="random_state"):
        Sweep(options={"random_state": 3})
    with pytest.raises(ConfigError, match="unknown system"):
        Sweep(systems=["pendulum"])


def test_base_seed_is_bounded_to_32_bits():
    assert Sweep(methods=["parametric"], base_seed=2**32 - 1).jobs()[0].noise_seed >= 0
    for bad in (2**32, -1, 99999999999999999999, 1.5, True):
        with pytest.raises(ConfigError, match=r"base_seed must be an integer from 0 to 4294967295 \(32 bits"):
            Sweep(methods=["parametric"], base_seed=bad)


@pytest.mark.xdist_group("ray")
def test_a_cluster_address_refuses_ray_init_sizes(tmp_path, monkeypatch):
    pytest.importorskip("ray")
    from charcurves.experiments._executors import ray_address

    monkeypatch.setenv("RAY_ADDRESS", "ray://head:10001")
    assert ray_address(None) == "ray://head:10001" and ray_address("auto") == "auto"
    with pytest.raises(ConfigError, match=r"ray_init_kwargs \['num_cpus'\] size a new Ray instance; a cluster "
                                          r"\('ray://head:10001'\) has its own size"):
        run_sweep(_tiny_sweep(), tmp_path / "r.sqlite", executor="ray", progress=False,
                  ray_init_kwargs={"num_cpus": 2})
    monkeypatch.setenv("RAY_ADDRESS", "")
    assert ray_address(None) is None


def test_neural_jobs_are_batched_per_level_and_others_run_alone():
    jobs = Sweep(methods=["parametric", "nn-cc"], snr_db=[40, 20], realizations=3).jobs()
    units = plan_units(jobs)
    nn = [u for u in units if u[0].method == "nn-cc"]
    par = [u for u in units if u[0].method == "parametric"]
    assert len(nn) == 2 and all(len(u) == 3 and len({j.snr_db for j in u}) == 1 for u in nn)
    assert len(par) == 6 and all(len(u) == 1 for u in par)
    assert [len(u) for u in plan_units(jobs, batch="all") if u[0].method == "nn-cc"] == [6]
    assert [len(u) for u in plan_units(jobs, batch="all", max_batch=4) if u[0].method == "nn-cc"] == [4, 2]
    assert all(len(u) == 1 for u in plan_units(jobs, batch="none"))


def test_stick_slip_parametric_gets_the_true_basis_by_default():
    s = Sweep(systems=["stick-slip"], methods=["parametric"], variant={"stick-slip": "scripts"})
    assert s.fit_options("stick-slip", "parametric")["basis"] == "f1=z, tanh(500*z); f2=z"
    assert Sweep(systems=["stick-slip"], methods=["parametric"]).fit_options("stick-slip", "parametric")["basis"] \
        == "f1=z, sign(z); f2=z"


# ---------------------------------------------------------------------------- the store
def _row(**kw):
    row = {"system": "duffing", "variant": "paper", "method": "parametric", "noise_on": "force", "snr_db": 20.0,
           "realization": 0, "preset": "default", "status": "ok", "rmse_f1": 1e-3, "rmse_f2": 2e-3}
    row.update(kw)
    return row


def test_store_one_row_per_key_and_nan_inf(tmp_path):
    path = tmp_path / "r.sqlite"
    with ResultsStore(path) as st:
        st.write(_row())
        st.write(_row(rmse_f1=5e-3))  # same key: replaced, not duplicated
        st.write(_row(snr_db=math.inf, rmse_f1=float("nan"), extra={"x": float("nan"), "arr": np.arange(2)}))
        st.write(_row(method="nn-cc", status="failed", error="ValueError: boom", rmse_f1=None))
        assert len(st) == 3
        df = st.to_dataframe()
        assert {"system", "method", "snr_db", "realization", "rmse_f1", "rmse_f2", "status"} <= set(df.columns)
        assert df.loc[df.method.eq("parametric") & df.snr_db.eq(20), "rmse_f1"].tolist() == [5e-3]
        assert np.isinf(df.snr_db).sum() == 1 and df.rmse_f1.isna().sum() == 2
        failed_key = ("duffing", "paper", "nn-cc", "force", 20.0, 0, "default", "{}", "")
        assert st.completed_keys(status="failed") == {failed_key}
        assert len(st.completed_keys()) == 3
        extra = [r["extra"] for r in st.rows() if r["snr_db"] == math.inf][0]
        assert extra == {"x": "nan", "arr": [0, 1]}
        st.to_csv(tmp_path / "r.csv")
        with pytest.raises(sqlite3.IntegrityError):  # the UNIQUE constraint itself, not only INSERT OR REPLACE
            st._con.execute("INSERT INTO results (system, variant, method, noise_on, snr_db, realization, preset, "
                            "status) VALUES ('duffing', 'paper', 'parametric', 'force', 20.0, 0, 'default', 'ok')")
        with pytest.raises(ValueError, match="status"):
            st.write(_row(status="done"))
    import pandas as pd

    csv = pd.read_csv(tmp_path / "r.csv")
    assert len(csv) == 3 and "rmse_f2" in csv.columns
    assert count_per_key(path) == (3, 1)


def _tiny_sweep(**kw):
    args = dict(systems=["duffing"], methods=["parametric"], snr_db=[30, 10], realizations=2, preset=TINY)
    args.update(kw)
    return Sweep(**args)


def test_resume_skips_stored_jobs_and_recomputes_only_deleted_ones(tmp_path):
    path = tmp_path / "r.sqlite"
    sweep = _tiny_sweep()
    rep = run_sweep(sweep, path, workers=1, progress=False)
    assert (rep.n_jobs, rep.n_run, rep.n_ok, rep.n_failed) == (4, 4, 4, 0)
    with ResultsStore(path) as st:
        before = {tuple(r[c] for c in KEY_COLUMNS): (r["id"], r["finished_at"]) for r in st.rows()}
    rep = run_sweep(sweep, path, workers=1, progress=False)
    assert (rep.n_skipped, rep.n_run) == (4, 0)
    with ResultsStore(path) as st:
        assert len(st) == 4
        victim = sorted(before)[1]
        assert st.delete(victim) == 1
    rep = run_sweep(sweep, path, workers=1, progress=False)
    assert (rep.n_skipped, rep.n_run) == (3, 1)
    with ResultsStore(path) as st:
        after = {tuple(r[c] for c in KEY_COLUMNS): (r["id"], r["finished_at"]) for r in st.rows()}
    assert set(after) == set(before)
    assert all(after[k] == before[k] for k in before if k != victim)
    assert after[victim] != before[victim]
    # more realisations extend the sweep: only the new ones run
    rep = run_sweep(_tiny_sweep(realizations=3), path, workers=1, progress=False)
    assert (rep.n_skipped, rep.n_run) == (4, 2)
    assert count_per_key(path) == (6, 1)


def test_failing_jobs_are_recorded_and_the_sweep_goes_on(tmp_path):
    path = tmp_path / "r.sqlite"
    sweep = _tiny_sweep(methods=["nn-cc", "parametric", "nn-cc+sym"], snr_db=[20], realizations=2,
                        method_options={"nn-cc": {"gauge": "f3"}, "parametric": {"basis": "f1=z; f2=bogus(z"}})
    rep = run_sweep(sweep, path, workers=1, progress=False)
    assert (rep.n_run, rep.n_ok, rep.n_failed) == (6, 2, 4)
    with ResultsStore(path) as st:
        df = st.to_dataframe()
        rows = st.rows()
    failed = df[df.status == "failed"]
    assert set(failed.method) == {"nn-cc", "parametric"}
    assert failed.error.str.contains("gauge|basis|bogus", regex=True).all()
    assert failed.rmse_f1.isna().all()
    assert all("traceback" in r["extra"] for r in rows if r["status"] == "failed")
    ok = df[df.status == "ok"]
    assert set(ok.method) == {"nn-cc+sym"} and np.isfinite(ok.rmse_f1).all()
    # failed jobs count as done, unless asked to retry them
    assert run_sweep(sweep, path, workers=1, progress=False).n_run == 0
    assert run_sweep(sweep, path, workers=1, progress=False, retry_failed=True).n_run == 4
    assert count_per_key(path) == (6, 1)


def test_batched_neural_jobs_match_separate_fits(tmp_path):
    sweep = _tiny_sweep(methods=["nn-cc+sym"], snr_db=[20], realizations=3)
    a = run_sweep(sweep, tmp_path / "a.sqlite", workers=1, progress=False)
    b = run_sweep(sweep, tmp_path / "b.sqlite", workers=1, progress=False, batch="none")
    assert a.n_units == 1 and b.n_units == 3
    cols = ["realization", "rmse_f1", "rmse_f2", "loss"]
    da = ResultsStore(tmp_path / "a.sqlite").to_dataframe()[cols].sort_values("realization").to_numpy()
    db = ResultsStore(tmp_path / "b.sqlite").to_dataframe()[cols].sort_values("realization").to_numpy()
    np.testing.assert_allclose(da, db, rtol=1e-7, atol=1e-12)


_KILL_SCRIPT = textwrap.dedent("""
    import os, signal, sys
    from charcurves.experiments import Sweep, run_sweep
    from charcurves.experiments import _store, _sweep

    path, moment, k = sys.argv[1], sys.argv[2], int(sys.argv[3])
    stored = [0]

    def kill():
        os.kill(os.getpid(), signal.SIGKILL)

    if moment == "mid-job":  # unit k + 1 has computed its row; the process dies before returning it
        real_run_unit = _sweep.run_unit
        def run_unit(unit, settings):
            rows = real_run_unit(unit, settings)
            if stored[0] == k:
                kill()
            return rows
        _sweep.run_unit = run_unit
    if moment == "mid-transaction":  # row k + 1 is inserted but not committed
        class Connection:
            def __init__(self, con):
                self._con = con
            def execute(self, sql, *args):
                if sql == "COMMIT" and stored[0] == k:
                    kill()
                return self._con.execute(sql, *args)
            def __getattr__(self, name):
                return getattr(self._con, name)
        real_init = _store.ResultsStore.__init__
        def init(self, *args, **kwargs):
            real_init(self, *args, **kwargs)
            self._con = Connection(self._con)
        _store.ResultsStore.__init__ = init

    def on_row(row):
        stored[0] += 1
        if moment == "after-commit" and stored[0] == k:
            kill()

    sweep = Sweep(systems=["duffing"], methods=["parametric"], snr_db=[40, 30, 20, 10, 0, -10], realizations=2)
    run_sweep(sweep, path, workers=1, progress=False, on_row=on_row if moment != "none" else None)
""")
KILL_AFTER = 5  # rows stored before the kill; the sweep has 12 jobs


@pytest.mark.parametrize("moment", ["after-commit", "mid-transaction", "mid-job"])
def test_sigkill_loses_nothing_and_duplicates_nothing(tmp_path, moment):
    """SIGKILL (no handler runs) at a moment the test controls, with 7 of 12 jobs still to do: right after
    row 5 is committed, inside the transaction of row 6 (inserted, not committed), or while job 6 has
    its result but before it is stored. Exactly 5 rows survive, none twice; a rerun runs the other 7."""
    path = str(tmp_path / "r.sqlite")
    script = tmp_path / "sweep.py"
    script.write_text(_KILL_SCRIPT)
    env = dict(os.environ, OMP_NUM_THREADS="1")
    proc = subprocess.run([sys.executable, str(script), path, moment, str(KILL_AFTER)], env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == -signal.SIGKILL, proc.stderr[-2000:]
    with ResultsStore(path) as st:  # opening recovers the WAL
        assert len(st) == KILL_AFTER and st.count("ok") == KILL_AFTER
    assert count_per_key(path) == (KILL_AFTER, 1)
    sweep = Sweep(systems=["duffing"], methods=["parametric"], snr_db=[40, 30, 20, 10, 0, -10], realizations=2)
    rep = run_sweep(sweep, path, workers=1, progress=False)
    assert (rep.n_skipped, rep.n_run, rep.n_ok) == (KILL_AFTER, 12 - KILL_AFTER, 12 - KILL_AFTER)
    assert count_per_key(path) == (12, 1)


# ---------------------------------------------------------------------------- forward validation
@pytest.mark.parametrize("name", ["duffing", "stick-slip"])
def test_validation_cases_keep_the_true_trajectory_inside_the_box(name):
    system = get_system(name)
    cases = make_validation_cases(system, 3, seed=7)
    assert len(cases) == 3 and cases.n_attempts >= 3
    box = training_box(system.simulate())
    assert cases.box == {"x": box["x"], "v": box["v"]}
    t_end, n = {"duffing": (80.0, 2000), "stick-slip": (40.0, 1000)}[name]
    from charcurves.experiments import VALIDATION_RANGES

    for c in cases:
        assert (c.t_end, c.n_points) == (t_end, n)
        for k, (lo, hi) in VALIDATION_RANGES[name].items():
            value = getattr(c, k)
            assert lo <= value <= hi and round(value, 3) == value
        tr = system.simulate(t_eval=c.t_eval, x0=c.x0, v0=c.v0, A=c.A, Omega=c.Omega)  # independent re-simulation
        assert box["x"][0] <= tr.x.min() and tr.x.max() <= box["x"][1]
        assert box["v"][0] <= tr.v.min() and tr.v.max() <= box["v"][1]
        if name == "duffing":  # draws are integrated stacked: the same trajectory to the solver's accuracy
            assert np.max(np.abs(tr.x[c.t_eval <= 20] - c.x_true[c.t_eval <= 20])) < 1e-6
            assert np.max(np.abs(tr.x - c.x_true)) < 0.05
        else:
            np.testing.assert_allclose(tr.x, c.x_true)
    again = make_validation_cases(system, 3, seed=7)
    assert [c.to_dict() for c in again] == [c.to_dict() for c in cases]
    assert [c.to_dict() for c in make_validation_cases(system, 3, seed=8)] != [c.to_dict() for c in cases]


def test_validation_attempts_are_bounded():
    system = get_system("duffing")
    tiny_box = {"x": (-0.01, 0.01), "v": (-0.01, 0.01)}
    with pytest.warns(UserWarning, match="only 0 of 2"):
        cases = make_validation_cases(system, 2, seed=0, box=tiny_box, max_attempts=3)
    assert len(cases) == 0 and cases.n_attempts == 3


def test_evaluate_forward_true_model_is_censored_and_a_bad_model_fails():
    system = get_system("duffing")
    cases = make_validation_cases(system, 2, seed=1)
    truth = symbolic_model("0.3*z", "z**3 - z")
    ev = evaluate_forward(truth, system, cases)
    assert ev.n_failed == 0 and ev.n_censored == 2
    assert ev.mean_t_sep == 80.0 and ev.mean_rmse_x < 1e-4
    assert all(c.censored and c.status == "ok" for c in ev.cases)
    wrong = symbolic_model("0.3*z", "-z**3 - 2*z")  # anti-restoring: runs away
    ev = evaluate_forward(wrong, system, cases)
    assert ev.n_failed == 2 and ev.n_censored == 0
    assert {c.status for c in ev.cases} <= {"left_box", "diverged"}
    assert all(np.isnan(c.rmse_x) and 0 < c.t_sep < 80 for c in ev.cases)
    assert ev.summary()["n_failed_cases"] == 2
    # a budget already spent: cases are recorded as timeouts, not run
    ev = evaluate_forward(truth, system, cases, time_budget=0.0)
    assert [c.status for c in ev.cases] == ["timeout", "timeout"]


def test_sweep_with_forward_cases_records_tsep_and_rmse_x(tmp_path):
    path = tmp_path / "r.sqlite"
    rep = run_sweep(_tiny_sweep(snr_db=[40], realizations=1), path, workers=1, progress=False, forward_cases=2)
    assert rep.n_ok == 1
    with ResultsStore(path) as st:
        (row,) = st.rows()
    assert row["n_cases"] == 2 and row["n_failed_cases"] == 0
    assert 0 < row["t_sep_mean"] <= 80 and row["rmse_x_mean"] >= 0
    assert len(row["extra"]["forward"]["cases"]) == 2
    assert '"forward"' in row["config"]  # the validation settings are part of the job's identity
    # cases drawn per level: rows of stores whose cases were shared across levels are other jobs
    assert '"seeds":"per-level"' in row["config"]
    rep = run_sweep(_tiny_sweep(snr_db=[40], realizations=1), path, workers=1, progress=False)
    assert rep.n_run == 1  # without forward cases it is another job


# ---------------------------------------------------------------------------- metrics
def test_ensemble_rmse_both_definitions():
    assert ensemble_rmse([3.0, 4.0], how="mean") == 3.5
    assert ensemble_rmse([3.0, 4.0], how="rms") == pytest.approx(math.sqrt(12.5))
    assert ensemble_rmse([1.0, 7.0, float("nan")], how="rms") == pytest.approx(5.0)
    assert math.isnan(ensemble_rmse([float("nan")]))
    lv, ens, n = ensemble_by_level([20, 20, math.inf, 0, 0, 0], [1, 3, 9, 2, 2, float("nan")], how="rms")
    assert lv.tolist() == [math.inf, 20, 0] and n.tolist() == [1, 2, 2]
    np.testing.assert_allclose(ens, [9.0, math.sqrt(5.0), 2.0])
    with pytest.raises(ValueError, match="how"):
        ensemble_rmse([1.0], how="median")


def test_slope_one_fit_by_hand():
    # log A = mean(log(0.02/0.1), log(0.08/1)) -> A = sqrt(0.2 * 0.08) = 0.12649...
    assert fit_slope_one([0.1, 1.0], [0.02, 0.08]) == pytest.approx(math.sqrt(0.016))
    # η = 0 (noise-free), non-positive and non-finite values are left out
    assert fit_slope_one([0.0, 0.1, 1.0, 2.0], [1e-5, 0.02, 0.08, float("nan")]) == pytest.approx(math.sqrt(0.016))
    # masks: the SR fits of the scripts stop at η <= 8
    eta = np.array([0.01, 1.0, 10.0])
    assert fit_slope_one(eta, [0.001, 0.1, 50.0], eta_max=8) == pytest.approx(0.1)
    assert fit_slope_one(eta, [0.001, 0.1, 50.0], mask=[True, False, False]) == pytest.approx(0.1)
    assert fit_slope_one(eta, [0.001, 0.1, 50.0], eta_min=0.5, eta_max=1.5) == pytest.approx(0.1)
    assert math.isnan(fit_slope_one([0.0], [1.0]))


def test_bias_fit_by_hand():
    eta = np.logspace(-2, 1, 31)
    b, A = fit_bias(eta, np.sqrt(0.2**2 + (0.3 * eta) ** 2))
    assert b == pytest.approx(0.2, rel=1e-6) and A == pytest.approx(0.3, rel=1e-6)
    # two points determine it: b² + A²·0.01 = 0.05, b² + A² = 1.04 -> A = 1, b = sqrt(0.04) = 0.2
    b, A = fit_bias([0.1, 1.0], [math.sqrt(0.05), math.sqrt(1.04)])
    assert b == pytest.approx(0.2, rel=1e-5) and A == pytest.approx(1.0, rel=1e-5)
    # bounds >= 0: a floor-free line gives b = 0
    b, A = fit_bias(eta, 0.5 * eta)
    assert b >= 0 and A == pytest.approx(0.5, rel=1e-4)


def test_performance_percent_reproduces_the_papers_values():
    # Duffing Table 2: Parametric 1.09/1.58, NN-CC 11.2/10.4 (x1e-2) -> 12.5 %
    p = performance_percent({"f1": 11.2, "f2": 10.4}, {"f1": 1.09, "f2": 1.58}, "duffing")
    assert p == pytest.approx(50 * (1.09 / 11.2 + 1.58 / 10.4)) and round(p, 1) == 12.5
    # Stick-slip Table 3: Parametric 0.061/0.028/0.065, NN-CC 0.549/0.514/0.336 -> 12.0 %
    p = performance_percent({"f1": 0.549, "f2": 0.514, "x": 0.336}, {"f1": 0.061, "f2": 0.028, "x": 0.065},
                            "stick-slip")
    assert p == pytest.approx(100 / 3 * (0.061 / 0.549 + 0.028 / 0.514 + 0.065 / 0.336))
    assert round(p, 1) == 12.0
    # SINDy-CC of stick-slip has only f terms
    p = performance_percent({"f1": 0.2, "f2": 0.1}, {"f1": 0.02, "f2": 0.02, "x": 0.06}, "stick-slip")
    assert p == pytest.approx(15.0)


def test_miw_by_hand():
    z = [0.0, 0.005, 0.03, 0.031, 0.029, 0.3]
    r = [1.0, 3.0, 0.0, 1.0, 2.0, 7.0]
    res = miw(z, r)
    # bins: 0 -> {1, 3} range 2; 1 -> {0, 1, 2} range 2; 10 -> {7} range 0
    assert res.n_bins == 3 and res.counts.tolist() == [2, 3, 1]
    assert res.miw_range == pytest.approx(4.0 / 3.0)
    # half-widths t_{0.995,n-1} * s / sqrt(n): 63.6567 * sqrt(2)/sqrt(2); 9.92484 * 1/sqrt(3); one-point bin left out
    assert res.miw_99 == pytest.approx((63.656741 + 9.924843 / math.sqrt(3)) / 2, rel=1e-6)
    # datasets are pooled
    pooled = miw([np.array(z[:3]), np.array(z[3:])], [np.array(r[:3]), np.array(r[3:])])
    assert pooled.miw_range == res.miw_range and pooled.miw_99 == res.miw_99


def test_curve_residuals_at_training_points():
    system = get_system("duffing")
    clean = system.simulate()
    model = symbolic_model("0.3*z", "z**3 - 1.1*z")
    x, res = curve_residuals(model, clean, system.true_curves(), "f2")
    np.testing.assert_allclose(x, clean.x)
    np.testing.assert_allclose(res, -0.1 * clean.x, atol=1e-12)


# ---------------------------------------------------------------------------- executors
def _same_rows(path_a, path_b):
    cols = ["system", "method", "snr_db", "realization", "rmse_f1", "rmse_f2", "gain", "loss", "t_sep_mean",
            "rmse_x_mean", "status"]
    a = ResultsStore(path_a).to_dataframe()[cols].sort_values(cols[:4]).reset_index(drop=True)
    b = ResultsStore(path_b).to_dataframe()[cols].sort_values(cols[:4]).reset_index(drop=True)
    assert len(a) == len(b) > 0
    import pandas as pd

    pd.testing.assert_frame_equal(a, b, check_exact=True)


@pytest.mark.xdist_group("ray")  # beside the cluster tests, never at the same time (tests/test_cluster.py)
def test_ray_executor_gives_the_same_rows_as_the_local_one(tmp_path):
    try:
        import ray
    except ImportError:
        pytest.skip("ray is not importable (pip install ray) - the Ray executor cannot be tested")
    sweep = _tiny_sweep(methods=["parametric", "nn-cc"], snr_db=[20], realizations=2)
    run_sweep(sweep, tmp_path / "local.sqlite", workers=1, progress=False, forward_cases=1)
    if ray.is_initialized():
        ray.shutdown()
    rep = run_sweep(sweep, tmp_path / "ray.sqlite", executor="ray", workers=1, progress=False, forward_cases=1,
                    ray_init_kwargs={"object_store_memory": 100 * 1024**2})
    assert rep.n_ok == 4 and not ray.is_initialized()  # it shut down the instance it started
    _same_rows(tmp_path / "local.sqlite", tmp_path / "ray.sqlite")


@pytest.mark.slow
def test_process_pool_gives_the_same_rows_as_the_driver(tmp_path):
    sweep = _tiny_sweep(methods=["parametric", "nn-cc"], snr_db=[20, 0], realizations=2)
    run_sweep(sweep, tmp_path / "a.sqlite", workers=1, progress=False, forward_cases=1)
    rep = run_sweep(sweep, tmp_path / "b.sqlite", workers=2, progress=False, forward_cases=1)
    assert rep.workers == 2 and rep.n_ok == 8
    _same_rows(tmp_path / "a.sqlite", tmp_path / "b.sqlite")
