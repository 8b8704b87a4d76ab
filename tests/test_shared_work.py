"""Work done once for many jobs: fits shared by a method and its +post-sr sibling, remembered SR searches,
stacked forward runs of one model, stacked validation draws. Each must give what the work done separately
gives (the same numbers, or the same to the solver's tolerance where runs are stacked)."""

import numpy as np
import pytest

from charcurves._errors import ConfigError
from charcurves.curves import SymbolicFittedCurve
from charcurves.data import corrupt
from charcurves.experiments import (
    RunSettings,
    Sweep,
    evaluate_forward,
    make_validation_cases,
    plan_units,
    run_unit,
    training_box,
)
from charcurves.fitting import PRESETS, CharacteristicCurves, FittedModel, fit_with_post_sr, shared_fit_base
from charcurves.simulate import prepare_model_curves, simulate_model, simulate_model_batch, sinusoidal_forcing
from charcurves.symbolic import OperonEngine
from charcurves.systems import get_system
from charcurves.templates import get_template

TINY = PRESETS["default"].replace(n_starts=1, adam_steps=20, lm_max_iter=3)


def symbolic_model(f1, f2, domain=(-2, 2)):
    curves = {"f1": SymbolicFittedCurve("f1", "x'", domain, f1), "f2": SymbolicFittedCurve("f2", "x", domain, f2)}
    return FittedModel(get_template("separable"), "test", curves, 1.0, 0.0, 0.0)


def _info_without_times(info):
    if isinstance(info, dict):
        return {k: _info_without_times(v) for k, v in info.items() if "seconds" not in k}
    if isinstance(info, list):
        return [_info_without_times(v) for v in info]
    return info


# ---------------------------------------------------------------------------- one fit, finished twice
def test_shared_fit_base_names_the_method_each_extension_builds_on():
    assert shared_fit_base("nn-cc+post-sr") == "nn-cc"
    assert shared_fit_base("nn-cc+sym+post-sr") == "nn-cc+sym"
    assert shared_fit_base("sindy-cc+sym+post-sr") == "sindy-cc+sym"
    assert shared_fit_base("sr-cc+refit") == "sr-cc"
    assert [shared_fit_base(m) for m in ("nn-cc", "sindy", "sindy-cc", "poly-cc", "sr", "sr-cc", "parametric")] == \
        [None] * 7


@pytest.mark.parametrize("base, preset, on", [("sindy-cc+sym", "default", "force"), ("nn-cc", TINY, "force"),
                                               ("sindy-cc+sym", "default", "state"), ("nn-cc", TINY, "state")])
def test_fit_with_post_sr_equals_the_two_fits_done_apart(duffing, base, preset, on):
    """With noise on the forcing (derivatives given: equation error) and on x (measured records:
    output error, which runs once for both and before post-SR)."""
    system, clean = duffing
    records = [corrupt(clean, 20 if on == "force" else 40, on=on, seed=k) for k in range(2)]
    sr = {"generations": 5}
    plain = CharacteristicCurves.from_method(method=base, preset=preset)
    distilled = CharacteristicCurves.from_method(method=base + "+post-sr", preset=preset, sr_options=sr)
    apart = plain.fit_many(records, seeds=[3, 4]), distilled.fit_many(records, seeds=[3, 4])
    shared = fit_with_post_sr(plain, distilled, records, seeds=[3, 4])
    z = np.linspace(-1.5, 1.5, 301)
    for a_list, b_list in zip(apart, shared):
        for a, b in zip(a_list, b_list):
            assert a.method == b.method and a.loss == b.loss and a.gain == b.gain
            for name in a.curves:
                np.testing.assert_array_equal(a.curves[name](z), b.curves[name](z))
            assert _info_without_times(a.info) == _info_without_times(b.info)
    assert [m.curves["f2"].kind for m in shared[1]] == ["symbolic", "symbolic"]
    assert all(m.curves["f2"].kind != "symbolic" for m in shared[0])
    for plain_model, closed in zip(*shared):
        if on == "state":  # the closed forms distil the curves output error refined, then are refined again
            assert _info_without_times(closed.info["output_error_before_post_sr"]) == \
                _info_without_times(plain_model.info["output_error"])
            assert closed.info["output_error"]["status"] == "ok"
        else:
            assert "output_error" not in closed.info and "output_error_before_post_sr" not in closed.info


