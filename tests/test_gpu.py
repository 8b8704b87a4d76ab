"""The CUDA leg: a small NN-CC fit on the GPU agrees with the same fit on the CPU.

Runs wherever ``torch.cuda.is_available()``; skipped (with the reason) elsewhere. docs/gpu.md
measured the largest CPU/CUDA curve difference at 1.7e-4 (float64; the devices sum in different
orders and Levenberg-Marquardt amplifies that slightly), so 1e-3 leaves a margin while a wrong
device path (float32, a lost symmetry, another record) is off by far more.
"""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

pytestmark = pytest.mark.skipif(not torch.cuda.is_available(),
                                reason="no CUDA device (torch.cuda.is_available() is False): the GPU leg runs on "
                                       "a machine with one")


@pytest.fixture(scope="module")
def records():
    from charcurves.data import corrupt
    from charcurves.systems import get_system

    system = get_system("duffing")
    clean = system.simulate()
    return system, [corrupt(clean, 20.0, seed=s) for s in (0, 1)]


@pytest.mark.parametrize("method", ["nn-cc+sym", "nn-cc"])
def test_cuda_and_cpu_curves_agree(records, method):
    from charcurves.fitting import CharacteristicCurves
    from charcurves.metrics import curve_errors

    system, recs = records
    fits = {}
    for device in ("cpu", "cuda"):
        fits[device] = CharacteristicCurves.from_method(method=method, device=device, threads=1).fit_many(recs, seeds=[0, 1])
    for cpu, gpu in zip(fits["cpu"], fits["cuda"]):
        for name in ("f1", "f2"):
            lo, hi = cpu.curves[name].domain
            z = np.linspace(lo, hi, 201)
            a, b = np.asarray(cpu.curves[name](z)), np.asarray(gpu.curves[name](z))
            assert a.dtype == b.dtype == np.float64
            assert np.max(np.abs(a - b)) < 1e-3, (name, np.max(np.abs(a - b)))
        e_cpu, e_gpu = curve_errors(cpu, system.true_curves()), curve_errors(gpu, system.true_curves())
        assert e_gpu["f1"] < 1e-2 and e_gpu["f2"] < 1e-2, e_gpu  # both fits are good, not merely equal
        assert abs(e_gpu["f2"] - e_cpu["f2"]) < 1e-3
