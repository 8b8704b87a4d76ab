"""docs/deviations.md is the index of the deviations from the paper; their full text is on the topic pages it
links (issue 49, item 4). Each numbered item has a row, an entry and a heading its link reaches."""

from __future__ import annotations

import pathlib
import re

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
INDEX = (DOCS / "deviations.md").read_text(encoding="utf-8")
PAGES = ["deviations.md", "deviations-systems.md", "deviations-training.md", "deviations-symbolic.md",
         "deviations-benchmark.md", "beyond-the-paper.md"]
#: the entries of the index: "- **N. title** ([details](page.md#anchor))"
ENTRIES = re.findall(r"^- \*\*(\d+)\. [^*]+\*\*\s+\(\[details\]\(([\w-]+\.md)#([\w-]+)\)\)", INDEX, flags=re.M)


def _prose_words(text: str) -> int:
    """Words outside code blocks and tables, as /work/shared/tools/house.py counts them."""
    n, code = 0, False
    for line in text.splitlines():
        if line.strip().startswith("```"):
            code = not code
            continue
        if not code and not line.lstrip().startswith("|"):
            n += len(re.findall(r"\w+", line))
    return n


def test_every_numbered_deviation_has_a_row_and_an_entry():
    rows = [int(n) for n in re.findall(r"^\| (\d+) \| ", INDEX.split("## Remaining discrepancies")[0], flags=re.M)]
    assert rows == list(range(1, 29))
    assert sorted(int(n) for n, _, _ in ENTRIES) == rows


def test_each_entry_links_to_the_heading_of_its_item():
    slugify = pytest.importorskip("markdown.extensions.toc").slugify  # the site's own anchors (docs extra)
    for n, page, anchor in ENTRIES:
        headings = re.findall(r"^##+ (.+)$", (DOCS / page).read_text(encoding="utf-8"), flags=re.M)
        slugs = {slugify(h, "-"): h for h in headings}
        assert anchor in slugs, (n, page, anchor)
        assert slugs[anchor].startswith(f"{n}. "), (n, page, slugs[anchor])


def test_the_deviation_pages_are_short_and_in_the_nav():
    nav = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    for page in PAGES:
        assert f"- {page}\n" in nav, page
        words = _prose_words((DOCS / page).read_text(encoding="utf-8"))
        assert words <= 1500, (page, words)
