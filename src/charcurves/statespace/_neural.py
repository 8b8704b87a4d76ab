"""Curves of hidden-state fits that are not linear in their parameters: networks and closed forms.

:func:`~._fit.fit_state_space` trains its stages on curves linear in their parameters (exact
re-expression on a new range, linear starts). A curve given as :class:`~charcurves.curves.Neural`
runs those stages as a polynomial of the fit's degree (its start); after the last stage each such
curve becomes its network by least squares on the polynomial's values over the range the states
now visit (one batched Levenberg-Marquardt of :mod:`charcurves.train` per curve), and one more
stage of output error at the last segment length trains the networks with every other parameter
(the Jacobian of the networks is :meth:`~charcurves.curves.NeuralCurve.evaluate_all`'s, the same
as the separable family's output error). Closed forms from post-SR go through the same stage
(:mod:`._post_sr`).
"""

from __future__ import annotations

import math

import numpy as np
import torch

from .._errors import ConfigError
from ..curves import LinearCurve, Neural, NeuralFittedCurve, Polynomial, Symbolic
from ..train import LeastSquaresProblem, train
from ._curves import _Curve

__all__: list[str] = []

#: Grid points of the least-squares transfer of a curve onto a network.
TRANSFER_POINTS = 200


class _ParamCurve(_Curve):
    """A curve of a hidden-state fit in a parametrisation that is not linear (a network's
    :class:`~charcurves.curves.NeuralCurve`, a closed form's
    :class:`~charcurves.curves.SymbolicParametrisation`); ``make(curve, row)`` builds its fitted curve."""

    def __init__(self, name, param, argument, arg_layout, center, half, theta, make, pinned: bool = False):
        super().__init__(name, param, argument, arg_layout, center, half, theta)
        self.make = make
        self.pinned = bool(pinned)
        self.domain = np.stack([center - half, center + half], axis=1)  # (B, 2), set from the states
        self.meta: dict = {}  # a closed form's SR digest

    def param(self):
        return self.rep

    def fitted(self, b):
        return self.make(self, b)


def split_representations(template, structure, degree: int, continued: bool, linear_reps):
    """``(reps, targets)``: what the stages train per curve (``linear_reps`` of the rest: the
    polynomial start of each neural curve) and ``name -> NeuralCurve`` of the curves given as
    networks. ConfigError for a representation a hidden-state fit cannot use."""
    targets = {}
    plain: dict = {}
    for name in structure.curve_names:
        rep = getattr(template, name, None)
        if isinstance(rep, Symbolic):
            raise ConfigError(f"{name}: a hidden-state fit cannot search closed forms (symbolic regression needs "
                              "equation-error data, which a hidden state lacks); give Polynomial or Neural curves "
                              "and post_sr=True (--post-sr) to distil them into closed forms")
        if isinstance(rep, Neural):
            rep.check()
            targets[name] = rep.network(None)
            plain[name] = Polynomial(degree=int(degree), basis="power")
        elif rep is None or isinstance(rep, LinearCurve):
            plain[name] = rep
        else:
            raise ConfigError(f"{name}: hidden-state fits take Polynomial, Basis, SparseLibrary or Neural curves, not "
                              f"{type(rep).__name__}; give {name}=Neural() or {name}=Polynomial(degree=6)")
    return linear_reps(plain), targets


class _CurveValues(LeastSquaresProblem):
    """Least squares of a parametrisation on given values: ``(param(theta, z) - f) / scale``
    per row (``z``, ``f``: ``(B, N)``), with a small weight decay on the network's weights."""

    def __init__(self, param, z: torch.Tensor, f: torch.Tensor, weight_decay: float = 1e-10):
        self.param, self.z, self.f = param, z, f
        self.y = f
        self.n_params = int(param.n_params)
        self.n_data = int(f.shape[1])
        self.n_used = torch.full((f.shape[0],), float(self.n_data), dtype=f.dtype)
        self.gamma = None
        self.weight_decay = weight_decay
        self._w = 1.0 / (f.std(dim=1, keepdim=True).clamp_min(1e-12) * math.sqrt(self.n_data))
        self._setup_decay([(0, param)], self.n_params)

    def _decay_rows(self, theta, r, J=None):
        if self.decay_index is None:
            return r, J
        m = self.decay_index.numel()
        r = torch.cat([r, self._sqrt_wd * theta[:, self.decay_index]], dim=1)
        if J is not None:
            Jd = theta.new_zeros(theta.shape[0], m, self.n_params)
            Jd[:, torch.arange(m), self.decay_index] = self._sqrt_wd.expand(theta.shape[0], m)
            J = torch.cat([J, Jd], dim=1)
        return r, J

    def residuals(self, theta):
        r = (self.param.evaluate(theta, self.z) - self.f) * self._w
        return torch.nan_to_num(self._decay_rows(theta, r)[0], nan=1e3, posinf=1e3, neginf=-1e3)

    def residuals_jacobian(self, theta):
        f, J = self.param.evaluate_jacobian(theta, self.z)
        return self._decay_rows(theta, (f - self.f) * self._w, J * self._w.unsqueeze(-1))

    def loss(self, theta):
        return self.residuals(theta).pow(2).sum(dim=1)


