"""The fitted model every method returns: curves, gain, constant, loss; save/load; simulation RHS."""

from __future__ import annotations

import datetime as _dt
import json
import os
from typing import Any

import numpy as np

from .._errors import ConfigError, ModelFileError
from ..curves import FittedCurve, curve_from_spec
from ..io import atomic_write_bytes
from ..templates import EquationTemplate, display, get_template
from ._display import curve_scale, display_expression, display_number
from ._model_schema import (FORMAT_VERSION, MODEL_SCHEMA, check_array_values, check_model_digest, model_digest,
                            validate_model_document)
from ._plots import plot_model
from ._posterior_store import posterior_from_spec, posterior_to_spec
from ._views import model_html

__all__ = ["FittedModel", "FORMAT_VERSION", "MODEL_SCHEMA", "load_model", "validate_model_document"]

_MODEL_JSON = "model.json"
#: The methods that have a ``+post-sr`` variant in charcurves.fitting's method table (a test checks
#: that the two agree): an error about a curve without a closed form names that variant as the fix.
DISTILLABLE_METHODS = ("nn-cc", "nn-cc+sym", "sindy-cc+sym")
_ARRAYS = "arrays.safetensors"


class FittedModel:
    """A template with its identified curves.

    Attributes
    ----------
    template : EquationTemplate
    method : str
    curves : dict[str, FittedCurve]
    gain : float            input gain g (1 unless learned)
    offset : float          the equation's free constant b (0 when a curve absorbs it)
    loss : float            final data loss (mean squared force residual on the fitted samples)
    info : dict             training details (preset, seed, iterations, times, masks...)

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.systems import get_system
    >>> model = cc.fit(get_system("duffing").simulate(), method="parametric", basis="f1=z; f2=z, z**3")
    >>> isinstance(model, cc.FittedModel), list(model.curves), model.gain
    (True, ['f1', 'f2'], 1.0)
    >>> model.to_sympy(digits=3)
    Eq(x(t)**3 - x(t) + 0.3*Derivative(x(t), t) + Derivative(x(t), (t, 2)), F(t))
    """

    def __init__(self, template: EquationTemplate, method: str, curves: dict[str, FittedCurve],
                 gain: float, offset: float, loss: float, info: dict | None = None):
        self.template = template
        self.method = method
        self.curves = dict(curves)
        self.gain = float(gain)
        self.offset = float(offset)
        self.loss = float(loss)
        self.info = dict(info or {})

    #: the posterior of the fit that made the model, where it computed one (charcurves.model._posterior)
    posterior: Any = None

    def curve_band(self, name: str, z, level: float = 0.95):
        """``(value, lo, hi)`` of curve ``name`` at ``z``: the pointwise ``level`` posterior band
        (:func:`charcurves.fitting.curve_band`)."""
        from ._posterior import curve_band

        return curve_band(self, name, z, level)

    # ------------------------------------------------------------------ evaluation
    def curve(self, name: str) -> FittedCurve:
        try:
            return self.curves[name]
        except KeyError:
            raise ConfigError(f"no curve {name!r}; this model has {', '.join(self.curves)}") from None

    @property
    def scalars(self) -> dict[str, float]:
        """Learned scalars ``a1, a2, ...`` and the free constants ``b2, b3, ...`` of further equations."""
        return {k: float(v) for k, v in dict(self.info.get("scalars", {})).items()}

    def acceleration(self, t, x, v, F) -> np.ndarray:
        """x'' implied by the model: g F - f1(x') - f2(x) - b."""
        if self.template.is_general:
            raise ConfigError(f"acceleration() is the separable family's; for the {self.template.family} template "
                              "use force_residual(record) or charcurves.simulate.simulate_model")
        return self.gain * np.asarray(F) - self.curves["f1"](v) - self.curves["f2"](x) - self.offset

    def force_residual(self, traj) -> np.ndarray:
        """The equation's residual (separable: x'' + f1 + f2 + b - g F) on a record with derivatives:
        shape (N,) for one equation, (N, E) for several."""
        if not self.template.is_general:
            return np.asarray(traj.a) - self.acceleration(traj.t, traj.x, traj.v, traj.F)
        D = self.template.design(traj)
        n, E = D["n"], D["E"]
        r = D["y"] - self.gain * D["F"]
        for name, c in self.curves.items():
            r = r + D["mult"][name] * np.tile(np.asarray(c(D["args"][name]), dtype=float), E)
        sc = self.scalars
        for s, sig in D["scalars"].items():
            r = r + sig * sc.get(s, 0.0)
        r = r.reshape(E, n)
        r[0] += self.offset
        for e in range(1, E):
            r[e] += sc.get(f"b{e + 1}", 0.0)
        return r[0] if E == 1 else r.T

    def rhs(self, forcing):
        """Right-hand side ``f(t, [x, v])`` for scipy's solve_ivp with forcing ``F(t)``."""
        if self.template.is_general:
            raise ConfigError(f"rhs() is the separable family's; simulate a {self.template.family} model with "
                              "charcurves.simulate.simulate_model")
        f1, f2, g, b = self.curves["f1"], self.curves["f2"], self.gain, self.offset

        def fun(t, y):
            x, v = y[0], y[1]
            a = g * forcing(t) - f1(np.asarray(v)) - f2(np.asarray(x)) - b
            return np.array([v, float(np.asarray(a).reshape(-1)[0])])

        return fun

    @property
    def is_symbolic(self) -> bool:
        return all(c.expression() is not None for c in self.curves.values())

    def _expressions(self, digits: int | None) -> dict:
        """Each curve's closed form in ``z`` (rounded for display when ``digits`` is given); a clear
        error naming the fix when a curve has none."""
        missing = [n for n, c in self.curves.items() if c.expression() is None]
        if missing:
            kinds = ", ".join(f"{n} ({self.curves[n].kind})" for n in missing)
            distilled = f"{self.method}+post-sr"
            how = f"--method {distilled}" if self.method in DISTILLABLE_METHODS else "a +post-sr method"
            raise ConfigError(
                f"curves {kinds} have no closed form; distil them first: fit with post_sr=True or {how}, or "
                "run charcurves.fitting.distill_model(model), or fit a basis method (parametric, poly-cc, sindy-cc)")
        if digits is None:
            return {n: c.expression() for n, c in self.curves.items()}
        return {n: display_expression(c.expression(), c.domain, digits=digits) for n, c in self.curves.items()}

    def to_sympy(self, *, curves: bool = False, digits: int | None = None, uncertainty: bool = False):
        """The identified equation as a sympy ``Eq`` (a list of them for several equations), or with
        ``curves=True`` a dict of curve name -> closed form in ``z``.

        Every curve must have a closed form (a basis method, SR-CC, or a +post-sr method); a neural
        curve raises :class:`~charcurves.ConfigError` naming the fix. ``digits`` rounds the numbers
        to that many significant digits and drops the terms that are zero at that precision over each
        curve's training range (for display; the model keeps every digit). ``uncertainty=True`` writes
        each constant that has a posterior as a symbol printed ``(mean ± sd)``, 1 sd (every term kept).

        Examples
        --------
        >>> import charcurves as cc
        >>> from charcurves.systems import get_system
        >>> model = cc.fit(get_system("duffing").simulate(), method="parametric", basis="f1=z; f2=z, z**3")
        >>> model.to_sympy(curves=True, digits=4)["f1"]
        0.3*z
        """
        import sympy as sp

        exprs = self._expressions(digits)
        if uncertainty:  # ._posterior_constants: the constants with their posterior sd
            from ._posterior_constants import uncertain_parts

            exprs, num = uncertain_parts(self, digits)
        if curves:
            return exprs

        if uncertainty:
            pass
        elif digits is None:
            def num(value: float, constant: bool = False):
                return sp.Float(value)
        else:  # rounded; a constant below the precision of the curves' values is dropped
            scale = curve_scale(self)

            def num(value: float, constant: bool = False):  # scalars multiply signals: never dropped
                return display_number(value, scale if constant else 0.0, digits)

        if self.template.is_general:  # one Eq, or a list of Eq for several equations
            return self._general_sympy(exprs, num)
        t = sp.Symbol("t")
        x = sp.Function("x")(t)
        F = sp.Function("F")(t)
        z = sp.Symbol("z")
        lhs = sp.diff(x, t, 2)
        lhs += exprs["f1"].subs(z, sp.diff(x, t))
        lhs += exprs["f2"].subs(z, x)
        if self.offset:
            lhs += num(self.offset, True)
        return sp.Eq(lhs, num(self.gain) * F if self.gain != 1 else F)

    def _general_sympy(self, exprs: dict, num):
        import sympy as sp

        template = self.template
        z = sp.Symbol("z")
        sc = self.scalars
        out = []
        for e, eq in enumerate(template.equations):
            lhs = eq.known
            for name, m in eq.curves.items():
                lhs = lhs + m * exprs[name].subs(z, template.argument_exprs[name])
            for s, sig in eq.scalars.items():
                lhs = lhs + num(sc.get(s, 0.0)) * sig
            off = self.offset if e == 0 else sc.get(f"b{e + 1}", 0.0)
            if off:
                lhs = lhs + num(off, True)
            rhs = eq.input if self.gain == 1 else num(self.gain) * eq.input
            eq_ = sp.Eq(lhs, rhs)
            # data symbols as written (x', x1'') rather than the parser's internal names
            out.append(eq_.subs({s: sp.Symbol(display(s.name), real=True) for s in eq_.free_symbols}))
        return out[0] if len(out) == 1 else out

    def to_latex(self, digits: int | None = 4, *, uncertainty: bool = False) -> str:
        """The equation with the closed forms written in, as LaTeX (several equations joined by a LaTeX line break).

        Numbers are printed to ``digits`` significant digits and terms that are zero at that
        precision are dropped (None: every stored digit). Needs closed forms, as :meth:`to_sympy`;
        ``uncertainty=True`` writes the constants as ``(mean \\pm sd)`` (1 sd), e.g. ``(0.299 \\pm 0.004) z|z|``.
        """
        import sympy as sp

        eq = self.to_sympy(digits=digits, uncertainty=uncertainty)
        return " \\\\ ".join(sp.latex(e) for e in eq) if isinstance(eq, list) else sp.latex(eq)

    # ------------------------------------------------------------------ notebook views
    def plot(self, ax=None, truth=None, **kwargs):
        """Draw the curves (training range shaded, truth dashed, bands filled) and return the axes.

        ``ax``: None (a new figure, one panel per curve), one Axes per curve, or a single Axes for
        all of them; ``truth``: name -> callable or a benchmark system's name (``"duffing"``). Other
        keywords (``bands``, ``label``, ``margin``) as :func:`charcurves.fitting.plot_model`.
        """
        return plot_model(self, ax, truth, **kwargs)

    def _repr_html_(self) -> str:
        """A notebook's view: the curves (closed forms to 4 digits), fit statistics, a small figure."""
        return model_html(self)

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
            "gauge": (f"{(self.template.anchors or ('f2',))[0]}(0) = 0" if not self.template.is_general
                      else ", ".join(self.info.get("gauge_conditions", [])) or "none (no constant to trade)"),
            "loss": self.loss,
            "curves": curves,
            **({"scalars": dict(self.info.get("scalars", {}))} if self.template.is_general else {}),
            # symmetry="auto": the parities imposed and the tests behind them (charcurves.selection)
            **({"symmetry": _jsonable(self.info["symmetry_auto"])} if "symmetry_auto" in self.info else {}),
            # uncertainty bands from an ensemble, when computed (charcurves.selection.attach_bands)
            **({"bands": _jsonable(bands)} if (bands := getattr(self, "bands", None)) else {}),
            **({"uncertainty": _jsonable(u)} if (u := _uncertainty(self)) else {}),
            "info": _split_timings(_jsonable(self.info))[0],
        }

    def timings(self) -> dict[str, float]:
        """Wall-clock times recorded in ``info`` (keys ending in "seconds"), by dotted path.

        They are left out of :meth:`result_dict`, which therefore depends only on the inputs and
        the seed (bit-identical on reruns on the same machine).
        """
        return _split_timings(_jsonable(self.info))[1]

    # ------------------------------------------------------------------ persistence
    def save(self, directory: str | os.PathLike) -> None:
        """Write ``model.json`` (readable spec) and ``arrays.safetensors`` atomically.

        A new directory appears complete or not at all; see docs/model-format.md.
        """
        from safetensors.numpy import save as st_save

        d = os.fspath(directory)
        arrays: dict[str, np.ndarray] = {}
        curve_specs = []
        for c in self.curves.values():
            spec, arr = c.to_spec()
            curve_specs.append(spec)
            arrays.update(arr)
        post_spec, post_arrays = posterior_to_spec(self)  # the posterior, where the fit has one (._posterior_store)
        arrays.update(post_arrays)
        doc = {
            "format": "charcurves-model",
            "format_version": FORMAT_VERSION,
            "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
            "template": self.template.to_dict(),
            "method": self.method,
            "gain": self.gain,
            "offset": self.offset,
            "loss": self.loss if np.isfinite(self.loss) else None,  # standard JSON: no NaN/Infinity
            "curves": curve_specs,
            "info": _jsonable(self.info),
            **({"posterior": post_spec} if post_spec else {}),
        }
        blob = st_save({k: np.ascontiguousarray(v, dtype=np.float64) for k, v in arrays.items()})
        import hashlib

        doc["arrays_sha256"] = hashlib.sha256(blob).hexdigest()
        # model.json is covered too: the digest of every key written, over the values as they read back
        doc = json.loads(json.dumps(doc))
        doc["model_sha256_keys"] = sorted(doc)
        doc["model_sha256"] = model_digest(doc, doc["model_sha256_keys"])
        text = json.dumps(doc, indent=2).encode()
        if os.path.islink(d):  # a link to a model folder is written through; the link stays
            d = os.path.realpath(d)
        if not os.path.exists(d):
            # a new model appears all at once: written in a temporary sibling, then renamed
            import shutil

            from ..io import make_temp_dir

            parent = os.path.dirname(os.path.abspath(d))
            os.makedirs(parent, exist_ok=True)
            tmp = make_temp_dir(parent, ".tmp-model-")
            try:
                atomic_write_bytes(os.path.join(tmp, _ARRAYS), blob)
                atomic_write_bytes(os.path.join(tmp, _MODEL_JSON), text)
                os.rename(tmp, d)
                return
            except OSError:
                if os.path.exists(d) and os.path.isdir(d):
                    pass  # created meanwhile by someone else: overwrite it file by file below
                else:
                    raise
            finally:
                shutil.rmtree(tmp, ignore_errors=True)
        if not os.path.isdir(d):
            raise ModelFileError(f"{d!r} is a file, not a model directory; give a directory path to save to")
        # overwriting: each file is replaced atomically and model.json, written last, is the commit
        # point; an interruption in between leaves arrays that load() rejects by their checksum
        atomic_write_bytes(os.path.join(d, _ARRAYS), blob)
        atomic_write_bytes(os.path.join(d, _MODEL_JSON), text)

    @classmethod
    def load(cls, directory: str | os.PathLike) -> FittedModel:
        return load_model(directory)

    def __repr__(self) -> str:
        return (f"FittedModel(method={self.method!r}, equation={self.template.equation!r}, "
                f"gain={self.gain:.6g}, offset={self.offset:.3g}, loss={self.loss:.4g})")


