"""The fitted model every method returns: curves, gain, constant, loss; save/load; simulation RHS."""

from __future__ import annotations

import datetime as _dt
import json
import os
from typing import Any

import numpy as np

from .._errors import ConfigError, ModelFileError
from ..curves._fitted import FittedCurve, curve_from_spec
from ..io._csv import atomic_write_bytes
from ..templates._separable import SeparableTemplate, get_template

__all__ = ["FittedModel", "FORMAT_VERSION", "load_model"]

FORMAT_VERSION = 1
_MODEL_JSON = "model.json"
_ARRAYS = "arrays.safetensors"


class FittedModel:
    """A template with its identified curves.

    Attributes
    ----------
    template : SeparableTemplate
    method : str
    curves : dict[str, FittedCurve]
    gain : float            input gain g (1 unless learned)
    offset : float          the equation's free constant b (0 when a curve absorbs it)
    loss : float            final data loss (mean squared force residual on the fitted samples)
    info : dict             training details (preset, seed, iterations, times, masks...)
    """

    def __init__(self, template: SeparableTemplate, method: str, curves: dict[str, FittedCurve],
                 gain: float, offset: float, loss: float, info: dict | None = None):
        self.template = template
        self.method = method
        self.curves = dict(curves)
        self.gain = float(gain)
        self.offset = float(offset)
        self.loss = float(loss)
        self.info = dict(info or {})

    # ------------------------------------------------------------------ evaluation
    def curve(self, name: str) -> FittedCurve:
        try:
            return self.curves[name]
        except KeyError:
            raise ConfigError(f"no curve {name!r}; this model has {', '.join(self.curves)}") from None

    def acceleration(self, t, x, v, F) -> np.ndarray:
        """x'' implied by the model: g F - f1(x') - f2(x) - b."""
        return self.gain * np.asarray(F) - self.curves["f1"](v) - self.curves["f2"](x) - self.offset

    def force_residual(self, traj) -> np.ndarray:
        """x'' + f1 + f2 + b - g F on a trajectory with derivatives."""
        return np.asarray(traj.a) - self.acceleration(traj.t, traj.x, traj.v, traj.F)

    def rhs(self, forcing):
        """Right-hand side ``f(t, [x, v])`` for scipy's solve_ivp with forcing ``F(t)``."""
        f1, f2, g, b = self.curves["f1"], self.curves["f2"], self.gain, self.offset

        def fun(t, y):
            x, v = y[0], y[1]
            a = g * forcing(t) - f1(np.asarray(v)) - f2(np.asarray(x)) - b
            return np.array([v, float(np.asarray(a).reshape(-1)[0])])

        return fun

    @property
    def is_symbolic(self) -> bool:
        return all(c.expression() is not None for c in self.curves.values())

    def to_sympy(self):
        """The identified equation as a sympy ``Eq`` (curves must be symbolic)."""
        import sympy as sp

        if not self.is_symbolic:
            missing = [n for n, c in self.curves.items() if c.expression() is None]
            raise ConfigError(
                f"curves {missing} are not symbolic; distil them first (a method with +post-sr) "
                "or use a basis method"
            )
        t = sp.Symbol("t")
        x = sp.Function("x")(t)
        F = sp.Function("F")(t)
        z = sp.Symbol("z")
        lhs = sp.diff(x, t, 2)
        lhs += self.curves["f1"].expression().subs(z, sp.diff(x, t))
        lhs += self.curves["f2"].expression().subs(z, x)
        if self.offset:
            lhs += sp.Float(self.offset)
        return sp.Eq(lhs, sp.Float(self.gain) * F if self.gain != 1 else F)

    def to_latex(self) -> str:
        import sympy as sp

        return sp.latex(self.to_sympy())

    # ------------------------------------------------------------------ the CLI's result.json
    def result_dict(self, n_grid: int = 1000) -> dict[str, Any]:
        curves = {}
        for name, c in self.curves.items():
            grid = c.grid(n_grid)
            expr = c.expression()
            entry = {
                "argument": c.argument,
                "domain": list(c.domain),
                "grid": grid.tolist(),
                "values": c(grid).tolist(),
                "expression": None if expr is None else str(expr),
                "kind": c.kind,
            }
            comps = c.components()
            if comps:
                entry["components"] = comps
            curves[name] = entry
        return {
            "family": self.template.family,
            "equation": self.template.equation,
            "method": self.method,
            "gain": self.gain,
            "gain_free": self.template.free_gain,
            "offset": self.offset,
            "gauge": f"{self.template.gauge}(0) = 0",
            "loss": self.loss,
            "curves": curves,
            "info": _jsonable(self.info),
        }

    # ------------------------------------------------------------------ persistence
    def save(self, directory: str | os.PathLike) -> None:
        """Write ``model.json`` (readable spec) and ``arrays.safetensors`` atomically."""
        from safetensors.numpy import save as st_save

        d = os.fspath(directory)
        os.makedirs(d, exist_ok=True)
        arrays: dict[str, np.ndarray] = {}
        curve_specs = []
        for c in self.curves.values():
            spec, arr = c.to_spec()
            curve_specs.append(spec)
            arrays.update(arr)
        doc = {
            "format": "charcurves-model",
            "format_version": FORMAT_VERSION,
            "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
            "template": self.template.to_dict(),
            "method": self.method,
            "gain": self.gain,
            "offset": self.offset,
            "loss": self.loss,
            "curves": curve_specs,
            "info": _jsonable(self.info),
        }
        blob = st_save({k: np.ascontiguousarray(v, dtype=np.float64) for k, v in arrays.items()})
        import hashlib

        doc["arrays_sha256"] = hashlib.sha256(blob).hexdigest()
        atomic_write_bytes(os.path.join(d, _ARRAYS), blob)
        atomic_write_bytes(os.path.join(d, _MODEL_JSON), json.dumps(doc, indent=2).encode())

    @classmethod
    def load(cls, directory: str | os.PathLike) -> FittedModel:
        return load_model(directory)

    def __repr__(self) -> str:
        return (f"FittedModel(method={self.method!r}, equation={self.template.equation!r}, "
                f"gain={self.gain:.6g}, offset={self.offset:.3g}, loss={self.loss:.4g})")