@pytest.mark.slow  # ~11 CPU s, the default nn-cc on a 40 dB record; the fast tier checks that post-SR distils
# the curves output error refined in test_fit_with_post_sr_equals_the_two_fits_done_apart[nn-cc-...-state]
def test_post_sr_of_a_measured_record_distils_the_output_error_curves():
    """Appendix F's Duffing record at 40 dB (noise on x, realisation 0, as the benchmark draws it).
    Post-SR used to distil the equation-error networks, whose curves carry the differentiated noise:
    the data guard then left z**3 - z for a degree-5 front member with even terms and f1 took a
    constant of -0.020 (worst RMSE 2.0e-2, 21x the plain nn-cc's 9.8e-4). Distilling the networks
    that output error refined gives z**3 - z and 0.3 z (worst RMSE 9.1e-4)."""
    from charcurves.metrics import curve_errors

    job = next(j for j in Sweep(systems=["duffing"], methods=["nn-cc"], snr_db=[40], realizations=1,
                                noise_on="state").jobs())
    system = get_system("duffing")
    record = corrupt(system.simulate(job.t_end, job.n_points), 40, on="state", seed=job.noise_seed)
    plain, closed = fit_with_post_sr(CharacteristicCurves.from_method(method="nn-cc", threads=1),
                                     CharacteristicCurves.from_method(method="nn-cc+post-sr", threads=1), [record],
                                     seeds=[job.fit_seed])
    worst_plain = max(curve_errors(plain[0], system.true_curves()).values())
    errors = curve_errors(closed[0], system.true_curves())
    assert worst_plain < 1.2e-3
    assert max(errors.values()) < 1.1 * worst_plain, errors  # 2.0e-2 when the equation-error fit was distilled
    f2 = closed[0].curves["f2"].expression()
    assert sorted(int(t.as_poly().degree()) for t in f2.as_ordered_terms()) == [1, 3], f2
    coef = {int(t.as_poly().degree()): float(t.as_coeff_Mul()[0]) for t in f2.as_ordered_terms()}
    assert abs(coef[3] - 1.0) < 0.01 and abs(coef[1] + 1.0) < 0.01, f2


def test_fit_with_post_sr_refuses_estimators_that_are_not_a_pair():
    with pytest.raises(ConfigError, match="differ only in post-SR: the first must fit without post-SR"):
        fit_with_post_sr(CharacteristicCurves.from_method(method="nn-cc+post-sr"), CharacteristicCurves.from_method(method="nn-cc"), [])
    with pytest.raises(ConfigError, match="fit different curves"):
        fit_with_post_sr(CharacteristicCurves.from_method(method="nn-cc"), CharacteristicCurves.from_method(method="nn-cc+sym+post-sr"), [])
    with pytest.raises(ConfigError, match="they differ in random_state"):
        fit_with_post_sr(CharacteristicCurves.from_method(method="nn-cc"),
                         CharacteristicCurves.from_method(method="nn-cc+post-sr", random_state=1), [])


def test_plan_units_puts_a_method_and_its_extension_on_the_same_records_together():
    jobs = Sweep(methods=["nn-cc", "nn-cc+post-sr", "sr-cc", "sr-cc+refit", "parametric"], snr_db=[40, 20],
                 realizations=3).jobs()
    units = plan_units(jobs)
    neural = [u for u in units if u[0].method == "nn-cc"]
    assert len(neural) == 2  # one per level: three realisations of each of the two methods
    for u in neural:
        assert sorted(j.method for j in u) == ["nn-cc"] * 3 + ["nn-cc+post-sr"] * 3 and len({j.snr_db for j in u}) == 1
    sr = [u for u in units if u[0].method == "sr-cc"]
    assert len(sr) == 6 and all([j.method for j in u] == ["sr-cc", "sr-cc+refit"] for u in sr)
    assert all(u[0].noise_seed == u[1].noise_seed for u in sr)
    assert sum(len(u) for u in units) == len(jobs) and sorted(j.key for u in units for j in u) == \
        sorted(j.key for j in jobs)
    # a cap counts records: both methods of a record stay in one unit
    capped = [u for u in plan_units(jobs, max_batch=2) if u[0].method == "nn-cc"]
    assert [len(u) for u in capped] == [4, 2, 4, 2]
    assert all({j.realization for j in u if j.method == "nn-cc"} == {j.realization for j in u
                                                                       if j.method == "nn-cc+post-sr"} for u in capped)
    # alone, an extension runs as before
    alone = plan_units(Sweep(methods=["nn-cc+post-sr"], snr_db=[20], realizations=2).jobs())
    assert [[j.method for j in u] for u in alone] == [["nn-cc+post-sr", "nn-cc+post-sr"]]


