"""The paper's twelve methods as presets: each names a representation per curve, a prior and post-SR.

``method="nn-cc+sym"`` (and the CLI's ``--method``) is a shorthand for composing objects: it
builds ``Neural(symmetry="odd")`` for every curve of the template, ``"poly-cc"`` a ``Polynomial``,
``"sindy-cc+sym"`` an odd ``SparseLibrary``, ``"sr-cc"`` a ``Symbolic`` curve (``"sr-cc+refit"``:
``Symbolic(refit=True)``), ``"parametric"`` a
``Basis`` per curve; ``+post-sr`` distils the fitted curves into closed forms afterwards.
"""

from __future__ import annotations

import numpy as np

from .._errors import ConfigError
from .._method_table import METHODS as METHODS  # pure data: the CLI reads it without loading torch
from ..curves import SYMMETRY_NAMES, Basis, Neural, Polynomial, SparseLibrary, Symbolic

__all__ = ["METHODS", "parse_symmetry", "parse_basis_option", "DEFAULT_BASIS", "DEFAULT_GENERAL_BASIS",
           "method_curve", "check_method_options", "POLY_OPTIONS", "SINDY_OPTIONS", "shared_fit_base"]


def shared_fit_base(method: str) -> str | None:
    """The method whose fit ``method`` extends, or None: X for "X+post-sr" (the same networks or
    libraries, then distilled: :func:`charcurves.fitting.fit_with_post_sr` fits both at once), "sr-cc"
    for "sr-cc+refit" (the same searches, then a joint refit; the engine runs a search asked twice in
    a process once).

    Examples
    --------
    >>> from charcurves.fitting import shared_fit_base
    >>> shared_fit_base("nn-cc+sym+post-sr"), shared_fit_base("sr-cc+refit"), shared_fit_base("nn-cc")
    ('nn-cc+sym', 'sr-cc', None)
    """
    spec = METHODS.get(method)
    if spec is None or not (spec.get("post_sr") or spec.get("refit")):
        return None

    def core(s: dict) -> dict:
        return {k: v for k, v in s.items() if k not in ("post_sr", "refit")}

    return next((m for m, s in METHODS.items() if not (s.get("post_sr") or s.get("refit")) and core(s) == core(spec)),
                None)


#: The paper's Parametric basis for Duffing, f1 = a1 x', f2 = a2 x + a3 x^3: pass it as
#: ``basis=DEFAULT_BASIS`` (parametric has no default basis).
DEFAULT_BASIS = {"f1": ["z"], "f2": ["z", "z**3"]}
#: A cubic polynomial per curve, to pass as ``basis=DEFAULT_GENERAL_BASIS`` (constants that
#: curves trade are resolved by the gauge after the fit).
DEFAULT_GENERAL_BASIS = ["1", "z", "z**2", "z**3"]

POLY_OPTIONS = ("degree", "rescaling", "basis", "expand_tol", "constant", "exclude_sticking", "stick_tol")
SINDY_OPTIONS = ("threshold", "degree", "max_iter", "alpha", "nu", "tol", "rescaling", "exclude_sticking", "stick_tol")
_SR_OPTIONS = ("stick_tol",)
_SRCC_OPTIONS = ("stick_tol", "outer_iterations", "inner_generations", "tol")


def parse_symmetry(sym, curve_names=("f1", "f2")) -> dict[str, str]:
    """``"f1=odd,f2=odd"`` / ``{"f1": "odd"}`` / ``"odd"`` (all curves) -> ``{"f1": "odd", "f2": "odd"}``.

    Examples
    --------
    >>> from charcurves.fitting import parse_symmetry
    >>> parse_symmetry("f1=odd"), parse_symmetry("odd"), parse_symmetry({"f2": "even"})
    ({'f1': 'odd', 'f2': 'none'}, {'f1': 'odd', 'f2': 'odd'}, {'f1': 'none', 'f2': 'even'})
    """
    out = {name: "none" for name in curve_names}
    if sym is None or sym == "":
        return out
    if isinstance(sym, str):
        if "=" not in sym:
            items = {name: sym.strip() for name in curve_names}
        else:
            items = {}
            for part in sym.split(","):
                if not part.strip():
                    continue
                if "=" not in part:
                    raise ConfigError(f"symmetry {part.strip()!r} needs the form CURVE=odd|even|none, e.g. f1=odd,f2=odd")
                k, v = part.split("=", 1)
                if k.strip() in items:  # the last one won silently before (issue 50)
                    raise ConfigError(f"symmetry names {k.strip()} twice ({sym.strip()!r}); give each curve once, "
                                      "e.g. f1=odd,f2=odd")
                items[k.strip()] = v.strip()
    elif isinstance(sym, dict):
        items = {str(k): str(v) for k, v in sym.items()}
    else:
        raise ConfigError(f"symmetry must be a string like 'f1=odd,f2=odd' or a dict, got {type(sym).__name__}")
    for k, v in items.items():
        if k not in curve_names:
            raise ConfigError(f"symmetry given for unknown curve {k!r}; the curves are {', '.join(curve_names)}")
        if v not in SYMMETRY_NAMES:
            raise ConfigError(f"unknown symmetry {v!r} for {k}; choose one of {', '.join(SYMMETRY_NAMES)}")
        out[k] = v
    return out


