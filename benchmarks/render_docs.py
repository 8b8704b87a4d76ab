"""Write the headline tables of docs/benchmark.md, measured-records.md, training-defaults.md, silverbox.md, differentiators.md, choosing.md, uncertainty-zoo.md, selection.md, several-records.md and zoo.md from the committed results in benchmarks/results/.

Usage: ``python benchmarks/render_docs.py`` rewrites every ``<!-- table:NAME -->`` ... ``<!-- /table -->``
block of the page from the results (run it after committing a rerun); ``--check`` writes nothing and exits 1
when the page differs from what the results give (tests/test_docs_tables.py checks the same).
"""
import pathlib
import sys

from charcurves.experiments import docs_tables, fill_table_markers

ROOT = pathlib.Path(__file__).resolve().parents[1]
PAGES = [ROOT / "docs" / name for name in ("benchmark.md", "measured-records.md", "training-defaults.md", "silverbox.md",
                                                "differentiators.md", "choosing.md", "uncertainty-zoo.md",
                                                "selection.md", "several-records.md", "zoo.md")]


def main(argv):
    tables = docs_tables(ROOT / "benchmarks" / "results")
    stale = []
    for page in PAGES:
        text = page.read_text(encoding="utf-8")
        new = fill_table_markers(text, tables)
        if new != text:
            stale.append(page)
            if "--check" not in argv:
                page.write_text(new, encoding="utf-8")
    for page in stale:
        print(f"{page.relative_to(ROOT)}: {'differs from the results' if '--check' in argv else 'tables rewritten'}")
    return 1 if stale and "--check" in argv else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
