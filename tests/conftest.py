import os
from pathlib import Path

# Tests run on small shared machines: one torch/BLAS thread per process is fastest there.
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MPLBACKEND", "Agg")
# MKL's matrix products may differ in the last bit with the memory alignment of their operands;
# strict conditional reproducibility removes that (read when torch loads MKL, so set it first)
os.environ.setdefault("MKL_CBWR", "AUTO,STRICT")

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from hypothesis import settings as hypothesis_settings  # noqa: E402

# The property tests (hypothesis) draw their examples from a fixed seed per test, so that a test
# run cannot pass or fail by chance and every run checks the same inputs; no example database is
# read or written. HYPOTHESIS_PROFILE=explore draws fresh random examples, to hunt for new failures
# (a failure found that way is printed with its reproducing seed and belongs in a fixed test).
hypothesis_settings.register_profile("fixed", derandomize=True, database=None)
hypothesis_settings.register_profile("explore", derandomize=False, database=None)
hypothesis_settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "fixed"))


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


@pytest.fixture(scope="session")
def turning_pendulum():
    """The turning pendulum of issue 20: x'' + 0.2 x' + 9.81 sin x = 6 sin 1.3t + 4 sin 2.3t, x(0) = 0.3,
    2 000 samples over 60 s (x runs to about 100 rad), 30 dB on F, v and a given."""
    from scipy.integrate import solve_ivp

    from charcurves.data import Trajectory, corrupt

    def force(t):
        return 6 * np.sin(1.3 * t) + 4 * np.sin(2.3 * t)

    t = np.linspace(0, 60, 2000)
    sol = solve_ivp(lambda s, y: [y[1], force(s) - 0.2 * y[1] - 9.81 * np.sin(y[0])], (0, 60), [0.3, 0.0],
                    t_eval=t, rtol=1e-10, atol=1e-10)
    x, v = sol.y
    return corrupt(Trajectory(t=t, x=x, F=force(t), v=v, a=force(t) - 0.2 * v - 9.81 * np.sin(x)), 30.0, seed=0)


def real_data_file(relative: str) -> Path:
    """A measured record in the real-data folder: $CHARCURVES_DATA_DIR, else ../shared/real-data from the
    repository root (docs/silverbox.md)."""
    folder = os.environ.get("CHARCURVES_DATA_DIR") or Path(__file__).resolve().parents[2] / "shared" / "real-data"
    return Path(folder) / relative


@pytest.fixture(scope="session")
def silverbox_csv() -> Path:
    """The Silverbox record SNLS80mV.csv: $SILVERBOX_CSV, else silverbox/SNLS80mV.csv of the real-data
    folder; a test that needs it skips, saying where it looked, when the file is not there."""
    given = os.environ.get("SILVERBOX_CSV")
    path = Path(given) if given else real_data_file(os.path.join("silverbox", "SNLS80mV.csv"))
    if not path.is_file():
        pytest.skip(f"the real Silverbox record SNLS80mV.csv is not at {path}; set SILVERBOX_CSV to the file, "
                    "or CHARCURVES_DATA_DIR to the folder that holds silverbox/SNLS80mV.csv")
    return path
