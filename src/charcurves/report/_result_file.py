"""The fields of a fit's ``result.json`` that the report reads, checked for their types (issue 50:
``"warnings": 5`` ended in ``TypeError: 'int' object is not iterable``)."""

from __future__ import annotations

import numbers
from typing import Any

from .._errors import ModelFileError

__all__ = ["check_result_fields"]


def _is_str_list(v: Any) -> bool:
    return isinstance(v, list) and all(isinstance(w, str) for w in v)


def _is_number_map(v: Any) -> bool:
    return isinstance(v, dict) and all(w is None or (isinstance(w, numbers.Real) and not isinstance(w, bool))
                                       for w in v.values())


#: field -> (test, what it must be); a field that is absent or null is left to the report's defaults
_FIELDS = {
    "method": (lambda v: isinstance(v, str), "a string"),
    "source": (lambda v: isinstance(v, str), "a string"),
    "interrupted": (lambda v: isinstance(v, bool), "true or false"),
    "warnings": (_is_str_list, "a list of strings"),
    "curve_rmse": (_is_number_map, "an object of numbers"),
    "bands": (lambda v: isinstance(v, dict), "an object"),
}


def check_result_fields(result: Any, path: str) -> None:
    """Refuse a ``result.json`` that is not an object, or whose fields read by the report have
    another type, naming the field; one line."""
    if not isinstance(result, dict):
        raise ModelFileError(f"{path!r} holds a JSON {type(result).__name__}, not the object 'charcurves fit' writes; "
                             "delete it to report the model alone, or re-fit")
    for key, (ok, what) in _FIELDS.items():
        value = result.get(key)
        if value is not None and not ok(value):
            raise ModelFileError(f"{path!r}: field {key!r} must be {what}, got {type(value).__name__} "
                                 f"{str(value)[:40]!r}; restore it, delete result.json to report the model alone, "
                                 "or re-fit")
