"""charcurves.datasets: the Silverbox's official split from local files; benchmark --real."""

from __future__ import annotations

import json

import numpy as np
import pytest

from charcurves._errors import ConfigError
from charcurves.datasets import BENCHMARKS, get_benchmark, silverbox


@pytest.fixture(scope="module")
def silverbox_dir(silverbox_csv):
    return silverbox_csv.parent.parent  # the folder that holds silverbox/SNLS80mV.csv


def test_silverbox_has_the_official_split_and_window(silverbox_dir):
    data = silverbox(data_dir=silverbox_dir)
    assert data.estimation.n_samples == 105712 - 40650
    assert {k: v.n_samples for k, v in data.tests.items()} == {
        "multisine": 127400 - 105712, "arrow_full": 40575 - 100, "arrow_no_extrapolation": 32000}
    assert data.init_window == 50 and data.unit == "mV"
    assert data.estimation.dt == pytest.approx(2**14 / 1e7, rel=1e-9)
    # the arrow without extrapolation is the first 32000 samples of the full arrow
    np.testing.assert_array_equal(data.tests["arrow_no_extrapolation"].x, data.tests["arrow_full"].x[:32000])


def test_a_folder_without_the_record_names_the_fix(tmp_path, monkeypatch):
    with pytest.raises(ConfigError, match=r"no Silverbox record at .*SNLS80mV.csv; give the folder that holds "
                                          r"silverbox/SNLS80mV.csv"):
        silverbox(data_dir=tmp_path)
    monkeypatch.setenv("CHARCURVES_DATA_DIR", str(tmp_path))
    with pytest.raises(ConfigError, match="no Silverbox record at"):
        get_benchmark("silverbox")
    with pytest.raises(ConfigError, match=f"unknown real benchmark 'bouc'; choose one of {', '.join(BENCHMARKS)}"):
        get_benchmark("bouc")


def test_benchmark_real_quick_run_writes_the_test_rmse(silverbox_dir, tmp_path, capsys):
    from charcurves.cli import main
    from charcurves.experiments import run_real_benchmark
    from charcurves.fitting import CharacteristicCurves

    est = CharacteristicCurves.from_method(method="parametric", basis="f1=z; f2=z, z**3", free_gain=True,
                               objective="equation-error")
    doc = run_real_benchmark("silverbox", tmp_path / "q", data_dir=silverbox_dir, max_samples=4096, estimator=est)
    assert doc["quick"] and doc["init_window"] == 50 and list(doc["tests"]) == [
        "multisine", "arrow_full", "arrow_no_extrapolation"]
    for r in doc["tests"].values():  # the Duffing structure on a 4096-sample slice: a few mV at most
        assert r["status"] == "ok" and 0.1 < r["rmse_mV"] < 5.0 and r["counted_samples"] == 4096 - 50
    assert json.loads((tmp_path / "q" / "real.json").read_text())["tests"]["multisine"]["rmse_mV"] == \
        pytest.approx(doc["tests"]["multisine"]["rmse_mV"])
    code = main(["benchmark", "--data-dir", str(tmp_path), "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err
    assert code == 2 and "--data-dir goes with --real" in err
