"""The model.json schema and its check (docs/model-format.md describes the same format)."""

from __future__ import annotations

import numpy as np

from .._errors import ModelFileError
from ..curves import expression_cost_problem

__all__ = ["MODEL_SCHEMA", "validate_model_document", "FORMAT_VERSION", "MAX_MODEL_MAGNITUDE", "model_digest",
           "check_model_digest", "check_array_values"]

FORMAT_VERSION = 1
_MODEL_JSON = "model.json"

#: The largest magnitude a number of a model file may have (gain, offset, domains, scales, weights) and, for
#: the gain and the scales, the inverse of the smallest: far beyond any fit, small enough that products
#: and squares of them stay finite in float64 (an output scale of 1e308 would overflow every evaluation).
MAX_MODEL_MAGNITUDE = 1e100
_SCALES = ("in_scale", "out_scale", "half_width")
_CURVE_NUMBERS = ("shift", "in_scale", "in_center", "out_scale", "center", "half_width", "constant")


# ---------------------------------------------------------------------- model.json schema
# A plain-Python schema (docs/model-format.md describes the same): a type per key, nested dicts
# for objects, a one-element list for "list of". Keys may be added in later releases of the same
# format version, so unknown keys are ignored; missing or mistyped ones are errors.
_NUMBER = "number"
_TEMPLATE_SCHEMA = {"family": str}
_CURVE_SCHEMA = {"kind": str, "name": str, "argument": str, "domain": [_NUMBER], "shift": _NUMBER}
_CURVE_KIND_SCHEMA = {
    "neural": {"network": {"hidden": [int], "activation": str, "symmetry": str, "symmetry_mode": str,
                           "linear_term": bool, "jump": bool},
               "in_scale": _NUMBER, "out_scale": _NUMBER},
    "basis": {"basis": [str]},
    "symbolic": {"expression": str},
    "linear": {"representation": str, "parameters": dict, "center": _NUMBER, "half_width": _NUMBER,
               "constant": _NUMBER},
}
MODEL_SCHEMA = {
    "format": str,
    "format_version": int,
    "template": _TEMPLATE_SCHEMA,
    "method": str,
    "gain": _NUMBER,
    "offset": _NUMBER,
    "loss": "number or null",
    "curves": [_CURVE_SCHEMA],
    "info": dict,
    "arrays_sha256": str,
}


def _type_name(value) -> str:
    return {dict: "an object", list: "a list", str: "a string", bool: "a boolean", type(None): "null"}.get(
        type(value), "a number" if isinstance(value, (int, float)) else type(value).__name__)


def _check(value, schema, where: str, jpath: str) -> None:
    def fail(expected: str):
        raise ModelFileError(f"{jpath!r}: {where} must be {expected}, not {_type_name(value)}; the model file is "
                             "corrupted or was edited by hand, re-save or re-fit the model")

    if isinstance(schema, dict):
        if not isinstance(value, dict):
            fail("an object")
        for key, sub in schema.items():
            if key not in value:
                raise ModelFileError(f"{jpath!r}: {where}.{key} is missing; the model file is incomplete, "
                                     "re-save or re-fit the model")
            _check(value[key], sub, f"{where}.{key}", jpath)
    elif isinstance(schema, list):
        if not isinstance(value, list):
            fail("a list")
        for i, item in enumerate(value):
            _check(item, schema[0], f"{where}[{i}]", jpath)
    elif schema == _NUMBER:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            fail("a number")
    elif schema == "number or null":
        if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float))):
            fail("a number")
    elif schema is int:
        if isinstance(value, bool) or not isinstance(value, int):
            fail("an integer")
    elif schema is dict:
        if not isinstance(value, dict):
            fail("an object")
    elif not isinstance(value, schema):
        fail({str: "a string", bool: "true or false"}.get(schema, schema.__name__))


