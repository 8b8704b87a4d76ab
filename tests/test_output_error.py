"""Sampled-input free runs (simulate/_sampled.py) and output-error refinement (objectives/_output_error.py)."""

from __future__ import annotations

import json

import numpy as np
import pytest

import charcurves as cc
from charcurves import ConfigError, DataError
from charcurves.curves import BasisFittedCurve, SymbolicFittedCurve
from charcurves.data import Trajectory, estimate_derivatives
from charcurves.fitting import FittedModel
from charcurves.fitting import cli_objective, closed_form_text, refine_output_error
from charcurves.simulate import (
    estimate_initial_state,
    free_run_error,
    rk4_sampled,
    simulate_model,
    simulate_sampled,
    stage_inputs,
)
from charcurves.templates import get_template

#: x'' + c x' + k1 x + k3 x^3 + b = g u, about 9 samples per resonance period at DT (as the Silverbox)
TRUE = {"c": 0.4, "k1": 1.0, "k3": 0.5, "g": 2.0, "b": 0.05}
DT = 0.7
N = 3000


def multisine(n: int, dt: float, seed: int = 0, fmax: float = 0.25) -> np.ndarray:
    """Random-phase multisine below ``fmax`` (band-limited, like the benchmark's excitation)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    freqs = np.arange(1, 60) / (n * dt) * 8
    freqs = freqs[freqs < fmax]
    u = np.sum(np.cos(2 * np.pi * freqs[:, None] * t[None, :] + rng.uniform(0, 2 * np.pi, freqs.size)[:, None]),
               axis=0)
    return 0.6 * u / np.std(u)


def true_accel(x, v, u):
    p = TRUE
    return p["g"] * u - p["c"] * v - p["k1"] * x - p["k3"] * x**3 - p["b"]


def symbolic_model(f1: str, f2: str, gain: float, offset: float = 0.0, free_gain: bool = True) -> FittedModel:
    curves = {"f1": SymbolicFittedCurve("f1", "x'", (-3, 3), f1), "f2": SymbolicFittedCurve("f2", "x", (-3, 3), f2)}
    return FittedModel(get_template("separable", free_gain=free_gain), "test", curves, gain, offset, 0.0)


@pytest.fixture(scope="module")
def duffing_record():
    """The Duffing ODE driven by a sampled multisine (linear hold), integrated with 32 RK4 steps per
    sample (converged: checked against LSODA below), 1 % output noise."""
    u = multisine(N, DT)
    x, _, status = rk4_sampled(true_accel, *stage_inputs(u, 32, "linear"), 0.0, 0.0, DT, 32)
    assert status == "ok"
    rng = np.random.default_rng(1)
    y = x + 0.01 * np.std(x) * rng.standard_normal(N)
    return Trajectory(t=np.arange(N) * DT, x=y, F=u), x


# ------------------------------------------------------------------------ the sampled simulator
def test_fixed_step_rk4_matches_lsoda_with_a_linear_hold():
    u = multisine(200, DT, seed=3)
    t = np.arange(200) * DT
    model = symbolic_model("0.4*z", "z + 0.5*z**3", 2.0, 0.05)
    lsoda = simulate_model(model, t, 0.1, 0.0, lambda s: np.interp(s, t, u), rtol=1e-10, atol=1e-12)
    for substeps, tol in ((32, 1e-6), (4, 2e-3)):
        res = simulate_sampled(model, u, 0.1, 0.0, dt=DT, hold="linear", substeps=substeps)
        assert res.ok and res.x.shape == (200,)
        assert np.max(np.abs(res.x - lsoda.x)) < tol * np.max(np.abs(lsoda.x)), substeps


def test_batched_states_equal_single_runs():
    u = multisine(300, DT, seed=4)
    stages = stage_inputs(u, 2, "linear")
    x0 = np.array([0.0, 0.5, -1.0])
    xb, vb, status = rk4_sampled(true_accel, *stages, x0, np.zeros(3), DT, 2)
    assert status == "ok" and xb.shape == (300, 3)
    for i in range(3):
        xs, _, _ = rk4_sampled(true_accel, *stages, float(x0[i]), 0.0, DT, 2)
        assert np.max(np.abs(xs - xb[:, i])) < 1e-12


def test_holds():
    u = np.array([0.0, 1.0, 3.0])
    a, m, b = stage_inputs(u, 2, "linear")
    assert np.allclose(a, [0, 0.5, 1, 2]) and np.allclose(m, [0.25, 0.75, 1.5, 2.5]) and np.allclose(b, [0.5, 1, 2, 3])
    a, m, b = stage_inputs(u, 2, "zoh")
    assert np.allclose(a, [0, 0, 1, 1]) and np.allclose(m, a) and np.allclose(b, a)
    # band-limited: a slow sine sampled 20 times per period comes back between the samples
    t = np.arange(200) * 0.05
    a, m, b = stage_inputs(np.sin(t), 1, "bandlimited")
    inner = slice(20, 180)  # the mirrored extension is exact only for an even continuation at the ends
    assert np.max(np.abs(m[inner] - np.sin(t[:-1] + 0.025)[inner])) < 1e-3
    with pytest.raises(ConfigError, match="unknown input hold 'cubic'; choose one of linear, zoh, bandlimited"):
        stage_inputs(u, 1, "cubic")
    with pytest.raises(ConfigError, match=r"substeps \(--refine-substeps, validate --substeps\) must be an integer "
                                          r"from 1 to 64 \(RK4 steps per sample"):
        stage_inputs(u, 0, "linear")


def test_failure_statuses():
    unstable = symbolic_model("-0.5*z", "-z - z**3", 1.0)  # negative damping and a softening spring
    res = simulate_sampled(unstable, np.zeros(2000), 1.0, 0.0, dt=0.1)
    assert res.status == "diverged" and 0 < res.x.size < 2000 and np.all(np.isfinite(res.x))
    assert "larger than" in res.message
    slow = simulate_sampled(symbolic_model("0.1*z", "z", 1.0), np.zeros(200000), 1.0, 0.0, dt=0.01, substeps=8,
                            time_budget=0.05)
    assert slow.status == "timeout" and slow.x.size == 0
    batch, _, status = rk4_sampled(lambda x, v, u: x**3 - 0.0 * v, *stage_inputs(np.zeros(400), 1, "linear"),
                                   np.array([0.0, 2.0]), np.zeros(2), 0.1)
    assert status == "diverged" and np.all(batch[:, 0] == 0) and np.isnan(batch[-1, 1])


def test_simulate_sampled_checks_its_input():
    model = symbolic_model("0.4*z", "z", 1.0)
    with pytest.raises(ConfigError, match="give the sample interval dt > 0"):
        simulate_sampled(model, np.zeros(10), 0.0, 0.0)
    with pytest.raises(DataError, match="uniformly spaced"):
        simulate_sampled(model, np.zeros(4), 0.0, 0.0, t=[0, 1, 2, 4])


# ------------------------------------------------------------------------ the refinement
def test_refinement_recovers_duffing_coefficients_from_a_poor_start(duffing_record):
    """Start 15 % off in c, 10 % in k1, 14 % in k3, 5 % in g, b = 0; the refinement must land on
    the true values (1 % output noise, linear hold, 4 RK4 steps per sample)."""
    traj, clean = duffing_record
    start = symbolic_model("0.46*z", "0.9*z + 0.43*z**3", 1.9)
    refined = refine_output_error(start, estimate_derivatives(traj, "spectral"))
    oe = refined.info["output_error"]
    assert oe["status"] == "ok" and sorted(oe["parameters"]) == ["b", "f1:z", "f2:z", "f2:z**3", "g"]
    c, k1, k3, g, b = (dict(zip(oe["parameters"], oe["coefficients_after"]))[k]
                       for k in ("f1:z", "f2:z", "f2:z**3", "g", "b"))
    assert c == pytest.approx(TRUE["c"], rel=5e-3)
    assert k1 == pytest.approx(TRUE["k1"], rel=3e-3)
    assert k3 == pytest.approx(TRUE["k3"], rel=5e-3)
    assert g == pytest.approx(TRUE["g"], rel=3e-3)
    assert b == pytest.approx(TRUE["b"], abs=3e-3)
    assert refined.gain == g and refined.offset == b
    assert float(refined.curves["f2"](1.0)) == pytest.approx(k1 + k3, rel=1e-12)
    # the free-run error drops to the noise level (1 % of std x)
    noise = 0.01 * np.std(clean)
    assert oe["free_run_rmse_before"] > 10 * noise
    assert oe["free_run_rmse_after"] < 1.2 * noise
    assert oe["segments"] == 12 and oe["segment_length"] == 250


def test_api_refine_option_on_a_parametric_fit(duffing_record):
    traj, _ = duffing_record
    kwargs = dict(method="parametric", basis="f1=z; f2=z, z**3", free_gain=True, differentiator="spectral")
    plain = cc.fit(traj, objective="equation-error", **kwargs)
    refined = cc.fit(traj, objective="output-error", **kwargs)
    short = traj.slice(slice(0, 600))
    auto = cc.fit(short, objective="auto", **kwargs)  # free gain, closed forms, estimated derivatives: refined
    assert auto.info["output_error"]["status"] == "ok"
    given = short.replace(v=np.gradient(short.x, DT), a=np.gradient(np.gradient(short.x, DT), DT))
    assert "output_error" not in cc.fit(given, objective="auto", **{**kwargs, "differentiator": "auto"}).info
    assert "output_error" not in plain.info
    assert isinstance(refined.curves["f2"], BasisFittedCurve) and refined.curves["f2"].basis == ["z", "z**3"]
    errs_plain = abs(plain.curves["f2"].coefficients[0] / TRUE["k1"] - 1)
    errs_refined = abs(refined.curves["f2"].coefficients[0] / TRUE["k1"] - 1)
    assert errs_plain > 0.05 and errs_refined < 3e-3  # the equation-error fit is biased at 9 samples per period
    assert refined.gain == pytest.approx(TRUE["g"], rel=3e-3)
    # the refined model keeps its refinement record through save/load
    after = dict(zip(refined.info["output_error"]["parameters"], refined.info["output_error"]["coefficients_after"]))
    assert after["g"] == refined.gain and after["f2:z**3"] == refined.curves["f2"].coefficients[1]


def test_free_run_diagnostics_and_the_curves_figure_panel(tmp_path, duffing_record):
    """The diagnostics of curves.png: one free run of the refitted model over the whole record, whose
    RMSE against the measured x is the one result.json reports; the figure gets two more rows."""
    import matplotlib

    matplotlib.use("Agg")
    from charcurves.cli._fit import _curves_figure
    from charcurves.fitting import free_run_diagnostics

    traj, clean = duffing_record
    short = traj.slice(slice(0, 800))
    kwargs = dict(method="parametric", basis="f1=z; f2=z, z**3", free_gain=True, differentiator="spectral")
    refined = cc.fit(short, objective="output-error", **kwargs)
    t, measured, free = free_run_diagnostics(refined, short)
    assert np.array_equal(measured, short.x) and t.shape == free.shape == (800,)
    rmse = float(np.sqrt(np.mean((free - measured) ** 2)))
    assert rmse == pytest.approx(refined.info["output_error"]["free_run_rmse_after"], rel=1e-9)
    noise = 0.01 * np.std(clean)
    assert rmse < 1.5 * noise  # the free run follows the record to its noise level (1 % of std x)
    plain = cc.fit(short, objective="equation-error", **kwargs)
    assert free_run_diagnostics(plain, short) is None
    with_panel = _curves_figure(refined, None, short, "t")
    without = _curves_figure(plain, None, short, "t")
    assert len(with_panel.axes) == 4 and len(without.axes) == 2
    assert with_panel.get_figheight() > 2 * without.get_figheight()


def test_refined_model_round_trips(tmp_path, duffing_record):
    traj, _ = duffing_record
    refined = refine_output_error(symbolic_model("0.42*z", "z + 0.5*z**3", 2.0),
                                  estimate_derivatives(traj.slice(slice(0, 1200)), "spectral"), substeps=2)
    refined.save(tmp_path / "m")
    again = cc.load_model(tmp_path / "m")
    assert again.info["output_error"]["substeps"] == 2
    assert float(again.curves["f1"](1.0)) == pytest.approx(float(refined.curves["f1"](1.0)), rel=1e-12)
    text = closed_form_text(again)
    assert text.startswith("x'' + ") and text.endswith("*F") and "x**3" in text


def test_free_run_error_and_initial_state(duffing_record):
    traj, clean = duffing_record
    truth = symbolic_model("0.4*z", "z + 0.5*z**3", 2.0, 0.05)
    x0, v0 = estimate_initial_state(truth, traj)
    assert abs(x0) < 0.02 and abs(v0) < 0.03  # the record starts at rest
    rmse, res = free_run_error(truth, traj)
    assert res.ok and rmse == pytest.approx(0.01 * np.std(clean), rel=0.1)


def test_refinement_options_are_checked(duffing_record):
    traj, _ = duffing_record
    model = symbolic_model("0.4*z", "z", 1.0)
    with pytest.raises(ConfigError, match="unknown refine option 'segments'; valid: hold, substeps"):
        cli_objective("output-error", None, {"segments": 3})  # the CLI's --refine-... settings
    with pytest.raises(ConfigError, match="unknown refine 'simulation'; choose one of none, output-error, auto"):
        cli_objective(None, "simulation")
    with pytest.raises(ConfigError, match=r"segment_length \(--segment-length\) must be an integer from 16 to 100000"):
        refine_output_error(model, traj, segment_length=4)
    uneven = Trajectory(t=np.r_[np.arange(100) * DT, 100 * DT + 0.3 + np.arange(100) * DT], x=np.zeros(200),
                        F=np.zeros(200))
    with pytest.raises(DataError, match="needs uniform sampling"):
        refine_output_error(model, uneven)


# ------------------------------------------------------------------------ CLI
class _Run:
    def __init__(self, returncode, stdout, stderr):
        self.returncode, self.stdout, self.stderr = returncode, stdout, stderr


@pytest.fixture
def cli(capsys):
    """The command line in this process (a subprocess would pay the import time for each call)."""
    from charcurves.cli import main

    def run(args):
        capsys.readouterr()
        code = main([str(a) for a in args])
        out = capsys.readouterr()
        return _Run(code, out.out, out.err)

    return run


@pytest.fixture(scope="module")
def duffing_csv(tmp_path_factory, duffing_record):
    traj, _ = duffing_record
    path = tmp_path_factory.mktemp("oe") / "box.csv"
    lines = ["u,y"] + [f"{a!r},{b!r}" for a, b in zip(traj.F.tolist(), traj.x.tolist())]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_cli_refines_by_default_for_free_gain_closed_forms(tmp_path, duffing_csv, cli):
    out = tmp_path / "fit"
    proc = cli(["fit", duffing_csv, "--x-col", "y", "--force-col", "u", "--sample-rate", 1 / DT, "--method",
                 "parametric", "--basis", "f1=z; f2=z, z**3", "--free-gain", "--out", out, "--no-figure"])
    assert proc.returncode == 0, proc.stderr
    res = json.loads((out / "result.json").read_text())
    oe = res["info"]["output_error"]
    assert oe["parameters"] == ["f1:z", "f2:z", "f2:z**3", "g", "b"]  # basis curves: in basis order
    c, k1, k3, g, b = oe["coefficients_after"]
    # time in seconds of the file: the same equation (the sample rate is 1/DT)
    assert (c, k1, k3, g) == pytest.approx((TRUE["c"], TRUE["k1"], TRUE["k3"], TRUE["g"]), rel=5e-3)
    assert res["gain"] == pytest.approx(g)
    assert oe["free_run_rmse_after"] < oe["free_run_rmse_before"] / 3
    assert "seconds" not in oe  # wall-clock times go to timing.json
    assert "output_error.seconds" in json.loads((out / "timing.json").read_text())
    assert "closed form: x'' + " in proc.stdout and "output-error refinement (hold linear" in proc.stdout
    # validate: the saved model on the same record
    proc = cli(["validate", out / "model", duffing_csv, "--x-col", "y", "--force-col", "u", "--sample-rate", 1 / DT,
                 "--rows", "0:1500", "--rows", "1500:3000", "--out", tmp_path / "val"])
    assert proc.returncode == 0, proc.stderr
    val = json.loads((tmp_path / "val" / "validation.json").read_text())
    assert [s["rows"] for s in val["segments"]] == [[0, 1500], [1500, 3000]]
    assert val["hold"] == "linear" and val["substeps"] == oe["substeps"]  # as refined
    for seg in val["segments"]:
        assert seg["status"] == "ok" and seg["rmse_relative_to_std"] < 0.015
    assert (tmp_path / "val" / "validation.png").stat().st_size > 10000
    # --refine none keeps the equation-error fit
    proc = cli(["fit", duffing_csv, "--x-col", "y", "--force-col", "u", "--sample-rate", 1 / DT, "--method",
                 "parametric", "--basis", "f1=z; f2=z, z**3", "--free-gain", "--refine", "none", "--out", tmp_path / "none", "--no-figure"])
    assert proc.returncode == 0, proc.stderr
    assert "output_error" not in json.loads((tmp_path / "none" / "result.json").read_text())["info"]


@pytest.mark.parametrize("extra, message", [
    (["--refine", "bogus"], "charcurves: error: unknown refine 'bogus'; choose one of none, output-error, auto"),
    (["--refine-hold", "cubic"], "charcurves: error: unknown input hold 'cubic'; choose one of linear, zoh, "
                                 "bandlimited"),
    (["--refine-substeps", "0"], "charcurves: error: argument --refine-substeps: must be an integer from 1 to 64 "
                                 "(RK4 steps per sample: time and memory of output error grow in proportion; the "
                                 "default chooses 1 to 8), got 0; give e.g. --refine-substeps 4 (see 'charcurves fit "
                                 "--help')"),
])
def test_cli_bad_refine_values(tmp_path, duffing_csv, extra, message, cli):
    args = ["fit", duffing_csv, "--x-col", "y", "--force-col", "u", "--sample-rate", 1 / DT, "--free-gain",
            "--method", "parametric", "--basis", "f1=z; f2=z, z**3", "--out", tmp_path / "o", "--no-figure", *extra]
    proc = cli(args)
    assert proc.returncode == 2
    assert proc.stderr.strip() == message
    assert not (tmp_path / "o").exists()


def test_cli_validate_errors(tmp_path, duffing_csv, cli):
    proc = cli(["validate", tmp_path / "nomodel", duffing_csv])
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and "nomodel" in proc.stderr


def test_symbolic_curves_get_one_coefficient_per_term():
    """Integer and implicit coefficients are refined too; constants and exponents stay."""
    import torch

    from charcurves.curves import trainable

    model = symbolic_model("0.3*z + 2*tanh(50.0*z)", "z**3 - z + 0.5", 1.5, 0.2)
    f1, f2 = trainable(model.curves["f1"]), trainable(model.curves["f2"])
    assert f1.labels + f2.labels == ["f1:tanh(50.0*z)", "f1:tanh(50.0*z)#0", "f1:z", "f2:z**3", "f2:z"]
    assert f1.theta.tolist() == [[2.0, 50.0, 0.3]] and f2.theta.tolist() == [[1.0, -1.0]]
    z = torch.tensor([0.3, -1.0, 0.01], dtype=torch.float64)
    for name, rf in (("f1", f1), ("f2", f2)):
        values = rf.param.evaluate(torch.as_tensor(rf.theta), z).numpy()[0] + rf.shift
        assert np.allclose(values, model.curves[name](z.numpy()), rtol=1e-13)
    assert float(f2.rebuild(f2.theta * 1.1)(0.0)) == pytest.approx(0.5)  # the constant is not scaled
    assert float(f1.rebuild(f1.theta * 1.1)(0.1)) == pytest.approx(0.33 * 0.1 + 2.2 * np.tanh(5.5), rel=1e-12)


@pytest.mark.parametrize("hold", ["linear", "bandlimited"])
def test_the_linear_hold_biases_the_free_gain_by_the_interpolants_amplitude(hold):
    """A free gain fitted by output error on a nearly clean Duffing record (forcing A cos(W t)) takes up
    what the input's hold does between samples: the linear interpolant of a sampled sinusoid has a
    fundamental smaller by sinc(W dt / 2)^2, so the gain is high by 1 / sinc^2 - 1 (benchmarks/results/
    coverage/hold_bias.json); the bandlimited hold reproduces the sinusoid and leaves no bias."""
    from charcurves.systems import get_system

    system = get_system("duffing")
    record = cc.corrupt(system.simulate(t_end=20.0, n_points=500), 120, on="state", seed=0)
    dt = float(record.t[1] - record.t[0])
    est = cc.CharacteristicCurves.from_method(method="parametric", basis="f1=z; f2=z, z**3", free_gain=True,
                                              objective=cc.OutputError(hold=hold), threads=1)
    model = est.fit(record).model_
    assert model.info["output_error"]["status"] == "ok"
    predicted = 1.0 / np.sinc(system.Omega * dt / (2 * np.pi)) ** 2 - 1.0  # 1.93e-4 here
    expected = predicted if hold == "linear" else 0.0
    assert model.gain - 1.0 == pytest.approx(expected, abs=0.03 * predicted)