def parse_basis_option(text, curve_names=("f1", "f2"), *, family: str = "separable") -> dict[str, list[str]]:
    """``"f1=z; f2=z, z**3"`` -> ``{"f1": ["z"], "f2": ["z", "z**3"]}`` (z is the curve's argument).

    A dict gives each curve's functions, a list the same functions for every curve. There is no
    default: None is a ConfigError naming ``basis=`` / ``--basis`` (the paper's Duffing basis is
    :data:`DEFAULT_BASIS`, a cubic per curve :data:`DEFAULT_GENERAL_BASIS`; pass them explicitly).

    Examples
    --------
    >>> from charcurves.fitting import DEFAULT_GENERAL_BASIS, parse_basis_option
    >>> parse_basis_option("f1=z; f2=z, z**3")
    {'f1': ['z'], 'f2': ['z', 'z**3']}
    >>> parse_basis_option(["z", "z**3"])
    {'f1': ['z', 'z**3'], 'f2': ['z', 'z**3']}
    """
    from ..curves import parse_basis_function

    if text is None or (isinstance(text, str) and not text.strip()):
        example = "; ".join(f"{n}=z, z**3" for n in curve_names)
        raise ConfigError(f"method 'parametric' needs a basis per curve: give basis=\"{example}\" (CLI: --basis "
                          f"\"{example}\"; z is the curve's argument), or basis=DEFAULT_BASIS for the paper's Duffing "
                          "basis")
    if isinstance(text, (list, tuple)):
        text = {n: list(text) for n in curve_names}
    if isinstance(text, dict):
        out = {k: [str(b) for b in (v if isinstance(v, (list, tuple)) else [v])] for k, v in text.items()}
    else:
        out = {}
        for part in str(text).split(";"):
            if not part.strip():
                continue
            if "=" not in part:
                raise ConfigError(f"basis part {part.strip()!r} has no '='; write e.g. \"f1=z; f2=z, z**3\"")
            name, funcs = part.split("=", 1)
            if name.strip() in out:  # the last one won silently before (issue 50)
                raise ConfigError(f"basis names {name.strip()} twice; give each curve's functions once, e.g. "
                                  "\"f1=z; f2=z, z**3\"")
            out[name.strip()] = [f.strip() for f in funcs.split(",") if f.strip()]
    unknown = set(out) - set(curve_names)
    if unknown:
        raise ConfigError(f"basis given for unknown curve(s) {sorted(unknown)}; the curves are {', '.join(curve_names)}")
    missing = [c for c in curve_names if not out.get(c)]
    if missing:
        raise ConfigError(f"no basis functions for {missing}; write e.g. \"f1=z; f2=z, z**3\"")
    for name, fs in out.items():
        seen: dict = {}
        for f in fs:
            expr = parse_basis_function(f)
            if expr in seen:  # two equal columns: a singular least-squares problem
                raise ConfigError(f"basis of {name} lists {seen[expr]!r} and {f!r}, the same function twice; "
                                  "give each function once")
            seen[expr] = f
    return out


def check_method_options(method: str, options: dict | None) -> dict:
    """The ``options`` of a method, checked (unknown keys are a ConfigError naming the valid ones)."""
    options = dict(options or {})
    rep = METHODS[method]["representation"]
    valid = {"poly": POLY_OPTIONS, "sindy": SINDY_OPTIONS, "sr": _SR_OPTIONS, "sr-cc": _SRCC_OPTIONS,
             "basis": ("exclude_sticking", "stick_tol"), "neural": ("exclude_sticking", "stick_tol")}[rep]
    unknown = sorted(set(options) - set(valid))
    if unknown:
        label = {"poly": "poly-cc", "sindy": "SINDy"}.get(rep)
        if label:
            raise ConfigError(f"unknown {label} option(s) {unknown}; valid: {', '.join(valid)}")
        raise ConfigError(f"unknown option(s) {unknown} for {method}; valid: {', '.join(valid) or 'none'}")
    return options


def method_curve(method: str, name: str, *, symmetry: str, jump, options: dict, basis: dict | None,
                 hidden=None, activation=None, velocity: bool = False):
    """The representation ``method`` gives curve ``name``."""
    spec = METHODS[method]
    rep = spec["representation"]
    sym = None if symmetry == "none" else symmetry
    if rep == "neural":
        if jump == "auto":
            j = "auto" if velocity else False
        else:
            j = name in jump
        return Neural(hidden=tuple(hidden) if hidden else None, activation=activation, symmetry=sym, jump=j)
    if rep == "poly":
        kw = {k: options[k] for k in ("degree", "rescaling", "basis", "expand_tol") if k in options}
        curve: Polynomial | SparseLibrary = Polynomial(symmetry=sym, **kw)
        curve.check()
        return curve
    if rep == "sindy":
        kw = {k: options[k] for k in ("threshold", "degree", "max_iter", "alpha", "nu", "tol", "rescaling") if k in options}
        curve = SparseLibrary(symmetry=sym if spec["symmetry"] else None,
                              optimizer="stlsq" if spec.get("free_gain") else "constrained-sr3", **kw)
        curve.check()
        return curve
    if rep in ("sr", "sr-cc"):
        return Symbolic(joint=rep == "sr", refit=bool(spec.get("refit", False)))
    return Basis(list((basis or {})[name]))


def poly_constant_option(options: dict) -> bool:
    value = options.get("constant", True)
    if not isinstance(value, (bool, np.bool_)):
        raise ConfigError(f"poly-cc option constant must be True or False, got {value!r}")
    return bool(value)
