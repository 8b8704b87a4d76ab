"""The equation-error problem of every gradient-trained fit (any template, any curve parametrisation).

The problem is linear in the curves: for each model k (of K trained together) and sample n,

    r[k, n] = w[k, n] * ( y[k, n] + sum_i m_i[k, n] * f_i(u_i[k, n]) + b[k] - g[k] * F[k, n] )

with ``y`` the known part of the equation (x''), ``m_i`` per-sample multipliers (1 for the
separable family), an optional constant ``b`` and gain ``g``. The symmetry penalty, when used,
adds residuals sqrt(lambda / N_sym) * (f_i(z) -+ f_i(-z)). The loss is the sum of squares, so
``w = 1/sqrt(N)`` gives the paper's mean-squared error.

Models never interact: Adam is elementwise and LM solves one small system per model, so K
models trained together equal K models trained one by one, to rounding. Not always to the bit:
torch's batched matrix product takes another path for a batch of one where a factor has a
dimension of one (a network's first and last layers), and float32 training over many epochs
grows that last-bit difference (docs/benchmark.md, "The paper's protocol on this CPU"). There,
batches of 2, 3, 5 and 10 gave each network layer's product the same bits, and batches of two and
three records the same fits after 5 epochs of the `paper` preset.

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

#: Decay groups whose label starts with this hold one coefficient of a linear or closed-form curve
#: (automatic relevance determination, e.g. output error's ``_Ridge``); see ``relevance_groups``.
RELEVANCE_LABEL = "coefficient "

#: bytes of one chunk's Jacobian in the normal equations of long records
CHUNK_BYTES = 32 * 2**20
#: records up to this length keep each mirrored curve's input ``cat([u, -u])`` precomputed
MIRROR_CACHE_SAMPLES = 16384


@dataclasses.dataclass
class CurveTerm:
    """One curve of the equation: its settings and its (scaled) argument per model."""

    curve: Any  # a parametrisation (NeuralCurve, LinearParametrisation, ...)
    u: torch.Tensor  # (K, N) scaled arguments
    multiplier: torch.Tensor | None = None  # (K, N)
    sym_points: torch.Tensor | None = None  # (K, N_sym) scaled points for the penalty

    def __post_init__(self) -> None:
        # exact-symmetry curves evaluate h(u) and h(-u) together; build that input once (not on
        # long records, which are evaluated in chunks that build their own)
        mirror = getattr(self.curve, "uses_mirror", False) and self.u.shape[1] <= MIRROR_CACHE_SAMPLES
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
    #: parameters that stay fixed (a boolean mask over theta's columns), or None
    frozen: torch.Tensor | None = None
    # set by the subclasses (annotations only: no class attributes)
    y: torch.Tensor
    weight_decay: Any
    n_params: int
    n_data: int
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
        # which groups are one coefficient's relevance (ARD), as opposed to a network's weights
        self.relevance_groups = torch.tensor([label.startswith(RELEVANCE_LABEL) for _, label in parts],
                                             dtype=torch.bool, device=self.y.device)
        self.decay_group = group[decay].to(self.y.device) if use_decay else None  # (m,) group of each decayed weight
        self.set_weight_decay(self.weight_decay)

    def residuals(self, theta: torch.Tensor) -> torch.Tensor:
        """Residuals ``(K, R)``: the data's first, the decay's last."""
        raise NotImplementedError

    def residuals_jacobian(self, theta: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Residuals ``(K, R)`` and their Jacobian ``(K, R, P)``, the decay's rows last."""
        raise NotImplementedError

    def data_loss(self, theta: torch.Tensor) -> torch.Tensor:
        """Sum of squared data residuals per model, ``(K,)``."""
        return self.residuals(theta)[:, :self.n_data].pow(2).sum(dim=1)

    def normal_equations(self, theta: torch.Tensor):
        """``(JtJ, Jtr, cost, data_cost)`` of every residual row but the weight decay's: JtJ
        ``(K, P, P)``, Jtr ``(K, P)``, the sum of squares ``(K,)`` and that of the data rows alone
        ``(K,)``. The decay's rows are added by :meth:`decay_terms`, so that a new decay needs no
        new pass over the data. This generic version forms the whole Jacobian; problems over long
        records override it to accumulate over chunks of samples."""
        r, J = self.residuals_jacobian(theta)
        if self.decay_index is not None:
            m = self.decay_index.numel()
            r, J = r[:, :-m], J[:, :-m]
        Jt = J.transpose(1, 2)
        return Jt @ J, (Jt @ r.unsqueeze(-1)).squeeze(-1), r.pow(2).sum(1), r[:, :self.n_data].pow(2).sum(1)

    def decay_terms(self, theta: torch.Tensor):
        """The weight decay's share of the normal equations: ``(w2, cost)`` with ``w2`` ``(K, m)``
        the squared decay of each decayed weight (0 for frozen ones, whose Jacobian column is
        zero), to be added to JtJ's diagonal and, times the weight, to Jtr; ``cost`` ``(K,)``."""
        idx = self.decay_index
        assert idx is not None  # called only when the problem has decay rows
        K, m = theta.shape[0], idx.numel()
        sq = self._sqrt_wd.expand(K, m)
        w2 = sq * sq
        cost = (w2 * theta[:, idx].pow(2)).sum(1)
        if self.frozen is not None:
            w2 = torch.where(self.frozen[idx].to(w2.device), torch.zeros_like(w2), w2)
        return w2, cost

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

    def _base(self, theta: torch.Tensor, sl: slice | None = None) -> torch.Tensor:
        y, F = (self.y, self.F) if sl is None else (self.y[:, sl], self.F[:, sl])
        if self.free_gain and self.gain_on == "force":
            return self.gain_of(theta) * y + self.bias_of(theta) - F
        return y + self.bias_of(theta) - self.gain_of(theta) * F

    def _term_inputs(self, term: CurveTerm, sl: slice | None):
        """A term's ``(u, u_both, multiplier)`` over the samples ``sl`` (all by default)."""
        if sl is None:
            return term.u, term.u_both, term.multiplier
        u = term.u[:, sl]
        return (u, None if term.u_both is None else torch.cat([u, -u], dim=1),
                None if term.multiplier is None else term.multiplier[:, sl])

    def _weighted_data(self, theta: torch.Tensor, sl: slice | None = None) -> torch.Tensor:
        pred = self._base(theta, sl)
        for i, term in enumerate(self.terms):
            u, u_both, mult = self._term_inputs(term, sl)
            f = term.curve.evaluate(self.block(theta, i), u, u_both)
            pred = pred + (f if mult is None else mult * f)
        return (self.weights if sl is None else self.weights[:, sl]) * pred

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
        parts = [self._weighted_data(theta)]
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

    def _data_rows(self, theta: torch.Tensor, sl: slice | None = None):
        """Weighted data residuals and their Jacobian over the samples ``sl`` (all by default)."""
        y, F, w = (self.y, self.F, self.weights) if sl is None else (self.y[:, sl], self.F[:, sl], self.weights[:, sl])
        K, N = y.shape
        J = theta.new_zeros(K, N, self.n_params)
        pred = self._base(theta, sl)
        for i, term in enumerate(self.terms):
            u, u_both, mult = self._term_inputs(term, sl)
            f, Ji = term.curve.evaluate_jacobian(self.block(theta, i), u, u_both)
            if mult is not None:
                f = mult * f
                Ji = mult.unsqueeze(-1) * Ji
            pred = pred + f
            o = self.offsets[i]
            J[:, :, o : o + term.curve.n_params] = Ji
        if self.free_gain:
            J[:, :, self.gain_index] = y if self.gain_on == "force" else -F
        if self.bias:
            J[:, :, self.bias_index] = 1.0
        return w * pred, w.unsqueeze(-1) * J

    def _penalty_rows(self, theta: torch.Tensor):
        K = theta.shape[0]
        r, Js = [], []
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
        return r, Js

    def chunk_samples(self) -> int:
        """Samples per chunk of the normal equations: a chunk's Jacobian stays near 32 MB."""
        per_sample = self.K * self.n_params * self.y.element_size()
        return max(1024, int(CHUNK_BYTES // max(per_sample, 1)))

    def _chunks(self):
        N, c = self.n_data, self.chunk_samples()
        return [None] if N <= c else [slice(a, min(a + c, N)) for a in range(0, N, c)]

    def normal_equations(self, theta: torch.Tensor):
        """Accumulated over chunks of samples, so that memory does not grow with the record."""
        K, P = theta.shape
        JtJ = theta.new_zeros(K, P, P)
        g = theta.new_zeros(K, P)
        data = theta.new_zeros(K)
        for sl in self._chunks():
            r, J = self._data_rows(theta, sl)
            Jt = J.transpose(1, 2)
            JtJ = JtJ + Jt @ J
            g = g + (Jt @ r.unsqueeze(-1)).squeeze(-1)
            data = data + r.pow(2).sum(1)
        cost = data
        for r, J in zip(*self._penalty_rows(theta)):
            Jt = J.transpose(1, 2)
            JtJ = JtJ + Jt @ J
            g = g + (Jt @ r.unsqueeze(-1)).squeeze(-1)
            cost = cost + r.pow(2).sum(1)
        return JtJ, g, cost, data

    def residuals_jacobian(self, theta: torch.Tensor):
        K = theta.shape[0]
        r0, J0 = self._data_rows(theta)
        pr, pJ = self._penalty_rows(theta)
        r, Js = [r0, *pr], [J0, *pJ]
        if self.decay_index is not None:
            m = self.decay_index.numel()
            Jd = theta.new_zeros(K, m, self.n_params)
            Jd[:, torch.arange(m, device=theta.device), self.decay_index] = (
                self._sqrt_wd.expand(K, m) if self._sqrt_wd.dim() else self._sqrt_wd)
            r.append(self._sqrt_wd * theta[:, self.decay_index])
            Js.append(Jd)
        return torch.cat(r, dim=1), torch.cat(Js, dim=1)

    def data_loss(self, theta: torch.Tensor) -> torch.Tensor:
        """Sum of squared data residuals per model, ``(K,)``, over chunks of samples."""
        chunks = self._chunks()
        if chunks == [None]:
            return super().data_loss(theta)
        total = theta.new_zeros(theta.shape[0])
        for sl in chunks:
            total = total + self._weighted_data(theta, sl).pow(2).sum(dim=1)
        return total

    def loss(self, theta: torch.Tensor) -> torch.Tensor:
        """Total loss per model, ``(K,)``."""
        if self._chunks() == [None]:
            return self.residuals(theta).pow(2).sum(dim=1)
        total = self.data_loss(theta)
        for i in self.penalised:
            total = total + self._sym_residual(theta, i).pow(2).sum(dim=1)
        if self.decay_index is not None:
            total = total + (self._sqrt_wd * theta[:, self.decay_index]).pow(2).sum(dim=1)
        return total

    def sample_subset(self, idx: torch.Tensor) -> BatchedProblem:
        """The same problem on the samples ``idx`` ``(K, n)`` (each model its own) only, each model's
        used samples reweighted to a mean over the subset (the first stage of a fit on a long
        record, see ``_long_record``)."""
        take = lambda a: torch.gather(a, 1, idx)  # noqa: E731
        used = (take(self.weights) > 0).to(self.y.dtype)
        w = used / used.sum(dim=1, keepdim=True).clamp_min(1.0).sqrt()
        terms = [CurveTerm(t.curve, take(t.u), None if t.multiplier is None else take(t.multiplier),
                           t.sym_points) for t in self.terms]
        return BatchedProblem(terms, take(self.y), take(self.F), w, free_gain=self.free_gain,
                              gain=self.gain, gain_on=self.gain_on, bias=self.bias, lambda_sym=self.lambda_sym,
                              weight_decay=self.weight_decay, bayesian=self.bayesian,
                              decay_groups=self.decay_groups)


