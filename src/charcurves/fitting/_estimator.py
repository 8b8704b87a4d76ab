"""The estimator users meet: a template + curve representation + priors + fitter, named by method."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from .._errors import ConfigError, DataError, IdentifiabilityError
from ..curves._neural import SYMMETRIES, NeuralCurve
from ..data._trajectory import MIN_SAMPLES, Trajectory
from ..templates._separable import get_template
from ._linear import fit_basis, parse_basis_option
from ._model import FittedModel
from ._presets import get_preset

__all__ = ["CharacteristicCurves", "METHODS", "parse_symmetry", "fit", "dry_friction_test", "JUMP_F_THRESHOLD"]

#: The paper's twelve methods as named presets of shared parts: a curve representation, whether a
#: symmetry prior applies (odd curves unless told otherwise) and whether the learned curves are
#: distilled into closed forms afterwards (post-SR).
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
    "parametric": {"representation": "basis", "symmetry": False, "post_sr": False},
}

#: Fitters of the other representations, loaded on first use ("module:function"). Each is called as
#: ``fitter(traj, template, *, symmetry, options, sr_options, random_state, method)`` and returns a
#: FittedModel; ``symmetry`` maps curve names to "none"/"odd"/"even".
_FITTERS = {
    "poly": "charcurves.fitting._poly:fit_poly",
    "sindy": "charcurves.fitting._sindy:fit_sindy",
    "sr": "charcurves.symbolic._methods:fit_sr",
    "sr-cc": "charcurves.symbolic._methods:fit_sr_cc",
}
#: post-SR: ``distill_model(model, *, sr_options, random_state) -> FittedModel`` with closed-form curves
_DISTILL = "charcurves.symbolic._distill:distill_model"


def _load(path: str):
    import importlib

    module, func = path.split(":")
    return getattr(importlib.import_module(module), func)


#: F statistic above which a jump at zero velocity is significant (chi2(1) quantile, p = 0.001)
JUMP_F_THRESHOLD = 10.83


def dry_friction_test(traj: Trajectory, template) -> tuple[float, float]:
    """F statistic and height of a jump at zero velocity, by least squares.

    The target g F - x'' is regressed on smooth odd and even powers of both arguments (degree
    5), with and without sign(x'); the F statistic of the added column measures how much a
    jump explains beyond smooth curves. Smooth systems give F of order 1 whatever the noise
    level (their curves lie in the span), dry friction gives tens to thousands.
    """
    args = template.arguments_of(traj)
    velocity = [n for n, var in template.variables.items() if var == "v"][0]
    cols = [np.ones(traj.n_samples)]
    for name, z in args.items():
        u = z / max(float(np.max(np.abs(z))), 1e-300)
        cols += [u, u**2, u**3, u**5]
    base = np.column_stack(cols)
    u = args[velocity]
    X = np.column_stack([base, np.sign(u)])
    y = template.gain * np.asarray(traj.F) - np.asarray(traj.a)
    c0, *_ = np.linalg.lstsq(base, y, rcond=None)
    c1, *_ = np.linalg.lstsq(X, y, rcond=None)
    sse0 = float(np.sum((y - base @ c0) ** 2))
    sse1 = float(np.sum((y - X @ c1) ** 2))
    dof = traj.n_samples - X.shape[1]
    if sse1 <= 0 or dof <= 0:
        return 0.0, 0.0
    return (sse0 - sse1) / (sse1 / dof), float(c1[-1])


def parse_symmetry(sym, curve_names=("f1", "f2")) -> dict[str, str]:
    """``"f1=odd,f2=odd"`` / ``{"f1": "odd"}`` / ``"odd"`` (all curves) -> ``{"f1": "odd", "f2": "odd"}``."""
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
                items[k.strip()] = v.strip()
    elif isinstance(sym, dict):
        items = {str(k): str(v) for k, v in sym.items()}
    else:
        raise ConfigError(f"symmetry must be a string like 'f1=odd,f2=odd' or a dict, got {type(sym).__name__}")
    for k, v in items.items():
        if k not in curve_names:
            raise ConfigError(f"symmetry given for unknown curve {k!r}; the curves are {', '.join(curve_names)}")
        if v not in SYMMETRIES:
            raise ConfigError(f"unknown symmetry {v!r} for {k}; choose one of {', '.join(SYMMETRIES)}")
        out[k] = v
    return out


class CharacteristicCurves:
    """Identify the characteristic curves of a template from measured records.

    Parameters
    ----------
    family : str
        The template family ("separable": x'' + f1(x') + f2(x) = g F; "first-order",
        "position-damping", "two-dof": see docs/families.md).
    method : str
        One of :data:`METHODS` ("nn-cc", "nn-cc+sym", "parametric").
    symmetry : str or dict, optional
        Parity priors per curve, e.g. "f1=odd,f2=odd". ``+sym`` methods default to odd curves.
        "auto" tests the parity of unconstrained curves first and imposes only what the data
        support (see :mod:`charcurves.selection._symmetry`); the decision is in
        ``model.info["symmetry_auto"]``.
    free_gain : bool
        Learn the input gain g (otherwise g = ``gain``).
    gain : float
    gain_on : {"force", "acceleration"}
        With a free gain: which measured side is noisy and so the regression target (see
        SeparableTemplate).
    gauge : str, optional
        The curve(s) anchored at 0 to fix the constants curves can trade (separable: "f2" by
        default, or "f1"; two-dof: "f2,f4"). None takes the family's default.
    equation : str, optional
        A user-written template instead of a family, e.g. "x'' + a1*x' + f1(x) = F" (several
        equations separated by ';'); see docs/families.md.
        The curve anchored at 0 (fixes the constant the curves can trade).
    preset : {"default", "paper"} or TrainingPreset
        Training settings of neural curves.
    derivatives : str
        "auto" (given v, a when present, otherwise estimated), "given", "savgol", "spline",
        "spectral" or "fd".
    jump : "auto", "none" or sequence of str
        Curves that get a learned jump at 0 (dry friction), e.g. ("f1",). "auto" (default) adds
        one to the velocity curve when the record has sticking phases (x' = 0 over runs of
        samples), which only dry friction produces, or when a least-squares test finds a jump
        at zero velocity significant (F-test, p < 0.001; see :func:`dry_friction_test`).
    basis : str or dict, optional
        Basis per curve for "parametric", e.g. "f1=z; f2=z, z**3" (z = the curve's argument).
    options : dict, optional
        Settings of the non-neural representations (e.g. {"degree": 10} for poly-cc,
        {"threshold": 1e-4} for the SINDy family).
    sr_options : dict, optional
        Symbolic-regression settings for sr, sr-cc and post-SR: engine ("operon" default,
        "pysr"), generations, populations, population_size, max_size, operators, selection.
    exclude_sticking : bool
        Leave out samples where the mass sticks (x' = 0 over a run): friction is set-valued there.
    random_state : int
    threads : int, optional
        Torch threads during training (None leaves torch's setting).
    device : str
        "cpu" or "cuda".
    refine : {"none", "output-error", "auto"}
        After the fit, refine the closed-form curves' coefficients, the gain and the constant by
        output error (free-run simulation error on the record; see
        :func:`charcurves.fitting._output_error.refine_output_error`). "auto" does so for free-gain
        fits with closed-form curves and estimated derivatives (measured records), else nothing.
    refine_options : dict, optional
        hold ("linear" default, "zoh", "bandlimited"), substeps (4), segment_length (256),
        max_nfev, time_budget (s).

    Examples
    --------
    >>> from charcurves.systems import get_system
    >>> from charcurves.data import corrupt
    >>> traj = corrupt(get_system("duffing").simulate(), 20, seed=0)
    >>> model = CharacteristicCurves(method="parametric").fit(traj).model_
    >>> round(model.curves["f1"].components().get("linear_slope", 0.3), 1)
    0.3
    """

    def __init__(self, family: str = "separable", method: str = "nn-cc+sym", *, symmetry=None,
                 free_gain: bool = False, gain: float = 1.0, gauge: str | None = None, gain_on: str = "force",
                 preset="default",
                 derivatives: str = "auto", jump: str | Sequence[str] = "auto", basis=None,
                 options: dict | None = None, sr_options: dict | None = None, exclude_sticking: bool = True, hidden: Sequence[int] | None = None,
                 activation: str | None = None, random_state: int = 0, threads: int | None = None,
                 device: str = "cpu", progress: Callable | None = None, equation: str | None = None,
                 refine: str = "none", refine_options: dict | None = None):
        self.family = family
        self.method = method
        self.symmetry = symmetry
        self.free_gain = free_gain
        self.gain = gain
        self.gauge = gauge
        self.equation = equation
        self.gain_on = gain_on
        self.preset = preset
        self.derivatives = derivatives
        self.jump = jump
        self.basis = basis
        self.options = options
        self.sr_options = sr_options
        self.exclude_sticking = exclude_sticking
        self.hidden = hidden
        self.activation = activation
        self.random_state = random_state
        self.threads = threads
        self.device = device
        self.progress = progress
        self.refine = refine
        self.refine_options = refine_options

    # scikit-learn's parameter contract
    def get_params(self, deep: bool = True) -> dict[str, Any]:
        import inspect

        names = [p for p in inspect.signature(type(self).__init__).parameters if p != "self"]
        return {n: getattr(self, n) for n in names}

    def set_params(self, **params) -> CharacteristicCurves:
        valid = self.get_params()
        for k, v in params.items():
            if k not in valid:
                raise ConfigError(f"unknown parameter {k!r}; valid: {', '.join(valid)}")
            setattr(self, k, v)
        return self

    # ------------------------------------------------------------------ configuration
    def _check_numeric_options(self) -> None:
        """Seed, threads and gain must be usable numbers; say which one is not before any work starts."""
        def is_int(value) -> bool:
            return isinstance(value, (int, np.integer)) and not isinstance(value, bool)

        if not is_int(self.random_state) or self.random_state < 0:
            raise ConfigError(f"the seed (random_state) must be a non-negative integer, got {self.random_state!r}; "
                              "give e.g. --seed 0")
        if self.threads is not None and (not is_int(self.threads) or self.threads < 1):
            raise ConfigError(f"threads must be a positive integer, got {self.threads!r}; give e.g. --threads 1")
        try:
            gain = float(self.gain)
        except (TypeError, ValueError):
            gain = float("nan")
        if not np.isfinite(gain) or gain == 0:
            raise ConfigError(f"the fixed gain must be a finite non-zero number, got {self.gain!r}; give e.g. gain=1.0")

    def _check_basis_cost(self) -> None:
        """Refuse basis functions whose exact evaluation by sympy could hang (e.g. ``9**9**9*z``)."""
        import re

        from ._model import expression_cost_problem

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

    def _check_device(self) -> None:
        """A torch device that exists on this machine (only neural curves use one)."""
        import torch

        try:
            device = torch.device(self.device)
        except (RuntimeError, TypeError, ValueError):
            raise ConfigError(f"unknown device {self.device!r}; use --device cpu or cuda") from None
        if device.type == "cuda" and not torch.cuda.is_available():
            raise ConfigError(f"device {self.device!r} asked for, but CUDA is not available on this machine; "
                              "use --device cpu")
        if device.type not in ("cpu", "cuda"):
            raise ConfigError(f"device {self.device!r} is not supported; use --device cpu or cuda")

    def _resolve(self):
        if self.method not in METHODS:
            raise ConfigError(f"unknown method {self.method!r}; choose one of {', '.join(METHODS)}")
        spec = METHODS[self.method]
        self._check_numeric_options()
        self._check_basis_cost()
        free_gain = bool(self.free_gain) or bool(spec.get("free_gain", False))
        from ..templates._general import check_equation_option

        check_equation_option(self.equation)
        template = get_template(self.family, equation=self.equation, free_gain=free_gain, gain=float(self.gain), gauge=self.gauge,
                                gain_on=self.gain_on)
        names = template.curve_names
        sym = parse_symmetry(self.symmetry, names)
        if spec["symmetry"] and all(v == "none" for v in sym.values()):
            if self.symmetry not in (None, "", {}) and str(self.symmetry).strip().lower() != "auto":
                # an explicit "no prior" must not be turned into the +sym default silently
                plain = self.method.replace("+sym", "")
                raise ConfigError(
                    f"method {self.method!r} imposes a parity prior but the symmetry given sets none on every curve; "
                    f"use {plain!r} for no prior, or give the parities (e.g. f1=odd,f2=odd)"
                )
            sym = {n: "odd" for n in names}  # the paper's +sym: odd curves
        if not spec["symmetry"] and not spec.get("allows_symmetry") and any(v != "none" for v in sym.values()):
            with_sym = [m for m in METHODS if m.startswith(self.method.split("+")[0]) and METHODS[m]["symmetry"]]
            raise ConfigError(
                f"method {self.method!r} has no symmetry prior; use {with_sym[0]} to impose {self.symmetry!r}"
                if with_sym else f"method {self.method!r} does not take a symmetry prior"
            )
        if self.jump == "auto" or self.jump is None or self.jump == "none":
            return template, spec, sym, (self.jump or "none")
        jumps = [self.jump] if isinstance(self.jump, str) else list(self.jump or ())
        jumps = [j.strip() for item in jumps for j in str(item).split(",") if j.strip()]
        for j in jumps:
            if j not in names:
                raise ConfigError(f"--jump names unknown curve {j!r}; the curves are {', '.join(names)}")
        return template, spec, sym, jumps

    def _prepare(self, traj: Trajectory, sym: dict[str, str], template) -> Trajectory:
        from ..data._differentiate import estimate_derivatives

        if getattr(template, "is_general", False):  # families beyond separable, user-written equations
            from ..templates._fit import prepare_record

            return prepare_record(traj, template, sym, self.derivatives, f"method {self.method}",
                                  without_prior=self._without_prior)
        if not isinstance(traj, Trajectory):
            raise DataError(f"fit expects a Trajectory, got {type(traj).__name__}; build one with Trajectory.from_csv/from_arrays")
        traj.require_samples(MIN_SAMPLES, f"method {self.method}")
        method = self.derivatives
        if method == "given" and not traj.has_derivatives:
            raise DataError("--derivatives given needs v and a columns in the data; "
                            "use --derivatives spline|spectral|savgol to estimate them")
        if not (method in ("auto", "given") and traj.has_derivatives):
            traj = estimate_derivatives(traj.replace(v=None, a=None), "auto" if method == "given" else method)
        try:
            template.check_excitation(traj)
        except DataError as exc:  # no excitation: the data cannot determine the curves at all
            raise IdentifiabilityError(f"no excitation: {exc}") from None
        if template.free_gain and np.ptp(np.asarray(traj.F)) == 0:
            raise IdentifiabilityError(
                "the forcing F is constant over the record, so the gain g cannot be told apart from a constant "
                "offset (not identifiable); drop --free-gain (free_gain=False) or give a record with varying forcing"
            )
        for name, z in template.arguments_of(traj).items():
            if sym[name] != "none" and (z.min() >= 0 or z.max() <= 0):
                raise IdentifiabilityError(
                    f"an {sym[name]} prior on {name} needs its argument {template.arguments[name]} on both "
                    f"sides of 0, but the record covers only [{z.min():.3g}, {z.max():.3g}], so the prior can be "
                    f"neither checked nor used; {self._without_prior(name, sym)} or give a record that crosses 0"
                )
        return traj

    def _without_prior(self, name: str, sym: dict[str, str]) -> str:
        """How to ask for the same fit without the parity prior on ``name`` (for error messages)."""
        kept = {n: v for n, v in sym.items() if n != name and v != "none"}
        if kept:
            return "drop it (--sym " + ",".join(f"{n}={'none' if n == name else sym[n]}" for n in sym) + ")"
        if METHODS[self.method]["symmetry"]:  # +sym would impose odd curves again
            plain = self.method.replace("+sym", "")
            return f"drop it (use --method {plain})"
        return "drop it (leave out --sym)"

    # ------------------------------------------------------------------ fitting
    def fit(self, traj: Trajectory) -> CharacteristicCurves:
        """Fit one record; the result is ``self.model_``."""
        self.model_ = self.fit_many([traj], seeds=[self.random_state])[0]
        return self

    def fit_many(self, trajectories: Sequence[Trajectory], seeds: Sequence[int] | None = None) -> list[FittedModel]:
        """Fit many records (noise realisations, SNR levels...); neural curves train in one batch."""
        if isinstance(self.symmetry, str) and self.symmetry.strip().lower() == "auto":
            from ..selection._symmetry import fit_many_auto  # detect parities, then fit with them

            return fit_many_auto(self, trajectories, seeds)
        self._check_refine()  # before the fit: a bad option must not cost a long run
        models, prepared = self._fit_many_raw(trajectories, seeds)
        if METHODS[self.method]["post_sr"]:
            distill = _load(_DISTILL)
            if seeds is None:
                seeds = [self.random_state + i for i in range(len(models))]
            # a fit stopped by Ctrl-C keeps its networks as they are: distilling them would start
            # another long search the user just asked to stop. Ctrl-C during post-SR keeps the
            # finished networks of the models not distilled yet (Operon does not watch for Ctrl-C:
            # it takes effect when the current curve's search returns, seconds by default)
            stop = any(m.info.get("interrupted") for m in models)
            done = []
            for m, s, tr in zip(models, seeds, prepared):
                if not stop:
                    try:
                        done.append(distill(m, sr_options=dict(self.sr_options or {}), random_state=int(s), traj=tr))
                        continue
                    except KeyboardInterrupt:
                        stop = True
                m.info["post_sr"] = "skipped: interrupted"
                done.append(m)
            models = done
            for m in models:
                m.method = self.method
                if stop:  # the whole call ends interrupted: nothing further (refinement) runs
                    m.info["interrupted"] = True
        return self._refine_models(models, trajectories, prepared)

    def _check_refine(self) -> None:
        from ._output_error import REFINE_MODES, check_refine_options

        if self.refine not in REFINE_MODES:
            raise ConfigError(f"unknown refine {self.refine!r}; choose one of {', '.join(REFINE_MODES)}")
        check_refine_options(self.refine_options)
        spec = METHODS.get(self.method, {})
        if self.refine == "output-error" and spec.get("representation") == "neural" and not spec.get("post_sr"):
            raise ConfigError(f"refine='output-error' needs closed-form curves, but {self.method} learns neural "
                              f"curves; use {self.method}+post-sr (or parametric, poly-cc, sindy), or refine='none'")

    def _refine_models(self, models, trajectories, prepared):
        """Output-error refinement (``refine``) of each fitted model on its own record."""
        if self.refine == "none":
            return models
        from ._output_error import refine_output_error

        out = []
        stop = any(m.info.get("interrupted") for m in models)
        for m, original, tr in zip(models, trajectories, prepared):
            closed = all(c.expression() is not None for c in m.curves.values())
            wanted = self.refine == "output-error" or (
                not getattr(m.template, "is_general", False) and closed
                and getattr(m.template, "free_gain", False) and not self._given(original))
            if wanted and not stop:
                try:
                    out.append(refine_output_error(m, tr, **dict(self.refine_options or {})))
                    continue
                except KeyboardInterrupt:  # keep the finished fit, unrefined, and say so
                    stop = True
            if wanted and stop:
                m.info["refine"] = "skipped: interrupted"
            out.append(m)
        if stop:  # the whole call ends interrupted
            for m in out:
                m.info["interrupted"] = True
        return out

    def _fit_many_raw(self, trajectories, seeds):
        template, spec, sym, jumps = self._resolve()
        trajs = [self._prepare(tr, sym, template) for tr in trajectories]
        if seeds is None:
            seeds = [self.random_state + i for i in range(len(trajs))]
        if getattr(template, "is_general", False):
            from ..templates._fit import fit_general

            return fit_general(self, template, spec, sym, jumps, trajs, seeds), trajs
        if jumps == "none":
            jumps_of = [() for _ in trajs]
        elif jumps == "auto":
            from ..templates._separable import sticking_mask

            velocity = tuple(n for n, var in template.variables.items() if var == "v")
            auto_ok = spec["representation"] == "neural" and get_preset(self.preset).auto_jump
            # decided per record (sticking phases, or the dry-friction F test); records with
            # different curve layouts train in different batches
            jumps_of = [velocity if auto_ok and (
                sticking_mask(tr, rel_tol=None if self._given(tr) else 0.01).any()
                or dry_friction_test(tr, template)[0] > JUMP_F_THRESHOLD) else () for tr in trajs]
        else:
            jumps_of = [tuple(jumps) for _ in trajs]
        jumps = sorted({j for js in jumps_of for j in js})
        if spec["representation"] in _FITTERS:
            if jumps:
                raise ConfigError(f"--jump applies to neural curves, not to method {self.method!r}")
            fitter = _load(_FITTERS[spec["representation"]])
            out = []
            for tr, s in zip(trajs, seeds):
                options = dict(self.options or {})
                if spec["representation"] in ("poly", "sindy"):
                    options.setdefault("exclude_sticking", self.exclude_sticking)
                    options.setdefault("stick_tol", None if self._given(tr) else 0.01)
                out.append(fitter(tr, template, symmetry=sym, options=options,
                                  sr_options=dict(self.sr_options or {}), random_state=int(s), method=self.method))
            return out, trajs
        if spec["representation"] == "basis":
            basis = parse_basis_option(self.basis, template.curve_names)
            if jumps:
                raise ConfigError("--jump applies to neural curves; add tanh(k*z) to the basis for parametric")
            return [fit_basis(tr, template, basis, method=self.method, exclude_sticking=self.exclude_sticking,
                              stick_tol=None if self._given(tr) else 0.01) for tr in trajs], trajs
        from ._neural_fit import fit_neural

        self._check_device()
        preset = get_preset(self.preset)
        given = all(self._given(tr) for tr in trajectories)
        groups: dict[tuple, list[int]] = {}
        for i, tr in enumerate(trajs):
            groups.setdefault((tr.n_samples, jumps_of[i]), []).append(i)
        out: list[FittedModel | None] = [None] * len(trajs)
        for (_, layout), idx in groups.items():
            curves = {
                name: NeuralCurve(
                    hidden=tuple(self.hidden) if self.hidden else preset.hidden,
                    activation=self.activation or preset.activation,
                    symmetry=sym[name],
                    symmetry_mode=preset.symmetry_mode,
                    linear_term=preset.linear_term,
                    jump=name in layout,
                )
                for name in template.curve_names
            }
            models = fit_neural([trajs[i] for i in idx], template, curves, preset, [int(seeds[i]) for i in idx],
                                method=self.method, exclude_sticking=self.exclude_sticking,
                                stick_tol=None if given else 0.01, device=self.device, threads=self.threads,
                                progress=self.progress)
            for i, m in zip(idx, models):
                out[i] = m
        return out, trajs  # type: ignore[return-value]

    def _given(self, traj: Trajectory) -> bool:
        return self.derivatives in ("auto", "given") and traj.has_derivatives

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
        from .._errors import NotFittedError

        if not hasattr(self, "model_"):
            raise NotFittedError("this CharacteristicCurves is not fitted yet; call fit(trajectory) first")
        return self.model_


def fit(traj: Trajectory, method: str = "nn-cc+sym", **kwargs) -> FittedModel:
    """Shortcut: ``CharacteristicCurves(method=method, **kwargs).fit(traj).model_``."""
    return CharacteristicCurves(method=method, **kwargs).fit(traj).model_