def validate_model_document(doc, jpath: str = _MODEL_JSON) -> None:
    """Check a parsed model.json against :data:`MODEL_SCHEMA`; raise ModelFileError naming the first problem.

    The format and its version are checked first, so a file from a newer charcurves is reported as
    such rather than as a schema mismatch.

    Examples
    --------
    >>> import json, os, tempfile
    >>> import charcurves as cc
    >>> from charcurves.fitting import validate_model_document
    >>> from charcurves.systems import get_system
    >>> path = os.path.join(tempfile.mkdtemp(), "model")
    >>> cc.fit(get_system("duffing").simulate(), method="parametric", basis="f1=z; f2=z, z**3").save(path)
    >>> with open(os.path.join(path, "model.json")) as fh:
    ...     doc = json.load(fh)
    >>> validate_model_document(doc)
    >>> try:
    ...     validate_model_document({**doc, "format_version": 99})
    ... except cc.ModelFileError as exc:
    ...     print(str(exc)[:60])
    'model.json': model format version 99 is not supported by th
    """
    if not isinstance(doc, dict) or doc.get("format") != "charcurves-model":
        raise ModelFileError(f"{jpath!r} is not a charcurves model file (no \"format\": \"charcurves-model\"); "
                             "give the directory a model was saved to")
    version = doc.get("format_version")
    if isinstance(version, bool) or not isinstance(version, int) or version < 1:
        raise ModelFileError(f"{jpath!r} has an invalid format_version {version!r}; the model file is corrupted, "
                             "re-save or re-fit the model")
    if version > FORMAT_VERSION:
        raise ModelFileError(f"{jpath!r}: model format version {version} is not supported by this charcurves, "
                             f"which reads version {FORMAT_VERSION} (the file comes from a newer release); "
                             "upgrade charcurves (pip install -U charcurves)")
    if version != FORMAT_VERSION:  # pragma: no cover - no older version exists yet
        raise ModelFileError(f"{jpath!r} has model format version {version}, which this charcurves no longer "
                             f"reads (it reads {FORMAT_VERSION}); re-fit the model")
    _check(doc, MODEL_SCHEMA, "model", jpath)
    for key, nonzero in (("gain", True), ("offset", False)):
        value = float(doc[key])
        if not np.isfinite(value) or (nonzero and value == 0.0):
            need = "a finite non-zero number" if nonzero else "a finite number"
            raise ModelFileError(f"{jpath!r}: model.{key} is {doc[key]!r}, but must be {need}; the model file is "
                                 "corrupted or was edited by hand, re-fit the model")
    _check_magnitude(doc["gain"], "model.gain", jpath, nonzero=True)
    _check_magnitude(doc["offset"], "model.offset", jpath)
    sha = doc["arrays_sha256"]
    if len(sha) != 64 or any(ch not in "0123456789abcdef" for ch in sha):
        raise ModelFileError(f"{jpath!r}: model.arrays_sha256 is not a sha256 hex digest; the model file is "
                             "corrupted, re-save or re-fit the model")
    names = []
    for i, curve in enumerate(doc["curves"]):
        where = f"model.curves[{i}]"
        if len(curve["domain"]) != 2:
            raise ModelFileError(f"{jpath!r}: {where}.domain must be [low, high]; the model file is corrupted, "
                                 "re-save or re-fit the model")
        kind_schema = _CURVE_KIND_SCHEMA.get(curve["kind"])
        if kind_schema is not None:  # other kinds (register_curve_kind) check themselves
            _check(curve, kind_schema, where, jpath)
        for k, value in enumerate(curve["domain"]):
            _check_magnitude(value, f"{where}.domain[{k}]", jpath)
        for key in _CURVE_NUMBERS:
            value = curve.get(key)
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                _check_magnitude(value, f"{where}.{key}", jpath, nonzero=key in _SCALES)
        texts = [curve["expression"]] if curve["kind"] == "symbolic" else list(curve.get("basis") or [])
        for text in texts:
            problem = expression_cost_problem(text)
            if problem:
                raise ModelFileError(f"{jpath!r}: {where} has the expression {text[:60]!r}, which {problem}; "
                                     "refusing to load it, re-fit the model")
        names.append(curve["name"])
    if len(set(names)) != len(names) or not names:
        raise ModelFileError(f"{jpath!r}: curve names {names} are empty or repeated; the model file is corrupted, "
                             "re-save or re-fit the model")


