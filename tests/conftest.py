import os

# Tests run on small shared machines: one torch/BLAS thread per process is fastest there.
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MPLBACKEND", "Agg")
# MKL's matrix products may differ in the last bit with the memory alignment of their operands;
# strict conditional reproducibility removes that (read when torch loads MKL, so set it first)
os.environ.setdefault("MKL_CBWR", "AUTO,STRICT")

import numpy as np  # noqa: E402
import pytest  # noqa: E402


@pytest.fixture(scope="session")
def duffing():
    from charcurves.systems import get_system

    system = get_system("duffing")
    return system, system.simulate()


@pytest.fixture(scope="session")
def duffing_20db(duffing):
    from charcurves.data import corrupt

    system, clean = duffing
    return corrupt(clean, 20.0, on="force", seed=0)


@pytest.fixture(autouse=True, scope="session")
def _torch_threads():
    import torch

    torch.set_num_threads(1)
    yield


def rmse(a, b):
    return float(np.sqrt(np.mean((np.asarray(a) - np.asarray(b)) ** 2)))
