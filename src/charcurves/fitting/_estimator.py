"""The estimator users meet: a template with a representation per curve, a differentiator, an
objective and optional post-SR, composed as objects (or built from one of the paper's methods by
:meth:`CharacteristicCurves.from_method`)."""

from __future__ import annotations

import copy
import inspect
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from .._bounds import check_number, check_seeds
from .._errors import ConfigError, NotFittedError
from .._params import Params
from ._legacy import from_legacy, legacy_options
from ._method_preset import MethodPreset
from ._methods import METHODS, check_method_options, method_curve, parse_basis_option, parse_symmetry
from ..model import FittedModel
from ..train import TrainingPreset, get_preset, torch_threads
from ._pipeline import run_pipeline
from ._offsets import name_offset_in_warnings
from ._priors import name_prior_in_warnings, priors_record
from ._symmetry import fit_many_auto

if TYPE_CHECKING:
    from ..data import Differentiator
    from ..templates import Template
    from ..objectives import Objective

__all__ = ["CharacteristicCurves", "fit", "MAX_SEED"]

#: Largest seed: every generator downstream (numpy, torch, Operon) accepts it.
MAX_SEED = 2**32 - 1


class CharacteristicCurves(Params):
    """Identify the characteristic curves of a template from measured records.

    Compose the parts as objects::

        CharacteristicCurves(template=Separable(f1=Polynomial(degree=3, symmetry="odd"), f2=Neural(symmetry="odd")),
                             differentiator=SavitzkyGolay(window=31, order=3), objective="auto")

    or build them from one of the paper's twelve methods with :meth:`from_method`
    (``CharacteristicCurves.from_method("nn-cc+sym", family="two-dof")``; see :data:`METHODS`).

    Parameters
    ----------
    template : Template, optional
        A template object (``Separable``, ``PositionDamping``, ``FirstOrder``, ``TwoDOF``, ``Equation``) with a representation per curve; unset curves take the method's.
    method : MethodPreset, optional
        The method preset and its shorthands (family, priors, basis...); :meth:`from_method` builds it. None: the default, NN-CC with the parity priors the record supports.
    differentiator : str or Differentiator, optional
        How the template's derivatives are obtained: "auto" (None: the record's own columns, else estimated), "given", a name ("spectral", "savgol", ...) or an instance.
    objective : str or Objective
        "auto" (default: equation error, then output error on records whose derivatives were estimated), "equation-error", "output-error" or an objective object (``EquationError()``, ``OutputError(...)``, ``Auto(...)`` or a subclass of ``Objective`` of your own).
    post_sr : bool, optional
        Distil the fitted curves into closed forms (symbolic regression); None: the method's choice.
    preset : str or TrainingPreset
        Training settings of gradient-trained curves: "default", "paper" or a TrainingPreset.
    random_state : int
        Seed of every random choice (0 to 2**32 - 1).
    threads : int, optional
        Torch and BLAS threads during the whole fit (None leaves both as they are).
    device : str
        Where neural curves train: "cpu" or "cuda".
    progress : callable, optional
        ``progress(phase, step, total, loss)`` during training.
    snr_db : float, optional
        Known signal-to-noise ratio of the forcing in dB for the self-check (None: the noise floor is estimated).
    **legacy : Any
        The older spellings (``method="nn-cc"``, ``family=``, ``symmetry=``, ``derivatives=``, ``refine=``...): accepted for one release with a FutureWarning; use :meth:`from_method`.

    Examples
    --------
    >>> from charcurves.data import corrupt
    >>> from charcurves.fitting import CharacteristicCurves
    >>> from charcurves.systems import get_system
    >>> traj = corrupt(get_system("duffing").simulate(), 20, seed=0)
    >>> model = CharacteristicCurves.from_method("parametric", basis="f1=z; f2=z, z**3").fit(traj).model_
    >>> round(model.curves["f1"].components().get("linear_slope", 0.3), 1)
    0.3
    """

    def __init__(self, template: Template | None = None, *, method: MethodPreset | None = None,
                 differentiator: str | Differentiator | None = None,
                 objective: str | Objective = "auto", post_sr: bool | None = None, preset: str | TrainingPreset = "default",
                 random_state: int = 0, threads: int | None = None, device: str = "cpu",
                 progress: Callable | None = None, snr_db: float | None = None, **legacy: Any):
        if legacy or isinstance(method, str):  # the older spelling: one FutureWarning, then the same objects
            method, differentiator, objective = from_legacy(method, differentiator, objective, legacy)
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
        self.snr_db = snr_db

    @classmethod
    def from_method(cls, method: str | None = None, *, template: Template | None = None, family: str = "separable",
                    equation: str | None = None, symmetry: str | dict | None = None, free_gain: bool = False,
                    gain: float = 1.0, gauge: str | Sequence[str] | None = None, gain_on: str = "force",
                    jump: str | Sequence[str] = "auto",
                    basis: str | dict | list | None = None, options: dict | None = None, degree: int | None = None,
                    hidden: Sequence[int] | None = None, activation: str | None = None,
                    exclude_sticking: bool = True, sr_options: dict | None = None,
                    differentiator: str | Differentiator | None = None,
                    objective: str | Objective = "auto", post_sr: bool | None = None, preset: str | TrainingPreset = "default",
                    random_state: int = 0, threads: int | None = None, device: str = "cpu",
                    progress: Callable | None = None, snr_db: float | None = None) -> CharacteristicCurves:
        """The estimator of one of the paper's methods, its shorthands turned into a :class:`MethodPreset`.

        A shorthand the method would ignore (``degree=`` with a neural method, ``basis=`` outside
        "parametric", curve settings where ``template`` sets every curve) is a ConfigError naming it.

        Parameters
        ----------
        method : str, optional
            One of :data:`METHODS`; None: NN-CC whose parity priors are those the record supports (each curve's parity is tested first).
        template : Template, optional
            A template object; its unset curves take the method's representation.
        family : str
            The template family without a template: "separable", "first-order", "position-damping" or "two-dof".
        equation : str, optional
            A user-written equation instead of a family (``"x'' + f1(x)*x' + f2(x) = F"``).
        symmetry : str or dict, optional
            Parity priors: "f1=odd,f2=odd", "odd" (every curve), a dict, or "auto" (tested on unconstrained curves).
        free_gain : bool
            Learn the input gain g.
        gain : float
            The fixed input gain (the paper: 1).
        gauge : str or sequence of str, optional
            Curves anchored at 0 (None: the family's default).
        gain_on : str
            With a free gain, the noisy side and regression target: "force" or "acceleration".
        jump : str or sequence of str
            A learned jump at 0 of neural curves: "auto" (where the record sticks), "none" or curve names.
        basis : str or dict or list, optional
            The functions of each curve of method "parametric" ("f1=z; f2=z, z**3").
        options : dict, optional
            Options of the method's representation ({"degree": 10}, {"threshold": 0.05}) and of sticking detection.
        degree : int, optional
            The polynomial degree of "poly-cc" and the SINDy methods (``options["degree"]``).
        hidden : sequence of int, optional
            Layer widths of neural curves (None: the training preset's).
        activation : str, optional
            Activation of neural curves (None: the training preset's).
        exclude_sticking : bool
            Leave out samples where the mass sticks.
        sr_options : dict, optional
            Symbolic regression settings (engine, generations, ...) of the SR methods and post-SR.
        differentiator : str or Differentiator, optional
            As :class:`CharacteristicCurves`: "auto" (None), "given", a name or an instance.
        objective : str or Objective
            As :class:`CharacteristicCurves`: "auto", "equation-error", "output-error" or an object.
        post_sr : bool, optional
            Distil the fitted curves into closed forms; None: the method's choice (the "+post-sr" methods).
        preset : str or TrainingPreset
            Training settings of gradient-trained curves: "default", "paper" or a TrainingPreset.
        random_state : int
            Seed of every random choice (0 to 2**32 - 1).
        threads : int, optional
            Torch and BLAS threads during the whole fit (None leaves both as they are).
        device : str
            Where neural curves train: "cpu" or "cuda".
        progress : callable, optional
            ``progress(phase, step, total, loss)`` during training.
        snr_db : float, optional
            Known signal-to-noise ratio of the forcing in dB for the self-check (None: estimated).

        Examples
        --------
        >>> from charcurves.fitting import CharacteristicCurves
        >>> est = CharacteristicCurves.from_method("poly-cc", symmetry="odd", degree=5, random_state=1)
        >>> est.method, est.random_state
        (MethodPreset(name='poly-cc', symmetry='odd', options={'degree': 5}), 1)
        >>> CharacteristicCurves.from_method("nn-cc", degree=5)
        Traceback (most recent call last):
        ...
        charcurves._errors.ConfigError: degree= applies to poly-cc and the SINDy methods, not to method 'nn-cc'
        """
        preset_obj = MethodPreset.build(method, template=template, family=family, equation=equation,
                                        symmetry=symmetry, free_gain=free_gain, gain=gain, gauge=gauge, gain_on=gain_on,
                                        jump=jump, basis=basis, options=options, degree=degree, hidden=hidden,
                                        activation=activation, exclude_sticking=exclude_sticking, sr_options=sr_options)
        return cls(template, method=preset_obj, differentiator=differentiator, objective=objective, post_sr=post_sr,
                   preset=preset, random_state=random_state, threads=threads, device=device, progress=progress,
                   snr_db=snr_db)

    # ------------------------------------------------------------------ fitting
    def fit(self, traj) -> CharacteristicCurves:
        """Fit one record, or a list of records together (curves, scalars and gain shared; initial
        and segment states per record; ``model_.info["records"]``); the result is ``self.model_``."""
        if isinstance(traj, (list, tuple)):
            from ._records import as_record_set

            group = as_record_set(traj)
            traj = group if len(group) > 1 else group.records[0]
        self.model_ = self.fit_many([traj], seeds=[self.random_state])[0]
        return self

    def fit_many(self, trajectories: Sequence, seeds: Sequence[int] | None = None) -> list[FittedModel]:
        """Fit many records (noise realisations, SNR levels...); neural curves train in one batch.
        ``threads`` holds for the whole fit (warm start, training, output error), so the bytes of
        the result do not depend on the environment's OMP_NUM_THREADS."""
        self.check()  # the thread count among the rest, before it is used
        trajectories = list(trajectories)
        seeds = check_seeds(seeds, len(trajectories))  # one integer seed per record (issue 50)
        with torch_threads(self.threads):
            if self.tests_priors():  # nothing asked: test the parities, impose what the record supports
                models = fit_many_auto(self, trajectories, seeds, default=True)
            elif isinstance(self.symmetry, str) and self.symmetry.strip().lower() == "auto":
                models = fit_many_auto(self, trajectories, seeds)  # detect parities, then fit with them
            else:
                models = run_pipeline(self, trajectories, seeds)
        for m in models:
            m.info["priors"] = priors_record(self, m)
            name_prior_in_warnings(m)
            name_offset_in_warnings(m)  # a misfit on a range far from 0 says so
        return models

    # ------------------------------------------------------------------ resolution (used by the pipeline)
    def tests_priors(self) -> bool:
        """Whether no method, template or symmetry was asked: then :meth:`fit_many` tests each
        curve's parity (poly-cc, about 0.1 s) and imposes only what the record supports."""
        m = self._shorthands()
        return m.name is None and self.template is None and m.symmetry in (None, "", {})

    def method_name(self) -> str:
        """The method preset: ``method``, else "nn-cc+sym" when a parity is asked (``symmetry``),
        else "nn-cc" (no prior; :meth:`fit_many` tests the parities first); "custom" for a template."""
        m = self._shorthands()
        if m.name is not None:
            return m.name
        if self.template is not None:
            return "custom"
        sym = m.symmetry
        values = sym.values() if isinstance(sym, dict) else str(sym or "").replace("=", ",").split(",")
        return "nn-cc+sym" if any(str(v).strip() in ("odd", "even") for v in values) else "nn-cc"

    def check(self) -> None:
        """Numbers and names that must be usable before any work starts."""
        def is_int(value) -> bool:
            return isinstance(value, (int, np.integer)) and not isinstance(value, bool)

        m = self._shorthands()
        m.check(self.template)  # a known method; no shorthand that it would ignore
        check_number("seed", self.random_state, label="the seed (random_state, --seed)")
        if self.threads is not None:
            check_number("threads", self.threads)
        if self.device != "cpu":  # a device that does not exist, for every method (poly-cc took "tpu" silently)
            from ._pipeline import check_device

            check_device(self.device)
        for name in ("free_gain", "exclude_sticking"):  # free_gain="False" would turn the gain on
            value = getattr(m, name)
            if not isinstance(value, (bool, np.bool_)):
                raise ConfigError(f"{name} must be True or False, got {value!r}; give e.g. {name}=True")
        if self.post_sr is not None and not isinstance(self.post_sr, (bool, np.bool_)):
            raise ConfigError(f"post_sr must be True, False or None, got {self.post_sr!r}")
        if m.hidden is not None and (isinstance(m.hidden, (str, bytes)) or not hasattr(m.hidden, "__iter__")
                                     or not all(is_int(h) and 1 <= h <= 4096 for h in m.hidden)
                                     or not 1 <= len(list(m.hidden)) <= 16):
            raise ConfigError(f"hidden must be a sequence of 1 to 16 layer widths, integers from 1 to 4096, got "
                              f"{m.hidden!r}; give e.g. hidden=(16, 16)")
        try:
            gain = float(m.gain)
        except (TypeError, ValueError):
            gain = float("nan")
        if not np.isfinite(gain) or gain == 0:
            raise ConfigError(f"the fixed gain must be a finite non-zero number, got {m.gain!r}; give e.g. gain=1.0")
        if self.snr_db is not None:
            try:
                snr = float(self.snr_db)
            except (TypeError, ValueError):
                snr = float("nan")
            if not np.isfinite(snr) or isinstance(self.snr_db, bool):
                raise ConfigError(f"snr_db must be a finite number of dB, got {self.snr_db!r}; give e.g. snr_db=20 "
                                  "(--snr 20), or leave it out to estimate the noise floor from the record")
            check_number("snr_db", snr)
        if m.sr_options is not None:  # before any training: post-SR runs after it
            from ..symbolic import make_engine

            make_engine(m.sr_options)
        m.check_basis_cost()

    def differentiator_value(self):
        return "auto" if self.differentiator is None else self.differentiator

    def resolve(self):
        """``(template object with every curve set, its structure, symmetry per curve, method label)``."""
        from ..templates import as_template

        self.check()
        m = self._shorthands()
        method = self.method_name()
        spec = METHODS.get(method)
        if self.template is None:
            free_gain = bool(m.free_gain) or bool(spec.get("free_gain", False))
            tmpl = as_template(m.family, equation=m.equation, free_gain=free_gain, gain=float(m.gain),
                               gauge=m.gauge, gain_on=m.gain_on)
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
        sym = parse_symmetry(m.symmetry, names) if unset else {n: "none" for n in names}
        if spec is not None and unset:
            sym = self._method_symmetry(method, spec, sym, names)
            options = check_method_options(method, m.options)
            basis = parse_basis_option(m.basis, names, family=structure.family) if spec["representation"] == "basis" \
                else None
            jump = self._jumps(names)
            if jump not in ("auto", "none") and spec["representation"] != "neural":
                raise ConfigError(f"--jump applies to neural curves, not to method {method!r}"
                                  + ("; add tanh(k*z) to the basis for parametric" if method == "parametric" else ""))
            for n in unset:
                curve = method_curve(method, n, symmetry=sym[n], jump="auto" if jump == "auto" else
                                     (() if jump == "none" else jump), options=options, basis=basis,
                                     hidden=m.hidden, activation=m.activation,
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

    # ------------------------------------------------------------------ the parameter contract
    def flat_params(self) -> dict[str, Any]:
        """Every setting as :meth:`from_method`'s arguments: ``from_method(**est.flat_params())`` is an
        equal estimator (used where a fit derives a variant, e.g. the parity tests)."""
        out = self.get_params(deep=False)
        preset = out.pop("method")
        out.update(self._shorthands().get_params(deep=False))
        out["method"] = out.pop("name")
        if preset is None:
            out["method"] = None
        return out

    def _shorthands(self) -> MethodPreset:
        if self.method is None:
            return MethodPreset()
        if not isinstance(self.method, MethodPreset):
            raise ConfigError(f"method must be a MethodPreset, got {self.method!r}; build the estimator with "
                              "CharacteristicCurves.from_method(...) or give method=MethodPreset(...)")
        return self.method

    # read by the fitting code (the pipeline, the parity tests): the method preset's shorthands
    @property
    def symmetry(self):
        return self._shorthands().symmetry

    @property
    def options(self) -> dict | None:
        return self._shorthands().options

    @property
    def jump(self):
        return self._shorthands().jump

    @property
    def exclude_sticking(self) -> bool:
        return self._shorthands().exclude_sticking

    @property
    def sr_options(self) -> dict | None:
        return self._shorthands().sr_options

    #: older names of the objective's settings: the constructor turns them into the objective
    refine = None
    refine_options = None

    def __repr__(self) -> str:
        sig = inspect.signature(type(self).__init__)
        shown = [f"{n}={v!r}" for n, v in self.get_params(deep=False).items()
                 if n != "method" and not _is_default(v, sig.parameters[n].default)]
        if self.method is None:
            return f"CharacteristicCurves({', '.join(shown)})"
        own = self._shorthands()
        head = [f"{own.name!r}"] if own.name is not None else []
        return f"CharacteristicCurves.from_method({', '.join(head + [f'{n}={getattr(own, n)!r}' for n in own.given()] + shown)})"


def _is_default(value: Any, default: Any) -> bool:
    try:
        return value is default or bool(value == default)
    except Exception:  # noqa: BLE001 - arrays and odd objects
        return False


def fit(traj, method: str | None = None, **kwargs) -> FittedModel:
    """Shortcut: ``CharacteristicCurves.from_method(method, **kwargs).fit(traj).model_``.

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.systems import get_system
    >>> system = get_system("duffing")
    >>> model = cc.fit(cc.corrupt(system.simulate(), 30, seed=0), method="poly-cc", symmetry="odd")
    >>> model.method, {k: round(v, 3) for k, v in cc.curve_errors(model, system.true_curves()).items()}
    ('poly-cc', {'f1': 0.001, 'f2': 0.002})
    """
    return CharacteristicCurves.from_method(method, **legacy_options(kwargs)).fit(traj).model_