def _check_magnitude(value, where: str, jpath: str, nonzero: bool = False) -> None:
    """Refuse a number outside +-MAX_MODEL_MAGNITUDE (and, ``nonzero``, inside +-1/MAX_MODEL_MAGNITUDE)."""
    v = float(value)
    small = 1.0 / MAX_MODEL_MAGNITUDE
    if not np.isfinite(v) or abs(v) > MAX_MODEL_MAGNITUDE or (nonzero and abs(v) < small):
        need = (f"between {small:g} and {MAX_MODEL_MAGNITUDE:g} in magnitude" if nonzero
                else f"finite and at most {MAX_MODEL_MAGNITUDE:g} in magnitude")
        raise ModelFileError(f"{jpath!r}: {where} is {value!r}, out of range (it must be {need}); the model file is "
                             "corrupted or was edited by hand, re-fit the model")


def check_array_values(arrays: dict, apath: str) -> None:
    """Refuse weights that are not finite or exceed :data:`MAX_MODEL_MAGNITUDE` in magnitude (one line)."""
    for name in sorted(arrays):
        a = np.asarray(arrays[name], dtype=float)
        if a.size and (not np.all(np.isfinite(a)) or float(np.max(np.abs(a))) > MAX_MODEL_MAGNITUDE):
            raise ModelFileError(f"{apath!r}: the array {name!r} holds non-finite values or values beyond "
                                 f"{MAX_MODEL_MAGNITUDE:g} in magnitude; the model file is corrupted, re-fit the model")


def model_digest(doc: dict, keys) -> str:
    """sha256 (hex) of the values of ``keys`` in ``doc``, as canonical JSON (sorted keys, no spaces):
    what model.json's ``model_sha256`` holds for the keys listed in ``model_sha256_keys``.

    Examples
    --------
    >>> from charcurves.fitting import model_digest
    >>> a = model_digest({"gain": 1.0, "method": "poly-cc"}, ["gain", "method"])
    >>> a == model_digest({"method": "poly-cc", "gain": 1.0, "comment": "not covered"}, ["gain", "method"])
    True
    >>> a == model_digest({"gain": 2.0, "method": "poly-cc"}, ["gain", "method"])
    False
    """
    import hashlib
    import json

    covered = {k: doc[k] for k in keys}
    text = json.dumps(covered, sort_keys=True, separators=(",", ":"), ensure_ascii=True, allow_nan=False)
    return hashlib.sha256(text.encode("ascii")).hexdigest()


def check_model_digest(doc: dict, jpath: str = _MODEL_JSON) -> None:
    """Refuse a model.json whose values no longer match its ``model_sha256`` (edited by hand after
    saving: a changed gain, a scale, a curve's settings). A file without ``model_sha256`` (written
    before charcurves covered model.json by a checksum) is not checked. Keys a later release adds
    outside ``model_sha256_keys`` are not covered, so they may be added.

    Examples
    --------
    >>> import json, os, tempfile
    >>> import charcurves as cc
    >>> from charcurves.fitting import check_model_digest
    >>> from charcurves.systems import get_system
    >>> path = os.path.join(tempfile.mkdtemp(), "model")
    >>> cc.fit(get_system("duffing").simulate(), method="parametric", basis="f1=z; f2=z, z**3").save(path)
    >>> with open(os.path.join(path, "model.json")) as fh:
    ...     doc = json.load(fh)
    >>> check_model_digest(doc)
    >>> try:
    ...     check_model_digest({**doc, "gain": 2.0})
    ... except cc.ModelFileError as exc:
    ...     print(str(exc)[:58])
    'model.json' was modified after it was saved (its values n
    """
    if "model_sha256" not in doc:
        return
    digest, keys = doc["model_sha256"], doc.get("model_sha256_keys")
    if (not isinstance(digest, str) or not isinstance(keys, list) or not all(isinstance(k, str) for k in keys)
            or "model_sha256" in keys):
        raise ModelFileError(f"{jpath!r}: model_sha256 or model_sha256_keys is damaged; the model file is corrupted, "
                             "re-save or re-fit the model")
    missing = [k for k in keys if k not in doc]
    try:
        same = not missing and model_digest(doc, keys) == digest
    except (TypeError, ValueError):
        same = False
    if not same:
        detail = (f"{missing[0]!r}, covered by model_sha256, was removed" if missing
                  else "its values no longer match model_sha256, e.g. an edited gain")
        raise ModelFileError(f"{jpath!r} was modified after it was saved ({detail}); refusing to load it, re-fit "
                             "the model or restore the file as saved")
