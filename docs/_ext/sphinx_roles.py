"""Griffe extension for the documentation build (mkdocs.yml): Sphinx roles become code spans.

Some docstrings name other objects with Sphinx roles, such as ``:func:`simulate_model```. Markdown
has no roles, so mkdocstrings would print the role text as it is. This extension rewrites each
role as a code span (``simulate_model`` in backticks) when griffe reads the docstring. The sources
are not changed.
"""

from __future__ import annotations

import re
from typing import Any

import griffe

_ROLE = re.compile(r":(?:py:)?(?:func|meth|class|attr|mod|data|obj|exc|const|ref):`~?\.?([^`<]+?)\s*(?:<[^`]*>)?`")


class SphinxRolesAsCode(griffe.Extension):
    """Rewrite ``:role:`name``` as a code span in every docstring."""

    def on_instance(self, *, obj: griffe.Object, **kwargs: Any) -> None:
        if obj.docstring is not None and ":" in obj.docstring.value:
            obj.docstring.value = _ROLE.sub(r"`\1`", obj.docstring.value)
