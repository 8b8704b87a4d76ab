"""MkDocs hooks of the documentation build (mkdocs.yml, ``hooks:``).

- The math of the pages becomes MathML when the site is built. ``pymdownx.arithmatex`` (generic
  mode) marks each formula, ``$...$`` inline and ``$$...$$`` as a block, and this hook converts
  the marked LaTeX with ``latex2mathml`` (the ``docs`` extra). Browsers draw MathML themselves, so
  the pages need no JavaScript, no font download and no network. A formula that latex2mathml
  cannot read stops the build.
- The repository link of the site (``repo_url``) is read from pyproject.toml,
  ``[project.urls]`` ``Repository`` (or ``Source``), so that it is written in one place. Without
  one the site has no repository link.
"""

from __future__ import annotations

import html
import pathlib
import re
import sys
from typing import Any

from latex2mathml.converter import convert

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

# what pymdownx.arithmatex writes in generic mode (its LaTeX is HTML-escaped)
_BLOCK = re.compile(r'<div class="arithmatex">\\\[(.*?)\\\]</div>', re.S)
_INLINE = re.compile(r'<span class="arithmatex">\\\((.*?)\\\)</span>', re.S)


def latex_to_mathml(page_html: str) -> str:
    """Every formula that arithmatex marked in ``page_html``, written as MathML."""
    page_html = _BLOCK.sub(lambda m: '<div class="math">' + convert(html.unescape(m.group(1)).strip(),
                                                                   display="block") + "</div>", page_html)
    return _INLINE.sub(lambda m: convert(html.unescape(m.group(1)).strip()), page_html)


def on_config(config: Any, **kwargs: Any) -> Any:
    pyproject = pathlib.Path(config["config_file_path"]).parent / "pyproject.toml"
    urls = tomllib.loads(pyproject.read_text(encoding="utf-8")).get("project", {}).get("urls", {})
    url = urls.get("Repository") or urls.get("Source")
    if url and not config.get("repo_url"):
        config["repo_url"] = url
        config["repo_name"] = config.get("repo_name") or url.rstrip("/").split("/", 3)[-1]
    return config


def on_page_content(html_text: str, **kwargs: Any) -> str:
    return latex_to_mathml(html_text)
