"""The headline tables of docs/benchmark.md are the ones the committed results give (issue 49, item 5):
each is written between its ``<!-- table:NAME -->`` markers by ``python benchmarks/render_docs.py``, so a
rerun updates the page and a typed number that the results do not give fails here."""

from __future__ import annotations

import pathlib
import re

import pytest

from charcurves.experiments import docs_tables, fill_table_markers

ROOT = pathlib.Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "benchmark.md"
RESULTS = ROOT / "benchmarks" / "results"
NAMES = {"full-duffing", "full-stick-slip", "scripts-duffing", "scripts-stick-slip", "paper-cpu", "appendix-f"}


@pytest.fixture(scope="module")
def tables():
    if not (RESULTS / "full" / "results.csv.gz").exists():
        pytest.skip("the committed results are not in this checkout")
    return docs_tables(RESULTS)


def test_every_table_of_the_page_is_the_one_the_committed_results_give(tables):
    text = PAGE.read_text(encoding="utf-8")
    markers = re.findall(r"<!-- table:([a-z0-9-]+) -->", text)
    assert sorted(markers) == sorted(NAMES) and set(tables) == NAMES  # each table once, none left typed
    assert fill_table_markers(text, tables) == text, "run `python benchmarks/render_docs.py` and commit the page"


def test_a_table_shows_the_committed_values(tables):
    # one row per method of both systems, as the report's Table 2 (benchmarks/results/full/report.md)
    rows = [r for r in tables["full-duffing"].splitlines()[2:]]
    assert len(rows) == 13
    assert rows[0] == ("| nn-cc | 0.0130 / 0.0154 | (0.0158 / 0.0176) | 0.112 / 0.104 | 8.58 / 6.74 | 85.3 % (12.5 %) "
                       "| -10 dB (0 dB) | 1.04 |")
    assert "| parametric | 0.0101 / 0.0143 |" in tables["full-duffing"]
    assert "| poly-cc, bias fit (b, A) | (0.217, 0.490) / (0.070, 0.425) | (0.195, 0.294) / (0.079, 0.310) |" in (
        tables["full-stick-slip"])
    assert len(tables["appendix-f"].splitlines()) == 2 + 26


def test_a_marker_without_a_table_is_refused_by_name():
    with pytest.raises(ValueError, match="no table named 'nope' for its marker"):
        fill_table_markers("<!-- table:nope -->\nold\n<!-- /table -->\n", {"t": "x\n"})
    page = "a\n<!-- table:t -->\nold\n<!-- /table -->\nb\n<!-- table:t -->\n<!-- /table -->\n"
    assert fill_table_markers(page, {"t": "| 1 |\n"}) == (
        "a\n<!-- table:t -->\n| 1 |\n<!-- /table -->\nb\n<!-- table:t -->\n| 1 |\n<!-- /table -->\n")
