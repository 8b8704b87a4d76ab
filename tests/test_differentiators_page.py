"""The figures that docs/differentiators.md's prose derives from its tables (ratios, counts, ranges) are the ones
the committed ``benchmarks/results/differentiators.json`` gives; the tables themselves are rendered
(tests/test_docs_tables.py)."""

from __future__ import annotations

import json
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results" / "differentiators.json"
PAGE = " ".join((ROOT / "docs" / "differentiators.md").read_text(encoding="utf-8").split())
METHODS = ("nn-cc+sym", "parametric", "poly-cc")


@pytest.fixture(scope="module")
def summary():
    if not RESULTS.exists():
        pytest.skip("the committed results are not in this checkout")
    return json.loads(RESULTS.read_text(encoding="utf-8"))["summary"]


def _fit(summary, record, method, diff):
    return summary["fits"][record][f"{method} | equation-error | {diff}"]["worst_mean"]


def test_kalman_against_spectral_and_savgol_on_duffing(summary):
    ratios = [_fit(summary, f"duffing {snr} dB", m, "spectral") / _fit(summary, f"duffing {snr} dB", m, "kalman")
              for snr in (40, 30) for m in METHODS]
    assert (round(min(ratios), 2), round(max(ratios), 1)) == (1.26, 2.1)
    assert "falls 1.26–2.1× at 40 and 30 dB for all three methods" in PAGE
    savgol = [_fit(summary, f"duffing {snr} dB", m, "savgol 31/3") / _fit(summary, f"duffing {snr} dB", m, "kalman")
              for snr in (40, 30) for m in METHODS]
    assert (round(min(savgol), 1), round(max(savgol))) == (2.2, 20) and "Savitzky–Golay 31/3 by 2.2–20×" in PAGE
    at20 = {m: _fit(summary, "duffing 20 dB", m, "spectral") / _fit(summary, "duffing 20 dB", m, "kalman") - 1
            for m in METHODS}
    assert max(abs(at20["nn-cc+sym"]), abs(at20["parametric"])) < 0.03 and round(100 * at20["poly-cc"]) == 19
    assert "for nn-cc+sym and parametric (within 3 %) and is 19 % ahead for poly-cc" in PAGE


def test_kalman_against_spectral_on_stick_slip(summary):
    behind = {snr: {m: _fit(summary, f"stick-slip {snr} dB", m, "kalman")
                    / _fit(summary, f"stick-slip {snr} dB", m, "spectral") - 1 for m in METHODS} for snr in (30, 20)}
    assert max(abs(behind[30]["nn-cc+sym"]), abs(behind[30]["parametric"])) < 0.02
    assert round(100 * behind[30]["poly-cc"]) == 8
    assert (round(100 * min(behind[20].values())), round(100 * max(behind[20].values()))) == (3, 13)
    assert ("within 2 % of `spectral` at 30 dB for nn-cc+sym and parametric (8 % behind for poly-cc), "
            "3–13 % behind it at 20 dB") in PAGE


def test_tvr_counts(summary):
    d = summary["derivatives"]
    assert all(d[r]["tvr"]["a_interior"] > d[r]["kalman"]["a_interior"] for r in d)
    assert sum(d[r]["tvr"]["a_interior"] > d[r]["spectral"]["a_interior"] for r in d) == 4
    pairs = [(r, m) for r in summary["fits"] for m in METHODS]
    assert len(pairs) == 18
    assert sum(_fit(summary, r, m, "tvr") > _fit(summary, r, m, "kalman") for r, m in pairs) == 17
    assert sum(_fit(summary, r, m, "tvr") < _fit(summary, r, m, "spectral") for r, m in pairs) == 6
    assert "behind `spectral` on 4 of the 6) and in 17 of the 18 fits (ahead of `spectral` in 6)" in PAGE
    slower = [d[r]["tvr"]["seconds"] / d[r]["kalman"]["seconds"] for r in d]
    assert 5 < sum(slower) / len(slower) < 7 and "about 6× slower than `kalman`" in PAGE
