"""The estimator users meet: a template with a representation per curve, a differentiator, an
objective and optional post-SR, composed as objects (or named by one of the paper's methods)."""

from __future__ import annotations

import copy
import inspect
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from .._bounds import check_number, check_seeds
from .._errors import ConfigError, NotFittedError
from ._methods import METHODS, check_method_options, method_curve, parse_basis_option, parse_symmetry
from ._model import FittedModel
from ._presets import get_preset
from ._priors import name_prior_in_warnings, priors_record

__all__ = ["CharacteristicCurves", "fit", "MAX_SEED"]

#: Largest seed: every generator downstream (numpy, torch, Operon) accepts it.
MAX_SEED = 2**32 - 1


class CharacteristicCurves:
    """Identify the characteristic curves of a template from measured records.

    Compose the parts as objects (the recommended way)::

        CharacteristicCurves(template=Separable(f1=Polynomial(degree=3, symmetry="odd"), f2=Neural(symmetry="odd")),
                             differentiator=SavitzkyGolay(window=31, order=3), objective="auto")

    or name one of the paper's twelve methods, which builds the same objects
    (``CharacteristicCurves(method="nn-cc+sym")``; see :data:`METHODS`).

    Parameters
    ----------
    template : Template, optional
        A template object (:class:`~charcurves.templates.Separable`, ``PositionDamping``,
        ``FirstOrder``, ``TwoDOF``, ``Equation``) with a representation per curve; curves left
        unset take the ``method`` preset's representation (``Neural()`` without a method). None:
        the template of ``family``/``equation`` with the method's curves.
    method : str, optional
        One of :data:`METHODS`. Default, without a template: NN-CC whose parity priors are those
        the record supports -- each curve's parity is tested first (poly-cc fits of a bootstrap
        ensemble, :func:`~charcurves.fitting.detect_symmetry`, about 0.1 s) and odd/even imposed
        only where one parity fits and the other does not (``info["priors"]`` says what and why);
        with ``symmetry`` given, "nn-cc+sym" with those parities.
    differentiator : str or Differentiator, optional
        How derivatives the template needs are obtained: "auto" (default: the record's own
        derivative columns when present, else estimated), "given", a name ("spectral", "savgol",
        "spline", "fd", ...) or an instance (``SavitzkyGolay(window=31, order=3)``).
    objective : {"auto", "equation-error", "output-error"} or EquationError/OutputError
        "auto" (default): equation error; then, on a record whose derivatives were estimated (a
        measured record: the state is noisy), output error -- the curves are refitted to the
        free-run simulation of the record (see :class:`~charcurves.fitting.OutputError`). The
        paper's preset keeps equation error.
    post_sr : bool, optional
        Distil the fitted curves into closed forms (symbolic regression); default: the method's.
    preset : {"default", "paper"} or TrainingPreset
        Training settings of gradient-trained curves.
    random_state : int
        Seed of every random choice (0 to 2**32 - 1).
    threads : int, optional
        Torch threads during the whole fit: warm start, training, output error (None leaves
        torch's setting).
    device : {"cpu", "cuda"}
    progress : callable, optional
        ``progress(phase, step, total, loss)`` during training.
    family, equation, symmetry, free_gain, gain, gauge, gain_on, jump, basis, options, sr_options,
    hidden, activation, exclude_sticking
        Shorthands of the method presets: the family or a user-written equation; parity priors
        ("f1=odd,f2=odd", a dict, or "auto": tested on unconstrained curves); the input gain; the
        curves anchored at 0; a learned jump at 0 ("auto", "none", or curve names); the
        Parametric basis ("f1=z; f2=z, z**3"); representation options ({"degree": 10}); symbolic
        regression settings; the network shape; whether sticking samples are left out.
    derivatives, refine, refine_options
        Older names of ``differentiator`` and the objective ("none" = equation error,
        "output-error", "auto"; ``refine_options`` = :class:`OutputError` settings).
    snr_db : float, optional
        Known signal-to-noise ratio of the forcing in dB, for the self-check (the loss of each
        equation against the noise floor, ``model.info["self_check"]``); default: the floor is
        estimated from the record.

    Examples
    --------
    >>> from charcurves.data import corrupt
    >>> from charcurves.fitting import CharacteristicCurves
    >>> from charcurves.systems import get_system
    >>> traj = corrupt(get_system("duffing").simulate(), 20, seed=0)
    >>> model = CharacteristicCurves(method="parametric", basis="f1=z; f2=z, z**3").fit(traj).model_
    >>> round(model.curves["f1"].components().get("linear_slope", 0.3), 1)
    0.3
    """

    def __init__(self, template=None, *, method: str | None = None, differentiator=None, objective="auto",
                 post_sr: bool | None = None, preset="default", random_state: int = 0, threads: int | None = None,
                 device: str = "cpu", progress: Callable | None = None, family: str = "separable",
                 equation: str | None = None, symmetry=None, free_gain: bool = False, gain: float = 1.0,
                 gauge=None, gain_on: str = "force", jump="auto", basis=None, options: dict | None = None,
                 sr_options: dict | None = None, hidden: Sequence[int] | None = None, activation: str | None = None,
                 exclude_sticking: bool = True, derivatives: str | None = None, refine: str | None = None,
                 refine_options: dict | None = None, snr_db: float | None = None):
        self.template = template
        self.method = method
        self.differentiator = differentiator
        self.objective = objective
        self.post_sr = post_sr
        self.preset = preset
        self.random_state = random_state
        self.threads = threads
        self.device = device
        self.progress = progress
        self.family = family
        self.equation = equation
        self.symmetry = symmetry
        self.free_gain = free_gain
        self.gain = gain
        self.gauge = gauge
        self.gain_on = gain_on
        self.jump = jump
        self.basis = basis
        self.options = options
        self.sr_options = sr_options
        self.hidden = hidden
        self.activation = activation
        self.exclude_sticking = exclude_sticking
        self.derivatives = derivatives
        self.refine = refine
        self.refine_options = refine_options
        self.snr_db = snr_db

    # ------------------------------------------------------------------ scikit-learn contract
    @classmethod
    def _param_names(cls) -> list[str]:
        return [p for p in inspect.signature(cls.__init__).parameters if p != "self"]

    def get_params(self, deep: bool = True) -> dict[str, Any]:
        out = {n: getattr(self, n) for n in self._param_names()}
        if deep and self.template is not None and hasattr(self.template, "get_params"):
            out.update({f"template__{k}": v for k, v in self.template.get_params(deep=True).items()})
        return out

    def set_params(self, **params) -> CharacteristicCurves:
        valid = self._param_names()
        nested = {}
        for k, v in params.items():
            head, sep, rest = k.partition("__")
            if head not in valid:
                raise ConfigError(f"unknown parameter {k!r}; valid: {', '.join(valid)}")
            if sep:
                nested[rest] = v
            else:
                setattr(self, k, v)
        if nested:
            if self.template is None or not hasattr(self.template, "set_params"):
                raise ConfigError("template__... parameters need a template object; give template=Separable(...) first")
            self.template.set_params(**nested)
        return self

    # ------------------------------------------------------------------ fitting
    def fit(self, traj) -> CharacteristicCurves:
        """Fit one record; the result is ``self.model_``."""
        self.model_ = self.fit_many([traj], seeds=[self.random_state])[0]
        return self

    def fit_many(self, trajectories: Sequence, seeds: Sequence[int] | None = None) -> list[FittedModel]:
        """Fit many records (noise realisations, SNR levels...); neural curves train in one batch.
        ``threads`` holds for the whole fit (warm start, training, output error), so the bytes of
        the result do not depend on the environment's OMP_NUM_THREADS."""
        from ._train import torch_threads

        self.check()  # the thread count among the rest, before it is used
        trajectories = list(trajectories)
        seeds = check_seeds(seeds, len(trajectories))  # one integer seed per record (issue 50)
        from ._symmetry import fit_many_auto

        with torch_threads(self.threads):
            if self.tests_priors():  # nothing asked: test the parities, impose what the record supports
                models = fit_many_auto(self, trajectories, seeds, default=True)
            elif isinstance(self.symmetry, str) and self.symmetry.strip().lower() == "auto":
                models = fit_many_auto(self, trajectories, seeds)  # detect parities, then fit with them
            else:
                from ._pipeline import run_pipeline

                models = run_pipeline(self, list(trajectories), seeds)
        for m in models:
            m.info["priors"] = priors_record(self, m)
            name_prior_in_warnings(m)
        return models

    # ------------------------------------------------------------------ resolution (used by the pipeline)
    def tests_priors(self) -> bool:
        """Whether no method, template or symmetry was asked: then :meth:`fit_many` tests each
        curve's parity (poly-cc, about 0.1 s) and imposes only what the record supports."""
        return self.method is None and self.template is None and self.symmetry in (None, "", {})

    def method_name(self) -> str:
        """The method preset: ``method``, else "nn-cc+sym" when a parity is asked (``symmetry``),
        else "nn-cc" (no prior; :meth:`fit_many` tests the parities first); "custom" for a template."""
        if self.method is not None:
            return self.method
        if self.template is not None:
            return "custom"
        sym = self.symmetry
        values = sym.values() if isinstance(sym, dict) else str(sym or "").replace("=", ",").split(",")
        return "nn-cc+sym" if any(str(v).strip() in ("odd", "even") for v in values) else "nn-cc"

    def check(self) -> None:
        """Numbers and names that must be usable before any work starts."""
        def is_int(value) -> bool:
            return isinstance(value, (int, np.integer)) and not isinstance(value, bool)

        if self.method is not None and self.method not in METHODS:
            raise ConfigError(f"unknown method {self.method!r}; choose one of {', '.join(METHODS)}")
        check_number("seed", self.random_state, label="the seed (random_state, --seed)")
        if self.threads is not None:
            check_number("threads", self.threads)
        if self.device != "cpu":  # a device that does not exist, for every method (poly-cc took "tpu" silently)
            from ._pipeline import check_device

            check_device(self.device)
        for name in ("free_gain", "exclude_sticking"):  # free_gain="False" would turn the gain on
            value = getattr(self, name)
            if not isinstance(value, (bool, np.bool_)):
                raise ConfigError(f"{name} must be True or False, got {value!r}; give e.g. {name}=True")
        if self.post_sr is not None and not isinstance(self.post_sr, (bool, np.bool_)):
            raise ConfigError(f"post_sr must be True, False or None, got {self.post_sr!r}")
        if self.hidden is not None and (isinstance(self.hidden, (str, bytes)) or not hasattr(self.hidden, "__iter__")
                                        or not all(is_int(h) and 1 <= h <= 4096 for h in self.hidden)
                                        or not 1 <= len(list(self.hidden)) <= 16):
            raise ConfigError(f"hidden must be a sequence of 1 to 16 layer widths, integers from 1 to 4096, got "
                              f"{self.hidden!r}; give e.g. hidden=(16, 16)")
        try:
            gain = float(self.gain)
        except (TypeError, ValueError):
            gain = float("nan")
        if not np.isfinite(gain) or gain == 0:
            raise ConfigError(f"the fixed gain must be a finite non-zero number, got {self.gain!r}; give e.g. gain=1.0")
        if self.snr_db is not None:
            try:
                snr = float(self.snr_db)
            except (TypeError, ValueError):
                snr = float("nan")
            if not np.isfinite(snr) or isinstance(self.snr_db, bool):
                raise ConfigError(f"snr_db must be a finite number of dB, got {self.snr_db!r}; give e.g. snr_db=20 "
                                  "(--snr 20), or leave it out to estimate the noise floor from the record")
            check_number("snr_db", snr)
        if self.derivatives is not None and self.differentiator is not None and self.derivatives != self.differentiator:
            raise ConfigError("give the differentiator once: derivatives= is the older name of differentiator=")
        if self.sr_options is not None:  # before any training: post-SR runs after it
            from ..symbolic import make_engine

            make_engine(self.sr_options)
        self._check_basis_cost()

    def _check_basis_cost(self) -> None:
        """Refuse basis functions whose exact evaluation by sympy could hang (e.g. ``9**9**9*z``)."""
        import re

        from ..curves import expression_cost_problem

        if isinstance(self.basis, str):
            texts = re.split(r"[;,=]", self.basis)
        elif isinstance(self.basis, dict):
            texts = [str(f) for v in self.basis.values() for f in (v if isinstance(v, (list, tuple)) else [v])]
        else:
            return
        for text in texts:
            problem = expression_cost_problem(text.strip())
            if problem:
                raise ConfigError(f"basis function {text.strip()[:60]!r} {problem}; write a plain closed form "
                                  "such as 'z**3' or 'tanh(50*z)'")

    def differentiator_value(self):
        value = self.differentiator if self.differentiator is not None else self.derivatives
        return "auto" if value is None else value

    def resolve(self):
        """``(template object with every curve set, its structure, symmetry per curve, method label)``."""
        from ..templates import as_template

        self.check()
        method = self.method_name()
        spec = METHODS.get(method)
        if self.template is None:
            free_gain = bool(self.free_gain) or bool(spec.get("free_gain", False))
            tmpl = as_template(self.family, equation=self.equation, free_gain=free_gain, gain=float(self.gain),
                               gauge=self.gauge, gain_on=self.gain_on)
        else:
            if not hasattr(self.template, "structure"):
                raise ConfigError(f"template must be a template object such as Separable(...) or Equation('...'), got "
                                  f"{type(self.template).__name__}; use family=/equation= for names")
            tmpl = copy.deepcopy(self.template)
            if spec is not None and spec.get("free_gain"):
                tmpl.free_gain = True
        structure = tmpl.structure()
        names = structure.curve_names
        if spec is not None and spec["representation"] in ("sr", "sr-cc") and structure.family != "separable":
            ok = [m for m, s in METHODS.items() if s["representation"] not in ("sr", "sr-cc")]
            raise ConfigError(f"method {method!r} supports the separable family only; for the {structure.family} "
                              f"template use one of {', '.join(ok)}")
        unset = [n for n in names if tmpl.curves.get(n) is None]
        sym = parse_symmetry(self.symmetry, names) if unset else {n: "none" for n in names}
        if spec is not None and unset:
            sym = self._method_symmetry(method, spec, sym, names)
            options = check_method_options(method, self.options)
            basis = parse_basis_option(self.basis, names, family=structure.family) if spec["representation"] == "basis" \
                else None
            jump = self._jumps(names)
            if jump not in ("auto", "none") and spec["representation"] != "neural":
                raise ConfigError(f"--jump applies to neural curves, not to method {method!r}"
                                  + ("; add tanh(k*z) to the basis for parametric" if method == "parametric" else ""))
            for n in unset:
                curve = method_curve(method, n, symmetry=sym[n], jump="auto" if jump == "auto" else
                                     (() if jump == "none" else jump), options=options, basis=basis,
                                     hidden=self.hidden, activation=self.activation,
                                     velocity=n in structure.velocity_curves)
                setattr(tmpl, n, curve)
        elif unset:
            from ..curves import Neural

            for n in unset:
                setattr(tmpl, n, Neural(symmetry=None if sym[n] == "none" else sym[n]))
        for n in names:
            curve = tmpl.curves[n]
            if not hasattr(curve, "check"):
                raise ConfigError(f"curve {n} must be a representation such as Neural() or Polynomial(degree=5), got "
                                  f"{type(curve).__name__}")
            curve.check()
        sym = {n: tmpl.curves[n].symmetry_name for n in names}
        return tmpl, structure, sym, method

    def _jumps(self, names):
        if self.jump in ("auto", None, "none", ""):
            return "none" if self.jump in ("none", "") else "auto"
        jumps = [self.jump] if isinstance(self.jump, str) else list(self.jump or ())
        jumps = [j.strip() for item in jumps for j in str(item).split(",") if j.strip()]
        for j in jumps:
            if j not in names:
                raise ConfigError(f"--jump names unknown curve {j!r}; the curves are {', '.join(names)}")
        return tuple(jumps)

    def _method_symmetry(self, method, spec, sym, names):
        if spec["symmetry"] and all(v == "none" for v in sym.values()):
            if self.symmetry not in (None, "", {}) and str(self.symmetry).strip().lower() != "auto":
                # an explicit "no prior" must not be turned into the +sym default silently
                plain = method.replace("+sym", "")
                raise ConfigError(
                    f"method {method!r} imposes a parity prior but the symmetry given sets none on every curve; "
                    f"use {plain!r} for no prior, or give the parities (e.g. f1=odd,f2=odd)")
            sym = {n: "odd" for n in names}  # the paper's +sym: odd curves
        if not spec["symmetry"] and not spec.get("allows_symmetry") and any(v != "none" for v in sym.values()):
            with_sym = [m for m in METHODS if m.startswith(method.split("+")[0]) and METHODS[m]["symmetry"]]
            raise ConfigError(f"method {method!r} has no symmetry prior; use {with_sym[0]} to impose {self.symmetry!r}"
                              if with_sym else f"method {method!r} does not take a symmetry prior")
        return sym

    def without_prior(self, name: str, sym: dict[str, str]) -> str:
        """How to ask for the same fit without the parity prior on ``name`` (for error messages)."""
        kept = {n: v for n, v in sym.items() if n != name and v != "none"}
        if kept:
            return "drop it (--sym " + ",".join(f"{n}={'none' if n == name else sym[n]}" for n in sym) + ")"
        method = self.method_name()
        if METHODS.get(method, {}).get("symmetry"):  # +sym would impose odd curves again
            return f"drop it (use --method {method.replace('+sym', '')})"
        return "drop it (leave out --sym)"

    def wants_post_sr(self) -> bool:
        if self.post_sr is not None:
            return bool(self.post_sr)
        return bool(METHODS.get(self.method_name(), {}).get("post_sr", False))

    def preset_object(self):
        return get_preset(self.preset)

    # ------------------------------------------------------------------ fitted attributes
    @property
    def curves_(self):
        return self._fitted().curves

    @property
    def gain_(self) -> float:
        return self._fitted().gain

    @property
    def loss_(self) -> float:
        return self._fitted().loss

    def _fitted(self) -> FittedModel:
        if not hasattr(self, "model_"):
            raise NotFittedError("this CharacteristicCurves is not fitted yet; call fit(trajectory) first")
        return self.model_

    def __repr__(self) -> str:
        sig = inspect.signature(type(self).__init__)
        shown = [f"{n}={getattr(self, n)!r}" for n in self._param_names()
                 if getattr(self, n) is not sig.parameters[n].default and getattr(self, n) != sig.parameters[n].default]
        return f"CharacteristicCurves({', '.join(shown)})"


def fit(traj, method: str | None = None, **kwargs) -> FittedModel:
    """Shortcut: ``CharacteristicCurves(method=method, **kwargs).fit(traj).model_``.

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.systems import get_system
    >>> system = get_system("duffing")
    >>> model = cc.fit(cc.corrupt(system.simulate(), 30, seed=0), method="poly-cc", symmetry="odd")
    >>> model.method, {k: round(v, 3) for k, v in cc.curve_errors(model, system.true_curves()).items()}
    ('poly-cc', {'f1': 0.001, 'f2': 0.002})
    """
    return CharacteristicCurves(method=method, **kwargs).fit(traj).model_
