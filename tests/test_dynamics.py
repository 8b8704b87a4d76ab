"""Largest Lyapunov exponent of fitted models: fitted curves, their derivatives, speed."""

import time

import numpy as np
import pytest

import charcurves as cc
from charcurves import SimulationError
from charcurves.curves import BasisFittedCurve, SymbolicFittedCurve
from charcurves.metrics import largest_lyapunov_exponent
from charcurves.simulate import prepare_curve

# module fixtures (duffing_nn_model ~2.1 CPU s) made once: all tests here in one xdist worker (--dist loadgroup)
pytestmark = pytest.mark.xdist_group("dynamics")

TIGHT = {"rtol": 1e-11, "atol": 1e-13}  # finite-time exponents of a chaotic orbit are tolerance-sensitive


def test_symbolic_fitted_curves_give_the_exponent_of_the_truth(duffing):
    system, _ = duffing
    f1 = SymbolicFittedCurve("f1", "x'", (-1, 1), "0.3*z")
    f2 = SymbolicFittedCurve("f2", "x", (-1.5, 1.5), "z**3 - z")
    fitted = largest_lyapunov_exponent(f1, f2, system.forcing, 0.5, -0.5, t_transient=50, t_total=100, **TIGHT)
    truth = largest_lyapunov_exponent(system.f1, system.f2, system.forcing, 0.5, -0.5, t_transient=50,
                                      t_total=100, df1=lambda v: 0.3, df2=lambda x: 3 * x * x - 1, **TIGHT)
    assert fitted == pytest.approx(truth, abs=1e-3)  # measured: 0.1483 both, 3e-5 apart
    assert fitted > 0.05


def test_basis_curves_with_an_offset_give_minus_half_the_damping():
    # x'' + 0.2 x' + x + 0.5 = 0: the offset moves the equilibrium, both exponents stay -0.1
    f1 = BasisFittedCurve("f1", "x'", (-1, 1), ["z"], [0.2])
    f2 = BasisFittedCurve("f2", "x", (-2, 2), ["z"], [1.0])
    assert prepare_curve(f1).evaluation == "exact"  # closed forms are evaluated exactly by default
    for evaluation, renorm in (("auto", None), ("tabulated", None), ("tabulated", 1.0)):
        lam = largest_lyapunov_exponent(f1, f2, lambda t: 0.0, 1.0, 0.0, offset=0.5, t_transient=0.0,
                                        t_total=200.0, renorm_every=renorm, evaluation=evaluation)
        assert lam == pytest.approx(-0.1, abs=5e-3)


@pytest.fixture(scope="module")
def duffing_nn_model(duffing_20db):
    return cc.fit(duffing_20db, method="nn-cc+sym", random_state=0, threads=1)


def test_fitted_network_exponent_is_fast_and_the_table_does_not_change_it(duffing, duffing_nn_model):
    system, _ = duffing
    model = duffing_nn_model
    args = (model.curves["f1"], model.curves["f2"], system.forcing, 0.5, -0.5)
    kw = {"gain": model.gain, "offset": model.offset, "t_transient": 0.0, "t_total": 20.0, **TIGHT}
    tabulated = largest_lyapunov_exponent(*args, **kw)
    exact = largest_lyapunov_exponent(*args, evaluation="exact", **kw)  # numpy network + central differences
    assert tabulated == pytest.approx(exact, abs=1e-6)  # measured 1e-10 apart over 30 time units
    start = time.perf_counter()
    lam = largest_lyapunov_exponent(*args, gain=model.gain, offset=model.offset, t_transient=50, t_total=1000)
    seconds = time.perf_counter() - start
    assert 0.03 < lam < 0.25  # chaotic like the truth (0.10 in the long-time limit)
    assert seconds < 10  # measured 0.9-1.3 s (exact evaluation: about 25 s)


def test_a_model_without_a_finite_exponent_raises_a_simulation_error():
    with pytest.raises(SimulationError, match="Lyapunov|tangent vector"):
        largest_lyapunov_exponent(lambda v: 0.2 * np.asarray(v), lambda x: np.nan * np.asarray(x), lambda t: 0.0,
                                  1.0, 0.0, t_transient=0.0, t_total=10.0)
