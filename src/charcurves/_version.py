"""The package version, in one place.

``pyproject.toml`` reads it for the distribution's metadata (``[tool.setuptools.dynamic]``),
``charcurves.__version__`` re-exports it, and ``charcurves --version`` prints it.
"""

__version__ = "0.1.0"
#: The same, under a plain name (what ``charcurves/__init__.py`` imports).
VERSION = __version__
