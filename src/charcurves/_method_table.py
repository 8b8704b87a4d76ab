"""The named methods' table, pure data with no heavy import: :data:`charcurves.fitting.METHODS` is this
dict, and the command line reads it here so that ``--help``, ``simulate`` and its usage errors do not
load torch and the fitting stack (issue 49)."""

from __future__ import annotations

from typing import Any

__all__ = ["METHODS"]

#: The paper's twelve methods as named presets of shared parts: a curve representation, whether a
#: symmetry prior applies (odd curves unless told otherwise) and whether the learned curves are
#: distilled into closed forms afterwards (post-SR); and ``sr-cc+refit``, SR-CC with a joint
#: least-squares refit of the coefficients of the structure SR found (``Symbolic(refit=True)``).
METHODS: dict[str, dict[str, Any]] = {
    "nn-cc": {"representation": "neural", "symmetry": False, "post_sr": False},
    "nn-cc+post-sr": {"representation": "neural", "symmetry": False, "post_sr": True},
    "nn-cc+sym": {"representation": "neural", "symmetry": True, "post_sr": False},
    "nn-cc+sym+post-sr": {"representation": "neural", "symmetry": True, "post_sr": True},
    "poly-cc": {"representation": "poly", "symmetry": False, "post_sr": False, "allows_symmetry": True},
    "sindy": {"representation": "sindy", "symmetry": False, "post_sr": False, "free_gain": True},
    "sindy-cc": {"representation": "sindy", "symmetry": False, "post_sr": False},
    "sindy-cc+sym": {"representation": "sindy", "symmetry": True, "post_sr": False},
    "sindy-cc+sym+post-sr": {"representation": "sindy", "symmetry": True, "post_sr": True},
    "sr": {"representation": "sr", "symmetry": False, "post_sr": False},
    "sr-cc": {"representation": "sr-cc", "symmetry": False, "post_sr": False},
    # not one of the paper's twelve: SR-CC whose found structure is refitted jointly by least squares
    "sr-cc+refit": {"representation": "sr-cc", "symmetry": False, "post_sr": False, "refit": True},
    "parametric": {"representation": "basis", "symmetry": False, "post_sr": False},
}