def fit_values(param, z: np.ndarray, f: np.ndarray, theta0: torch.Tensor, max_iter: int = 200) -> np.ndarray:
    """Parameters ``(B, p)`` of ``param`` whose values at ``z`` fit ``f`` (both ``(B, N)``), by the
    trainer's Levenberg-Marquardt from ``theta0``."""
    T = lambda a: torch.as_tensor(np.asarray(a, dtype=float), dtype=torch.float64)  # noqa: E731
    problem = _CurveValues(param, T(z), T(f))
    theta, _ = train(problem, theta0.clone(), adam_steps=0, adam_lr=0.0, lm_max_iter=int(max_iter), lm_tol=1e-10,
                     stop_loss=0.0, lm_nielsen=True)
    return theta.double().numpy()


def _neural_fitted(c, b):
    lo, hi = c.domain[b]
    return NeuralFittedCurve(c.name, c.argument, (float(lo), float(hi)), c.rep, c.theta[b][None].copy(),
                             float(c.half[b]), 1.0, 0.0)


def to_network(c, spec, u: np.ndarray, seed: int) -> _ParamCurve:
    """The network ``spec`` (a :class:`~charcurves.curves.NeuralCurve`) fitted to curve ``c``'s
    values over the range ``u`` (``(B, N)``: its argument along the states) of every row: the
    network sees ``u / max|u|`` (as :class:`~charcurves.curves.NeuralFittedCurve` does)."""
    B = c.theta.shape[0]
    u = np.where(np.isfinite(u), u, np.nan)
    lo, hi = np.nanmin(u, axis=1), np.nanmax(u, axis=1)
    bad = ~(np.isfinite(lo) & np.isfinite(hi) & (hi > lo))
    lo, hi = np.where(bad, c.center - c.half, lo), np.where(bad, c.center + c.half, hi)
    half = np.maximum(np.abs(lo), np.abs(hi))
    grid = lo[:, None] + (hi - lo)[:, None] * np.linspace(0.0, 1.0, TRANSFER_POINTS)[None, :]
    f = c.values(grid)
    gen = torch.Generator().manual_seed(int(seed))
    theta = fit_values(spec, grid / half[:, None], f, spec.init(B, gen, torch.float64))
    out = _ParamCurve(c.name, spec, c.argument, c.arg_layout, np.zeros(B), half, theta, _neural_fitted,
                      pinned=spec.pinned_at_zero)
    out.domain = np.stack([lo, hi], axis=1)
    return out


def with_domain(c, u: np.ndarray):
    """``c`` with its domain the range ``u`` (``(B, N)``) visits (the previous one where it is empty)."""
    u = np.where(np.isfinite(u), u, np.nan)
    lo, hi = np.nanmin(u, axis=1), np.nanmax(u, axis=1)
    ok = np.isfinite(lo) & np.isfinite(hi) & (hi > lo)
    c.domain = np.where(ok[:, None], np.stack([lo, hi], axis=1), c.domain)
    return c


def check_anchors(targets: dict, anchored) -> None:
    """A network the gauge anchors at 0 must be 0 at 0 by construction (odd), else ConfigError."""
    for name in sorted(anchored):
        if name in targets and not targets[name].pinned_at_zero:
            raise ConfigError(f"{name} is anchored at 0 by the template's gauge, which a network does not keep; give "
                              f"{name}=Neural(symmetry='odd') or a Polynomial")


def curve_kind(c) -> str:
    """What a curve of the fit is: "neural", "closed form", or its linear representation's class."""
    from ..curves import ContinuedPolynomial

    rep = getattr(c.rep, "inner", c.rep)
    name = type(rep).__name__
    if name in ("NeuralCurve", "SymbolicParametrisation"):
        return {"NeuralCurve": "neural", "SymbolicParametrisation": "closed form"}[name]
    if isinstance(rep, Polynomial):
        return "ContinuedPolynomial" if isinstance(rep, ContinuedPolynomial) else "Polynomial"
    return name


def network_stage(run, arg, shared, targets, traj, gain, scalars, loss, seed, log, started, progress):
    """Each curve of ``targets`` moved onto its network (:func:`to_network`) and one stage of output
    error (``run``) at the last segment length; Ctrl-C during the transfer keeps the polynomial stages."""
    import time

    try:
        new = [to_network(c, targets[c.name], arg(c, traj), int(seed) + i) if c.name in targets else c
               for i, c in enumerate(shared)]
        traj, gain, scalars, loss_new, iterations, interrupted = run(new, gain, scalars, traj)
    except KeyboardInterrupt:
        log[-1]["stopped"] = "interrupted"
        return shared, traj, gain, scalars, loss, True
    log.append({"segment_length": int(log[-1]["segment_length"]), "linear_curves": False,
                "curves": "neural", "networks": sorted(targets), "loss": [float(v) for v in loss_new],
                "lm_iterations": iterations, "seconds": time.perf_counter() - started})
    if interrupted:
        log[-1]["stopped"] = "interrupted"
    if progress is not None:
        progress(f"networks ({', '.join(sorted(targets))}): best loss {float(np.min(loss_new)):.4g}")
    return new, traj, gain, scalars, loss_new, interrupted