def test_a_shared_unit_gives_the_rows_of_separate_units():
    jobs = Sweep(methods=["sindy-cc+sym", "sindy-cc+sym+post-sr", "sr-cc", "sr-cc+refit"], snr_db=[20],
                 realizations=1, method_options={m: {"sr_options": {"generations": 5}} for m in
                                                 ("sindy-cc+sym+post-sr", "sr-cc", "sr-cc+refit")}).jobs()
    settings = RunSettings(forward_cases=0)
    together = {j.method: r for u in plan_units(jobs) for j, r in zip(u, run_unit(u, settings))}
    apart = {j.method: run_unit([j], settings)[0] for j in jobs}
    assert set(together) == set(apart) == {j.method for j in jobs}
    for m in together:
        a, b = together[m], apart[m]
        assert a["status"] == b["status"] == "ok"
        assert (a["rmse_f1"], a["rmse_f2"], a["loss"]) == (b["rmse_f1"], b["rmse_f2"], b["loss"])
        assert a["extra"]["curves"] == b["extra"]["curves"]
    # the refit differs from SR-CC in its coefficients only, and each row says what its method costs alone
    assert together["sr-cc+refit"]["rmse_f1"] != together["sr-cc"]["rmse_f1"]
    assert together["sr-cc+refit"]["extra"]["fit_seconds"] >= together["sr-cc"]["extra"]["fit_seconds"]
    assert together["sindy-cc+sym+post-sr"]["extra"]["fit_seconds"] > together["sindy-cc+sym"]["extra"]["fit_seconds"]


# ---------------------------------------------------------------------------- remembered searches
class CountingOperon(OperonEngine):
    calls = 0

    def _search(self, *args, **kwargs):
        type(self).calls += 1
        return super()._search(*args, **kwargs)


def test_a_search_asked_twice_runs_once_and_gives_the_same_result():
    z = np.linspace(-2, 2, 200)
    engine = CountingOperon(generations=5)
    first = engine.fit(z[:, None], z**3 - z, ["z"], random_state=11)
    again = engine.fit(z[:, None], z**3 - z, ["z"], random_state=11)
    assert CountingOperon.calls == 1
    assert again.expression == first.expression and again.front == first.front and again.mse == first.mse
    again.info["mutated"] = True  # each caller gets its own info
    assert "mutated" not in engine.fit(z[:, None], z**3 - z, ["z"], random_state=11).info
    engine.fit(z[:, None], z**3 - z, ["z"], random_state=12)  # another seed, other data, other settings: new
    engine.fit(z[:, None], z**3 - 1.01 * z, ["z"], random_state=11)
    CountingOperon(generations=6).fit(z[:, None], z**3 - z, ["z"], random_state=11)
    assert CountingOperon.calls == 4


# ---------------------------------------------------------------------------- stacked runs of one model
def test_prepared_curves_evaluate_arrays_as_their_scalar_form(duffing):
    system, clean = duffing
    nn = CharacteristicCurves.from_method(method="nn-cc+sym", preset=TINY).fit(corrupt(clean, 20, seed=0)).model_
    z = np.linspace(-3.0, 3.0, 97)  # beyond the tables, where the exact curve is used
    for model in (nn, symbolic_model("0.3*z", "z**3 - z")):
        for c in prepare_model_curves(model):
            np.testing.assert_allclose(c.values(z), [c.smooth(float(u)) for u in z], rtol=1e-12, atol=1e-12)
            assert c.vector_ops > 0


def test_stacked_runs_match_runs_one_at_a_time():
    model = symbolic_model("0.3*z", "z**3 - z")  # the true curves: only the solver differs
    t = np.linspace(0.0, 30.0, 601)
    A, W = np.array([0.5, 0.3, 0.45]), np.array([1.2, 1.0, 1.3])
    x0, v0 = [0.5, -0.3, 0.1], [-0.5, 0.2, 0.0]
    runs = simulate_model_batch(model, t, x0, v0, lambda s: A * np.cos(W * s), rtol=1e-10, atol=1e-12)
    assert all(r.status == "ok" and r.details["batched"] for r in runs)
    for i, r in enumerate(runs):
        one = simulate_model(model, t, x0[i], v0[i], sinusoidal_forcing(A[i], W[i]), rtol=1e-10, atol=1e-12)
        assert np.max(np.abs(r.x - one.x)) < 1e-6 and np.max(np.abs(r.v - one.v)) < 1e-6


