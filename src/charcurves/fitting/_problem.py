"""The equation-error problem of every gradient-trained fit (any template, any curve parametrisation).

The problem is linear in the curves: for each model k (of K trained together) and sample n,

    r[k, n] = w[k, n] * ( y[k, n] + sum_i m_i[k, n] * f_i(u_i[k, n]) + b[k] - g[k] * F[k, n] )

with ``y`` the known part of the equation (x''), ``m_i`` per-sample multipliers (1 for the
separable family), an optional constant ``b`` and gain ``g``. The symmetry penalty, when used,
adds residuals sqrt(lambda / N_sym) * (f_i(z) -+ f_i(-z)). The loss is the sum of squares, so
``w = 1/sqrt(N)`` gives the paper's mean-squared error.

Models never interact: Adam is elementwise and LM solves one small system per model, so K
models trained together equal K models trained one by one.

A curve is any parametrisation with the protocol of :class:`charcurves.curves.LinearParametrisation`
(a neural network, a polynomial, a user-written representation...). Weight decay (Bayesian
regularisation) acts on the parameters each parametrisation lists in ``decay_groups()``.
The shared decay machinery lives in :class:`LeastSquaresProblem`, which the output-error problem
(:mod:`._shooting`) extends too.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import torch

__all__ = ["CurveTerm", "BatchedProblem", "LeastSquaresProblem", "DECAY_GROUPS"]

DECAY_GROUPS = ("shared", "per-curve", "per-layer")


@dataclasses.dataclass
class CurveTerm:
    """One curve of the equation: its settings and its (scaled) argument per model."""

    curve: Any  # a parametrisation (NeuralCurve, LinearParametrisation, ...)
    u: torch.Tensor  # (K, N) scaled arguments
    multiplier: torch.Tensor | None = None  # (K, N)
    sym_points: torch.Tensor | None = None  # (K, N_sym) scaled points for the penalty

    def __post_init__(self) -> None:
        # exact-symmetry curves evaluate h(u) and h(-u) together; build that input once
        mirror = getattr(self.curve, "uses_mirror", False)
        self.u_both = torch.cat([self.u, -self.u], dim=1) if mirror else None


class LeastSquaresProblem:
    """What the batched trainer needs besides residuals and Jacobians: the weight-decay rows.

    Subclasses set ``n_params`` and call :meth:`_setup_decay` with each curve's parameter offset;
    they provide ``residuals(theta)``, ``residuals_jacobian(theta)``, ``loss(theta)``,
    ``subset(rows)``, ``n_data`` (the residual rows that are data, first), ``n_used`` (data
    samples per model, for the evidence) and a reference tensor ``y`` (device and dtype).
    """

    bayesian: bool = False
    decay_groups: str = "shared"
    #: start the evidence from a decay scaled to the weights' size (output error; see _train)
    scaled_initial_decay: bool = False
    # set by the subclasses (annotations only: no class attributes)
    y: torch.Tensor
    weight_decay: Any
    n_params: int
    decay_index: torch.Tensor | None
    decay_group: torch.Tensor | None

    def _setup_decay(self, blocks, n_params: int) -> None:
        """Decay mask and groups from ``blocks`` = [(offset, parametrisation), ...]."""
        decay = torch.zeros(n_params, dtype=torch.bool)
        group = torch.zeros(n_params, dtype=torch.long)
        parts: list[tuple[int | None, str]] = []
        if self.decay_groups not in DECAY_GROUPS:
            raise ValueError(f"decay_groups must be one of {', '.join(DECAY_GROUPS)}, got {self.decay_groups!r}")
        for i, (offset, curve) in enumerate(blocks):
            for sl, label in curve.decay_groups():
                a, b = offset + sl.start, offset + sl.stop
                decay[a:b] = True
                if self.decay_groups == "per-layer":
                    group[a:b] = len(parts)
                    parts.append((i, label))
                elif self.decay_groups == "per-curve":
                    # a curve's network is one group; its polynomial terms keep a group of their own
                    own = "" if label.startswith("layer") else label
                    if not parts or parts[-1] != (i, own):
                        parts.append((i, own))
                    group[a:b] = len(parts) - 1
        if self.decay_groups == "shared" or not parts:
            parts = [(None, "")]
            group[:] = 0
        use_decay = bool(decay.any()) and (self.bayesian or float(torch.as_tensor(self.weight_decay).max()) > 0)
        self.decay_index = torch.nonzero(decay).flatten().to(self.y.device) if use_decay else None
        # each group as (term index or None for all terms, what part of that term's parameters)
        self.decay_group_parts = parts
        self.n_decay_groups = len(parts)
        self.decay_group = group[decay].to(self.y.device) if use_decay else None  # (m,) group of each decayed weight
        self.set_weight_decay(self.weight_decay)

    def refresh_decay_rows(self, theta: torch.Tensor, r: torch.Tensor, J: torch.Tensor) -> None:
        """Update, in place, the residual and Jacobian rows of the weight decay (the last rows)."""
        idx = self.decay_index
        assert idx is not None  # called only when the problem has decay rows
        m = idx.numel()
        sq = self._sqrt_wd if self._sqrt_wd.dim() else self._sqrt_wd.expand(theta.shape[0], 1)
        r[:, -m:] = sq * theta[:, idx]
        rows = torch.arange(J.shape[1] - m, J.shape[1], device=J.device)
        J[:, rows, idx] = sq.expand(-1, m)

    def set_weight_decay(self, wd) -> None:
        """A float, one value per model ``(K,)``, or one per model and decay group ``(K, G)``."""
        wd = torch.as_tensor(wd, dtype=self.y.dtype, device=self.y.device)
        self.weight_decay = wd
        sq = torch.sqrt(wd.clamp_min(0))
        if wd.dim() == 2 and self.decay_group is not None:
            self._sqrt_wd = sq[:, self.decay_group]  # (K, m): each decayed weight's own group
        else:
            self._sqrt_wd = sq.reshape(-1, 1) if wd.dim() else sq

    def decay_per_group(self, K: int) -> torch.Tensor:
        """The decay as ``(K, G)``."""
        wd = torch.as_tensor(self.weight_decay, dtype=self.y.dtype, device=self.y.device)
        if wd.dim() == 2:
            return wd
        return wd.reshape(-1, 1).expand(K, self.n_decay_groups) if wd.dim() else wd.expand(K, self.n_decay_groups)

    @property
    def K(self) -> int:
        return self.y.shape[0]


@dataclasses.dataclass
class BatchedProblem(LeastSquaresProblem):
    terms: Sequence[CurveTerm]
    y: torch.Tensor  # (K, N)
    F: torch.Tensor  # (K, N)
    weights: torch.Tensor  # (K, N): 1/sqrt(N_used) for used samples, 0 for excluded ones
    free_gain: bool = False
    gain: float = 1.0
    # with a free gain, which measured side carries the noise (the regression target): "force"
    # fits F = h x'' + sum f + b with h = 1/g (the paper's loss, no attenuation by noise on F);
    # "acceleration" fits x'' + sum f + b = g F (for records whose noise sits on the state)
    gain_on: str = "force"
    bias: bool = False
    lambda_sym: float = 0.0
    # on network weights only (linear, jump, gain, constant stay free); a float or one value per
    # model (K,), which Bayesian regularisation updates during Levenberg-Marquardt
    weight_decay: float | torch.Tensor = 0.0
    bayesian: bool = False
    # one decay for all network weights of a model, or one per curve (MacKay's hyperparameter
    # groups: a curve the data make nearly linear can be damped hard while another stays flexible);
    # with per-curve groups weight_decay is (K, n_curves)
    decay_groups: str = "shared"

    def __post_init__(self) -> None:
        self.offsets = []
        o = 0
        for term in self.terms:
            self.offsets.append(o)
            o += term.curve.n_params
        self.gain_index = o if self.free_gain else None
        o += int(self.free_gain)
        self.bias_index = o if self.bias else None
        o += int(self.bias)
        self.n_params = o
        self._setup_decay([(self.offsets[i], term.curve) for i, term in enumerate(self.terms)], o)
        self.n_used = (self.weights > 0).sum(dim=1).to(self.y.dtype)
        self.n_data = self.y.shape[1]
        self.gamma = None
        self.penalised = [
            i
            for i, t in enumerate(self.terms)
            if t.curve.symmetry != "none" and t.curve.symmetry_mode == "penalty" and self.lambda_sym > 0
        ]

    def subset(self, rows: slice) -> BatchedProblem:
        """The same problem for models ``rows`` only (models are independent)."""
        terms = [CurveTerm(t.curve, t.u[rows], None if t.multiplier is None else t.multiplier[rows],
                           None if t.sym_points is None else t.sym_points[rows]) for t in self.terms]
        wd = self.weight_decay
        wd = wd[rows] if torch.is_tensor(wd) and wd.dim() else wd
        return BatchedProblem(terms, self.y[rows], self.F[rows], self.weights[rows], free_gain=self.free_gain,
                              gain=self.gain, gain_on=self.gain_on, bias=self.bias, lambda_sym=self.lambda_sym, weight_decay=wd,
                              bayesian=self.bayesian, decay_groups=self.decay_groups)

    def block(self, theta: torch.Tensor, i: int) -> torch.Tensor:
        o = self.offsets[i]
        return theta[:, o : o + self.terms[i].curve.n_params]

    def _base(self, theta: torch.Tensor) -> torch.Tensor:
        if self.free_gain and self.gain_on == "force":
            return self.gain_of(theta) * self.y + self.bias_of(theta) - self.F
        return self.y + self.bias_of(theta) - self.gain_of(theta) * self.F

    def gain_of(self, theta: torch.Tensor) -> torch.Tensor:
        """The free coefficient: g (gain_on="acceleration") or h = 1/g (gain_on="force")."""
        if self.free_gain:
            assert self.gain_index is not None
            return theta[:, self.gain_index : self.gain_index + 1]
        return torch.full((theta.shape[0], 1), float(self.gain), dtype=theta.dtype, device=theta.device)

    def bias_of(self, theta: torch.Tensor) -> torch.Tensor:
        if self.bias:
            assert self.bias_index is not None
            return theta[:, self.bias_index : self.bias_index + 1]
        return torch.zeros(theta.shape[0], 1, dtype=theta.dtype, device=theta.device)

    # ------------------------------------------------------------------ residuals
    def residuals(self, theta: torch.Tensor) -> torch.Tensor:
        pred = self._base(theta)
        for i, term in enumerate(self.terms):
            f = term.curve.evaluate(self.block(theta, i), term.u, term.u_both)
            pred = pred + (f if term.multiplier is None else term.multiplier * f)
        parts = [self.weights * pred]
        for i in self.penalised:
            parts.append(self._sym_residual(theta, i))
        if self.decay_index is not None:
            parts.append(self._sqrt_wd * theta[:, self.decay_index])
        return torch.cat(parts, dim=1) if len(parts) > 1 else parts[0]

    def _sym_residual(self, theta, i):
        term = self.terms[i]
        z = term.sym_points
        both = term.curve.evaluate(self.block(theta, i), torch.cat([z, -z], dim=1))
        n = z.shape[1]
        s = -1.0 if term.curve.symmetry == "odd" else 1.0
        return math.sqrt(self.lambda_sym / n) * (both[:, :n] - s * both[:, n:])

    def residuals_jacobian(self, theta: torch.Tensor):
        K, N = self.y.shape
        J = theta.new_zeros(K, N, self.n_params)
        pred = self._base(theta)
        for i, term in enumerate(self.terms):
            f, Ji = term.curve.evaluate_jacobian(self.block(theta, i), term.u, term.u_both)
            if term.multiplier is not None:
                f = term.multiplier * f
                Ji = term.multiplier.unsqueeze(-1) * Ji
            pred = pred + f
            o = self.offsets[i]
            J[:, :, o : o + term.curve.n_params] = Ji
        if self.free_gain:
            J[:, :, self.gain_index] = self.y if self.gain_on == "force" else -self.F
        if self.bias:
            J[:, :, self.bias_index] = 1.0
        r = [self.weights * pred]
        Js = [self.weights.unsqueeze(-1) * J]
        for i in self.penalised:
            term = self.terms[i]
            z = term.sym_points
            assert z is not None  # penalised terms have symmetry points
            n = z.shape[1]
            f, Ji = term.curve.evaluate_jacobian(self.block(theta, i), torch.cat([z, -z], dim=1))
            s = -1.0 if term.curve.symmetry == "odd" else 1.0
            c = math.sqrt(self.lambda_sym / n)
            Jp = theta.new_zeros(K, n, self.n_params)
            o = self.offsets[i]
            Jp[:, :, o : o + term.curve.n_params] = c * (Ji[:, :n] - s * Ji[:, n:])
            r.append(c * (f[:, :n] - s * f[:, n:]))
            Js.append(Jp)
        if self.decay_index is not None:
            m = self.decay_index.numel()
            Jd = theta.new_zeros(K, m, self.n_params)
            Jd[:, torch.arange(m, device=theta.device), self.decay_index] = (
                self._sqrt_wd.expand(K, m) if self._sqrt_wd.dim() else self._sqrt_wd)
            r.append(self._sqrt_wd * theta[:, self.decay_index])
            Js.append(Jd)
        return torch.cat(r, dim=1), torch.cat(Js, dim=1)

    def loss(self, theta: torch.Tensor) -> torch.Tensor:
        """Total loss per model, ``(K,)``."""
        return self.residuals(theta).pow(2).sum(dim=1)