def load_model(directory: str | os.PathLike) -> FittedModel:
    """Read a model written by :meth:`FittedModel.save`; never executes code from the file.

    Examples
    --------
    >>> import os, tempfile
    >>> import charcurves as cc
    >>> from charcurves.systems import get_system
    >>> path = os.path.join(tempfile.mkdtemp(), "duffing-model")
    >>> cc.fit(get_system("duffing").simulate(), method="poly-cc").save(path)
    >>> sorted(os.listdir(path))
    ['arrays.safetensors', 'model.json']
    >>> model = cc.load_model(path)
    >>> model.method, round(float(model.curves["f2"](2.0)), 6)
    ('poly-cc', 6.0)
    """
    import hashlib

    from safetensors.numpy import load as st_load

    d = os.fspath(directory)
    jpath = os.path.join(d, _MODEL_JSON)
    apath = os.path.join(d, _ARRAYS)
    if not os.path.isdir(d):
        what = "is missing (does not exist)" if not os.path.exists(d) else "is not a directory"
        raise ModelFileError(f"model directory {d!r} {what}; give the directory a model was saved to")
    try:
        with open(jpath, "rb") as fh:
            raw = fh.read()
        with open(apath, "rb") as fh:
            blob = fh.read()
    except FileNotFoundError as exc:
        raise ModelFileError(f"{exc.filename!r} is missing; give the directory a model was saved to") from None
    except OSError as exc:
        raise ModelFileError(f"{exc.filename!r} cannot be read ({exc.strerror}); check its permissions") from None
    try:
        doc = json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError):
        raise ModelFileError(f"{jpath!r} is not valid JSON (truncated or damaged); the model file is corrupted, "
                             "re-save or re-fit the model") from None
    validate_model_document(doc, jpath)
    if hashlib.sha256(blob).hexdigest() != doc["arrays_sha256"]:
        raise ModelFileError(f"{apath!r} does not match the checksum in model.json; the model file is corrupted, "
                             "re-save or re-fit the model")
    try:
        try:
            arrays = st_load(blob)
        except Exception as exc:  # safetensors raises its own error type for a damaged header
            raise ModelFileError(f"{apath!r} is not a readable safetensors file ({type(exc).__name__}); "
                                 "the model file is corrupted, re-save or re-fit the model") from None
        check_array_values(arrays, apath)
        tdoc = dict(doc["template"])
        family = tdoc.pop("family")
        if family == "state-space":  # a template with hidden states (charcurves.fitting.fit_state_space)
            from ..templates import StateSpace

            template: EquationTemplate = StateSpace.from_dict(tdoc).structure()
        else:
            template = get_template(family, **tdoc)
        curves = {}
        for spec in doc["curves"]:
            c = curve_from_spec(spec, arrays)
            curves[c.name] = c
        loss = doc["loss"] if doc["loss"] is not None else float("nan")
        model = FittedModel(template, doc["method"], curves, doc["gain"], doc["offset"], loss, doc.get("info", {}))
        if "posterior" in doc:  # written since the posterior is saved; older files load without one
            model.posterior = posterior_from_spec(doc["posterior"], arrays, jpath)
        # last, so that a damaged curve is named by its own check first; an edit that leaves a
        # readable model (the gain changed) is caught here
        check_model_digest(doc, jpath)
        return model
    except ModelFileError as exc:
        message = str(exc)
        if not any(fix in message for fix in ("re-save", "re-fit", "upgrade")):  # the curve readers' own errors
            raise ModelFileError(f"{jpath!r}: {message}; re-fit the model or upgrade charcurves") from None
        raise
    except (KeyError, TypeError, ValueError) as exc:
        detail = str(exc).splitlines()[0] if str(exc) else ""
        raise ModelFileError(f"{jpath!r} is incomplete or corrupted ({type(exc).__name__}: {detail}); "
                             "re-save or re-fit the model") from None


def _split_timings(obj, path: str = ""):
    """``(obj without keys ending in "seconds", {dotted path: value} of those keys)``."""
    timings: dict[str, float] = {}
    if isinstance(obj, dict):
        clean = {}
        for key, value in obj.items():
            sub = f"{path}.{key}" if path else str(key)
            if str(key).endswith("seconds") and isinstance(value, (int, float)) and not isinstance(value, bool):
                timings[sub] = value
                continue
            clean[key], inner = _split_timings(value, sub)
            timings.update(inner)
        return clean, timings
    if isinstance(obj, list):
        out = []
        for i, value in enumerate(obj):
            item, inner = _split_timings(value, f"{path}[{i}]")
            out.append(item)
            timings.update(inner)
        return out, timings
    return obj, timings


def _uncertainty(model):
    from ._posterior import uncertainty_summary

    return uncertainty_summary(model)


def _jsonable(obj):
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, np.floating):
        obj = float(obj)
    if isinstance(obj, float) and not np.isfinite(obj):
        return str(obj)
    return obj