def test_stacked_runs_keep_each_runs_own_failure():
    model = symbolic_model("-0.5*z", "-z**3")  # negative damping, softening spring: runs away from 1.0, stays at 0
    t = np.linspace(0.0, 100.0, 1000)
    runs = simulate_model_batch(model, t, [0.0, 1.0, 0.5], [0.0, 1.0, 0.0], lambda s: np.zeros(3), max_abs=1e3,
                                box={"x": (-2.0, 2.0)})
    assert [r.status for r in runs] == ["ok", "left_box", "left_box"]
    assert runs[0].x.size == t.size and np.all(runs[0].x == 0.0)
    assert "x = " in runs[1].message and "left [-2, 2]" in runs[1].message
    for r in runs[1:]:
        assert 0 < r.t_end_reached < 100 and r.x.size < t.size and np.all(np.abs(r.x) <= 2.0 + 1e-9)
        assert r.x.size <= np.searchsorted(t, r.t_end_reached, side="right")  # samples up to the last step inside
    blown = simulate_model_batch(model, t, [0.0, 1.0], [0.0, 1.0], lambda s: np.zeros(2), max_abs=1e3)
    assert [r.status for r in blown] == ["ok", "diverged"] and "larger than 1000" in blown[1].message


def test_models_with_a_jump_or_long_closed_forms_run_one_at_a_time():
    t = np.linspace(0.0, 10.0, 201)
    coulomb = symbolic_model("0.3*z + 0.8*sign(z)", "z")
    runs = simulate_model_batch(coulomb, t, [0.1, 0.2], [0.0, 0.0], lambda s: np.array([1.0, 1.0]) * np.cos(s))
    assert [r.details["batched"] for r in runs] == [False, False] and [r.status for r in runs] == ["ok", "ok"]
    long_form = symbolic_model(" + ".join(f"{0.01 * k}*z**{k}" for k in range(1, 12)), "z**3 - z")
    runs = simulate_model_batch(long_form, t, [0.1, 0.2], [0.0, 0.0], lambda s: np.array([0.5, 0.5]) * np.cos(s))
    assert [r.details["batched"] for r in runs] == [False, False]


def test_forward_validation_stacked_gives_the_statuses_and_separation_times_of_one_at_a_time(monkeypatch):
    import charcurves.metrics._validation as validation

    system = get_system("duffing")
    cases = make_validation_cases(system, 4, seed=5)
    for model in (symbolic_model("0.3*z", "z**3 - z"), symbolic_model("0.32*z", "1.05*z**3 - z"),
                  symbolic_model("0.3*z", "-z**3 - 2*z")):
        # LSODA runs case by case (faster); the stacked path serves the other solvers
        assert validation._batched_runs(model, cases, None, None, "LSODA", 1e-10, 1e-12, 20.0, None) is None
        stacked = evaluate_forward(model, system, cases, method="DOP853")
        assert validation._batched_runs(model, cases, None, None, "DOP853", 1e-10, 1e-12, 20.0, None) is not None
        monkeypatch.setattr(validation, "_batched_runs", lambda *a, **k: None)
        alone = evaluate_forward(model, system, cases, method="DOP853")
        monkeypatch.undo()
        assert [c.status for c in stacked.cases] == [c.status for c in alone.cases]
        np.testing.assert_allclose([c.t_sep for c in stacked.cases], [c.t_sep for c in alone.cases], atol=0.05)


# ---------------------------------------------------------------------------- stacked validation draws
def test_stacked_duffing_draws_give_the_cases_of_single_draws():
    system = get_system("duffing")
    cases = make_validation_cases(system, 4, seed=9)
    box = training_box(system.simulate())
    first20 = cases[0].t_eval <= 20.0
    for c in cases:  # each true trajectory as the system's own run of the case, to the solver's accuracy
        tr = system.simulate(t_eval=c.t_eval, x0=c.x0, v0=c.v0, A=c.A, Omega=c.Omega)
        assert np.max(np.abs(tr.x[first20] - c.x_true[first20])) < 1e-6
        assert np.max(np.abs(tr.x - c.x_true)) < 0.05
        assert box["x"][0] <= c.x_true.min() and c.x_true.max() <= box["x"][1]
    # loose tolerances (the scripts' variant): one draw at a time, bit for bit the system's own run
    scripts = get_system("duffing", "scripts")
    c = make_validation_cases(scripts, 1, seed=9, t_end=20.0, n_points=201)[0]
    np.testing.assert_array_equal(scripts.simulate(t_eval=c.t_eval, x0=c.x0, v0=c.v0, A=c.A, Omega=c.Omega).x, c.x_true)


