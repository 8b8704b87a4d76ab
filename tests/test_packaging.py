"""Release packaging: the version in one place, py.typed, CITATION.cff, and the API reference
pages of the documentation site (docs/api/, mkdocs.yml) kept in step with the package."""

from __future__ import annotations

import importlib.metadata
import importlib.resources
import re
from pathlib import Path

import pytest

import charcurves

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "charcurves"


def test_version_comes_from_version_module():
    from charcurves._version import __version__

    assert charcurves.__version__ == __version__
    assert re.fullmatch(r"\d+\.\d+\.\d+([ab]|rc|\.dev|\.post)?\d*", __version__)


def test_version_matches_installed_distribution():
    installed = importlib.metadata.version("charcurves")
    assert charcurves.__version__ == installed, (
        f"src/charcurves/_version.py says {charcurves.__version__} but the installed metadata says "
        f"{installed}; reinstall with pip install -e ."
    )


def test_pyproject_reads_version_from_version_module():
    tomllib = pytest.importorskip("tomllib")
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    assert "version" not in config["project"]
    assert config["project"]["dynamic"] == ["version"]
    assert config["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "charcurves._version.__version__"}
    assert "py.typed" in config["tool"]["setuptools"]["package-data"]["charcurves"]


def test_py_typed_is_in_the_package():
    assert (importlib.resources.files("charcurves") / "py.typed").is_file()


def test_citation_version_matches_package():
    text = (ROOT / "CITATION.cff").read_text(encoding="utf-8")
    match = re.search(r"^version:\s*['\"]?([^'\"\s]+)['\"]?\s*$", text, re.MULTILINE)
    assert match, "CITATION.cff has no top-level version"
    assert match.group(1) == charcurves.__version__


def test_changelog_and_license_exist():
    assert "## [Unreleased]" in (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
    assert (ROOT / "LICENSE").read_text(encoding="utf-8").startswith("MIT License")


def test_api_index_lists_every_top_level_name():
    text = (ROOT / "docs" / "api" / "index.md").read_text(encoding="utf-8")
    rows = dict(re.findall(r"^\| \[`(\w+)`\]\[([\w.]+)\] \|", text, re.MULTILINE))
    assert sorted(rows) == sorted(charcurves._LAZY), (
        "the top-level table of docs/api/index.md must list exactly the names of charcurves._LAZY"
    )
    for name, target in rows.items():
        assert target == f"{charcurves._LAZY[name]}.{name}", f"{name} links to {target}"


def _exporting_subpackages() -> list[str]:
    """Subpackages whose __init__ imports names (the command line is documented in the README)."""
    names = []
    for init in sorted(PACKAGE.glob("*/__init__.py")):
        name = init.parent.name
        if name != "cli" and re.search(r"^from \.\w* ?import ", init.read_text(encoding="utf-8"), re.MULTILINE):
            names.append(name)
    return names


def test_every_subpackage_has_an_api_page():
    nav = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    subpackages = _exporting_subpackages()
    assert {"data", "fitting", "curves", "templates"} <= set(subpackages)
    for name in subpackages:
        page = ROOT / "docs" / "api" / f"{name}.md"
        assert page.is_file(), f"charcurves.{name} exports names but has no page {page.relative_to(ROOT)}"
        assert f"::: charcurves.{name}\n" in page.read_text(encoding="utf-8")
        assert f"- api/{name}.md\n" in nav, f"api/{name}.md is not in the nav of mkdocs.yml"