def load_model(directory: str | os.PathLike) -> FittedModel:
    """Read a model written by :meth:`FittedModel.save`; never executes code from the file."""
    import hashlib

    from safetensors.numpy import load as st_load

    d = os.fspath(directory)
    jpath = os.path.join(d, _MODEL_JSON)
    apath = os.path.join(d, _ARRAYS)
    try:
        with open(jpath, "rb") as fh:
            doc = json.loads(fh.read().decode("utf-8"))
        with open(apath, "rb") as fh:
            blob = fh.read()
    except FileNotFoundError as exc:
        raise ModelFileError(f"{exc.filename!r} is missing; give the directory a model was saved to") from None
    except (UnicodeDecodeError, json.JSONDecodeError):
        raise ModelFileError(f"{jpath!r} is not valid JSON; the model file is corrupted") from None
    if not isinstance(doc, dict) or doc.get("format") != "charcurves-model":
        raise ModelFileError(f"{jpath!r} is not a charcurves model file")
    version = doc.get("format_version")
    if version != FORMAT_VERSION:
        raise ModelFileError(
            f"model format version {version!r} is not supported (this charcurves reads version "
            f"{FORMAT_VERSION}); re-fit the model or upgrade charcurves"
        )
    if hashlib.sha256(blob).hexdigest() != doc.get("arrays_sha256"):
        raise ModelFileError(f"{apath!r} does not match its checksum; the model file is corrupted")
    try:
        arrays = st_load(blob)
        tdoc = dict(doc["template"])
        family = tdoc.pop("family")
        template = get_template(family, **tdoc)
        curves = {}
        for spec in doc["curves"]:
            c = curve_from_spec(spec, arrays)
            curves[c.name] = c
        return FittedModel(template, doc["method"], curves, doc["gain"], doc["offset"], doc["loss"],
                           doc.get("info", {}))
    except ModelFileError:
        raise
    except (KeyError, TypeError, ValueError) as exc:
        raise ModelFileError(f"{jpath!r} is incomplete or corrupted ({type(exc).__name__}: {exc})") from None


def _jsonable(obj):
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, (np.floating,)):
        return float(obj)
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, float) and not np.isfinite(obj):
        return str(obj)
    return obj