def test_draws_that_leave_the_box_stop_early_with_the_answers_of_whole_runs(monkeypatch):
    """The scripts' Duffing draws its validation cases one run at a time (loose tolerances); about 99 % of
    the draws leave the training box, most within the first 13 s of the 80. A run given the box stops at
    the first solver step with a sample outside: every draw gets the answer (inside or not) of its whole
    run, the cases inside are that run to the last bit, and the runs that leave take fewer solver steps."""
    import scipy.integrate

    from charcurves.metrics._validation import VALIDATION_RANGES, _inside

    scripts = get_system("duffing", "scripts")
    box = training_box(corrupt(scripts.simulate(), 35.0, on="force", seed=0))
    rng = np.random.default_rng(1)
    ranges = VALIDATION_RANGES["duffing"]
    draws = [{k: round(float(rng.uniform(*ranges[k])), 3) for k in ("x0", "v0", "A", "Omega")} for _ in range(48)]
    t = np.linspace(0.0, 80.0, 2000)
    steps = {"n": 0}
    real_step = scipy.integrate.LSODA.step

    def counting(self):
        steps["n"] += 1
        return real_step(self)

    monkeypatch.setattr(scipy.integrate.LSODA, "step", counting)
    whole = list(scripts.simulate_many(t, draws))
    n_whole, steps["n"] = steps["n"], 0
    early = list(scripts.simulate_many(t, draws, box))
    inside = [run is not None and _inside(run[0], run[1], box) for run in whole]
    assert 0 < sum(inside) < len(draws) // 2  # both answers occur among these draws
    assert [run is not None for run in early] == inside
    for a, b in zip(whole, early):
        if b is not None:
            np.testing.assert_array_equal(a[0], b[0])
            np.testing.assert_array_equal(a[1], b[1])
    assert steps["n"] < 0.6 * n_whole, (steps["n"], n_whole)
    # the validation cases drawn with the box are those of whole runs
    cases = make_validation_cases(scripts, 2, seed=3, box=box)
    import charcurves.systems._base as base

    def whole_run(fun, t_eval, y0, rtol, atol, box):  # the run to its end, then the box
        sol = scipy.integrate.solve_ivp(fun, (t_eval[0], t_eval[-1]), y0, "LSODA", t_eval, rtol=rtol, atol=atol)
        return (sol.y[0], sol.y[1]) if sol.success and _inside(sol.y[0], sol.y[1], box) else None

    with monkeypatch.context() as m:
        m.setattr(base, "_lsoda_samples_inside", whole_run)
        slow = make_validation_cases(scripts, 2, seed=3, box=box)
    assert cases.n_attempts == slow.n_attempts > 2 and len(cases) == len(slow) == 2
    for c, d in zip(cases, slow):
        np.testing.assert_array_equal(c.x_true, d.x_true)


# ---------------------------------------------------------------------------- LSODA from sample to sample
def test_lsoda_sample_to_sample_gives_the_trajectory_and_failures_of_stepping(monkeypatch):
    """A run without events goes by LSODA over its samples (odeint, or scipy.integrate.ode from sample to
    sample where it stops early); it must give the stepped LSODA's trajectory to the tolerances, and stop
    with the same status where the model runs away."""
    import charcurves.simulate._forward as forward

    t = np.linspace(0.0, 60.0, 1201)
    cases = [(symbolic_model("0.3*z", "z**3 - z"), 0.5, -0.3, None),  # Duffing: chaotic, stays bounded
             (symbolic_model("-0.5*z", "-z**3"), 1.0, 1.0, 1e3)]       # negative damping, softening: diverges
    for model, x0, v0, max_abs in cases:
        kw = dict(rtol=1e-10, atol=1e-12) if max_abs is None else dict(max_abs=max_abs)
        fast = simulate_model(model, t, x0, v0, sinusoidal_forcing(0.5, 1.2), **kw)
        with monkeypatch.context() as m:
            m.setattr(forward._Run, "free_lsoda", lambda self, t0, x, v: self.slip(t0, x, v, 0))
            stepped = simulate_model(model, t, x0, v0, sinusoidal_forcing(0.5, 1.2), **kw)
        assert fast.status == stepped.status
        n = min(fast.x.size, stepped.x.size)
        if max_abs is None:
            assert fast.status == "ok" and n == t.size
            np.testing.assert_allclose(fast.x[:400], stepped.x[:400], atol=1e-6)  # the first 20 s; chaos after
        else:
            assert fast.status == "diverged" and abs(fast.x.size - stepped.x.size) <= 1
            np.testing.assert_allclose(fast.x[: n - 1], stepped.x[: n - 1], rtol=1e-5, atol=1e-6)
