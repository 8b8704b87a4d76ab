"""One training loop for every neural-curve model: batched Adam, then batched Levenberg-Marquardt.

The problem is linear in the curves: for each model k (of K trained together) and sample n,

    r[k, n] = w[k, n] * ( y[k, n] + sum_i m_i[k, n] * f_i(u_i[k, n]) + b[k] - g[k] * F[k, n] )

with ``y`` the known part of the equation (x''), ``m_i`` per-sample multipliers (1 for the
separable family), an optional constant ``b`` and gain ``g``. The symmetry penalty, when used,
adds residuals sqrt(lambda / N_sym) * (f_i(z) -+ f_i(-z)). The loss is the sum of squares, so
``w = 1/sqrt(N)`` gives the paper's mean-squared error.

Models never interact: Adam is elementwise and LM solves one small system per model, so K
models trained together equal K models trained one by one.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence

import torch

from ..curves._neural import NeuralCurve

__all__ = ["CurveTerm", "BatchedProblem", "train"]

DECAY_GROUPS = ("shared", "per-curve", "per-layer")


@dataclasses.dataclass
class CurveTerm:
    """One curve of the equation: its settings and its (scaled) argument per model."""

    curve: NeuralCurve
    u: torch.Tensor  # (K, N) scaled arguments
    multiplier: torch.Tensor | None = None  # (K, N)
    sym_points: torch.Tensor | None = None  # (K, N_sym) scaled points for the penalty

    def __post_init__(self) -> None:
        # exact-symmetry curves evaluate h(u) and h(-u) together; build that input once
        self.u_both = torch.cat([self.u, -self.u], dim=1) if self.curve.exact_symmetry != "none" else None


@dataclasses.dataclass
class BatchedProblem:
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
        decay = torch.zeros(o, dtype=torch.bool)
        for i, term in enumerate(self.terms):
            sl = term.curve.slices()["mlp"]
            decay[self.offsets[i] + sl.start : self.offsets[i] + sl.stop] = True
        use_decay = self.bayesian or (float(torch.as_tensor(self.weight_decay).max()) > 0)
        self.decay_index = torch.nonzero(decay).flatten().to(self.y.device) if use_decay else None
        if self.decay_groups not in DECAY_GROUPS:
            raise ValueError(f"decay_groups must be one of {', '.join(DECAY_GROUPS)}, got {self.decay_groups!r}")
        group = torch.zeros(o, dtype=torch.long)
        # each group as (term index or None for all terms, what part of that term's network)
        self.decay_group_parts: list[tuple[int | None, str]] = [(None, "")]
        if self.decay_groups == "per-curve":
            for i, term in enumerate(self.terms):
                sl = term.curve.slices()["mlp"]
                group[self.offsets[i] + sl.start : self.offsets[i] + sl.stop] = i
            self.decay_group_parts = [(i, "") for i in range(len(self.terms))]
        elif self.decay_groups == "per-layer":
            # MacKay's groups: each layer's weights and its biases, per curve (they act on
            # different scales, so one decay for all of them over- or under-damps some)
            self.decay_group_parts = []
            for i, term in enumerate(self.terms):
                start = self.offsets[i] + term.curve.slices()["mlp"].start
                for layer, (fan_in, fan_out) in enumerate(term.curve.mlp.layers, start=1):
                    for kind, size in (("weights", fan_in * fan_out), ("biases", fan_out)):
                        group[start : start + size] = len(self.decay_group_parts)
                        self.decay_group_parts.append((i, f"layer {layer} {kind}"))
                        start += size
        self.n_decay_groups = len(self.decay_group_parts)
        self.decay_group = group[decay].to(self.y.device) if use_decay else None  # (m,) group of each decayed weight
        self.set_weight_decay(self.weight_decay)
        self.n_used = (self.weights > 0).sum(dim=1).to(self.y.dtype)
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

    def refresh_decay_rows(self, theta: torch.Tensor, r: torch.Tensor, J: torch.Tensor) -> None:
        """Update, in place, the residual and Jacobian rows of the weight decay (the last rows)."""
        idx = self.decay_index
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
            return theta[:, self.gain_index : self.gain_index + 1]
        return torch.full((theta.shape[0], 1), float(self.gain), dtype=theta.dtype, device=theta.device)

    def bias_of(self, theta: torch.Tensor) -> torch.Tensor:
        if self.bias:
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
        J = [self.weights.unsqueeze(-1) * J]
        for i in self.penalised:
            term = self.terms[i]
            z = term.sym_points
            n = z.shape[1]
            f, Ji = term.curve.evaluate_jacobian(self.block(theta, i), torch.cat([z, -z], dim=1))
            s = -1.0 if term.curve.symmetry == "odd" else 1.0
            c = math.sqrt(self.lambda_sym / n)
            Jp = theta.new_zeros(K, n, self.n_params)
            o = self.offsets[i]
            Jp[:, :, o : o + term.curve.n_params] = c * (Ji[:, :n] - s * Ji[:, n:])
            r.append(c * (f[:, :n] - s * f[:, n:]))
            J.append(Jp)
        if self.decay_index is not None:
            m = self.decay_index.numel()
            Jd = theta.new_zeros(K, m, self.n_params)
            Jd[:, torch.arange(m, device=theta.device), self.decay_index] = (
                self._sqrt_wd.expand(K, m) if self._sqrt_wd.dim() else self._sqrt_wd)
            r.append(self._sqrt_wd * theta[:, self.decay_index])
            J.append(Jd)
        return torch.cat(r, dim=1), torch.cat(J, dim=1)

    def loss(self, theta: torch.Tensor) -> torch.Tensor:
        """Total loss per model, ``(K,)``."""
        return self.residuals(theta).pow(2).sum(dim=1)


@dataclasses.dataclass
class TrainingLog:
    adam_steps: int = 0
    lm_iterations: int = 0
    history: list = dataclasses.field(default_factory=list)  # (phase, step, mean loss)
    stopped_by: str = ""
    interrupted: bool = False
    effective_parameters: list = dataclasses.field(default_factory=list)


def _adam(problem, theta, steps, lr, stop_loss, log, progress, holder, check_every=100):
    theta = theta.clone().requires_grad_(True)
    opt = torch.optim.Adam([theta], lr=lr)
    done = torch.zeros(theta.shape[0], dtype=torch.bool, device=theta.device)
    # a model whose loss turns non-finite goes back to its last finite weights and stops there
    diverged = torch.zeros_like(done)
    last_good = theta.detach().clone()
    for step in range(steps):
        opt.zero_grad(set_to_none=True)
        per_model = problem.loss(theta)
        per_model.sum().backward()
        if step % check_every == 0 or step == steps - 1:
            with torch.no_grad():
                bad = ~torch.isfinite(per_model.detach())
                if bool(bad.any()):
                    diverged |= bad
                    theta[bad] = last_good[bad]
                last_good = theta.detach().clone()
                done = (per_model.detach() < stop_loss) | diverged
            log.history.append(("adam", step, float(per_model.detach()[~diverged].mean())))
            holder["theta"] = last_good
            if progress is not None:
                progress("adam", step, steps, float(per_model.detach().mean()))
            if bool(done.all()):
                log.stopped_by = "stop_loss"
                break
        if done.any():
            # models already below the stop loss keep their weights (as separate runs would):
            # Adam's momentum would still move them, so restore them after the step
            frozen = theta.detach()[done].clone()
            opt.step()
            with torch.no_grad():
                theta[done] = frozen
        else:
            opt.step()
        log.adam_steps = step + 1
    holder["theta"] = theta.detach()
    return theta.detach()


def _evidence_update(problem, theta, JtJ, r):
    """MacKay's evidence approximation (Foresee & Hagan's Bayesian regularisation for LM).

    With E_D the raw sum of squared data residuals over N samples and E_W the squared norm of the
    network weights, the most probable hyperparameters satisfy alpha = gamma / (2 E_W) and
    beta = (N - gamma) / (2 E_D), where gamma = P_w - 2 alpha tr_w(H^-1) is the effective number
    of weights and H = 2 beta J_D^T J_D + 2 alpha I_w the Gauss-Newton Hessian. In the loss
    ||r||^2 + lambda ||w||^2 (r scaled by 1/sqrt(N)) this is lambda = alpha / (beta N).
    ``JtJ`` and ``r`` are those LM already has at ``theta`` (decay rows included).
    """
    K, P, _ = JtJ.shape
    N = problem.y.shape[1]
    n_used = problem.n_used
    idx = problem.decay_index
    G = problem.n_decay_groups
    lam = problem.decay_per_group(K).to(theta.dtype)  # (K, G)
    masks = torch.zeros(G, P, dtype=theta.dtype, device=theta.device)
    masks[problem.decay_group, idx] = 1.0
    m_g = masks.sum(1)  # (G,) weights per group
    lam_param = lam @ masks  # (K, P)
    # data part of J^T J (in raw units): remove the decay rows' lambda * I_w, undo the 1/sqrt(N) scaling
    JtJ_data = (JtJ - torch.diag_embed(lam_param)) * n_used.view(K, 1, 1)
    E_D = r[:, :N].pow(2).sum(1) * n_used
    E_W = (theta.pow(2) @ masks.T).clamp_min(1e-12)  # (K, G)
    gamma_prev = problem.gamma if problem.gamma is not None else m_g.expand(K, G)
    beta = ((n_used - gamma_prev.sum(1)) / (2 * E_D)).clamp_min(1e-12)
    alpha = lam * (beta * n_used).view(K, 1)  # (K, G)
    H = 2 * beta.view(K, 1, 1) * JtJ_data + torch.diag_embed(2 * (alpha @ masks) + 1e-10)
    L, info = torch.linalg.cholesky_ex(H)
    ok = info == 0  # a model whose Hessian is not positive definite keeps its decay this step
    L = torch.where(ok.view(K, 1, 1), L, torch.eye(P, dtype=L.dtype, device=L.device).expand(K, P, P))
    Hinv_diag = torch.diagonal(torch.cholesky_inverse(L), dim1=1, dim2=2)
    tr_w = Hinv_diag @ masks.T  # (K, G)
    gamma = torch.minimum((m_g - 2 * alpha * tr_w).clamp_min(1.0), m_g)
    gamma = torch.where(ok.view(K, 1), gamma, gamma_prev)
    problem.gamma = gamma
    alpha_new = gamma / (2 * E_W)
    beta_new = ((n_used - gamma.sum(1)) / (2 * E_D)).clamp_min(1e-12)
    lam_new = torch.where(ok.view(K, 1), alpha_new / (beta_new * n_used).view(K, 1), lam)
    if problem.weight_decay.dim() < 2 and G == 1:
        lam_new = lam_new[:, 0]  # keep the caller's (K,) layout
    return lam_new, gamma.sum(1)


def _levenberg_marquardt(problem, theta, max_iter, tol, stop_loss, log, progress, holder):
    K, P = theta.shape
    if problem.bayesian:
        shape = (K,) if problem.n_decay_groups == 1 else (K, problem.n_decay_groups)
        problem.set_weight_decay(torch.full(shape, 1e-8, dtype=theta.dtype, device=theta.device))
    r, J = problem.residuals_jacobian(theta)
    cost = r.pow(2).sum(1)
    mu = torch.full((K,), 1e-3, dtype=theta.dtype, device=theta.device)
    active = cost > stop_loss
    stalls = torch.zeros(K, dtype=torch.long, device=theta.device)
    eye = torch.eye(P, dtype=theta.dtype, device=theta.device)
    for it in range(max_iter):
        if not bool(active.any()):
            break
        JtJ = J.transpose(1, 2) @ J
        g = (J.transpose(1, 2) @ r.unsqueeze(-1)).squeeze(-1)
        diag = torch.diagonal(JtJ, dim1=1, dim2=2)
        # Marquardt scaling with a floor so directions the data do not see stay damped
        scale = diag + 1e-9 * diag.max(dim=1, keepdim=True).values + 1e-12
        A = JtJ + (mu.unsqueeze(-1) * scale).unsqueeze(-1) * eye
        L, info = torch.linalg.cholesky_ex(A)
        step = -torch.cholesky_solve(g.unsqueeze(-1), L).squeeze(-1)
        ok_solve = info == 0
        step = torch.where(ok_solve.unsqueeze(-1) & active.unsqueeze(-1), step, torch.zeros_like(step))
        trial = theta + step
        r_new = problem.residuals(trial)
        cost_new = r_new.pow(2).sum(1)
        accept = active & ok_solve & torch.isfinite(cost_new) & (cost_new < cost)
        rel = torch.where(accept, (cost - cost_new) / cost.clamp_min(1e-300), torch.zeros_like(cost))
        theta = torch.where(accept.unsqueeze(-1), trial, theta)
        cost = torch.where(accept, cost_new, cost)
        if bool(accept.any()):
            # the Jacobian only changes where a step was taken: recompute it once, at the new point
            r, J = problem.residuals_jacobian(theta)
        holder["theta"] = theta
        mu = torch.where(accept, (mu / 3).clamp_min(1e-12), (mu * 4).clamp_max(1e12))
        stalls = torch.where(accept & (rel < tol), stalls + 1, torch.where(accept, 0, stalls))
        if problem.bayesian and bool(accept.any()):
            # re-estimate the decay of the models that moved; the objective changes with it,
            # so the decay rows of the residuals and Jacobian are refreshed under the new value
            lam_new, gamma = _evidence_update(problem, theta, J.transpose(1, 2) @ J, r)
            lam_old = torch.as_tensor(problem.weight_decay, device=theta.device).expand_as(lam_new)
            moved = (accept & active).view(K, *([1] * (lam_new.dim() - 1)))
            problem.set_weight_decay(torch.where(moved, lam_new, lam_old))
            problem.refresh_decay_rows(theta, r, J)  # only the decay rows depend on the decay
            cost = r.pow(2).sum(1)
            log.effective_parameters = gamma.tolist()
        finished = (stalls >= 3) | (mu >= 1e12) | (cost < stop_loss)
        active = active & ~finished
        log.lm_iterations = it + 1
        if it % 10 == 0:
            log.history.append(("lm", it, float(cost.mean())))
            if progress is not None:
                progress("lm", it, max_iter, float(cost.mean()))
    log.stopped_by = log.stopped_by or ("stall" if not bool(active.any()) else "max_iter")
    return theta


def train(
    problem: BatchedProblem,
    theta0: torch.Tensor,
    *,
    adam_steps: int,
    adam_lr: float,
    lm_max_iter: int,
    lm_tol: float,
    stop_loss: float,
    progress: Callable | None = None,
) -> tuple[torch.Tensor, TrainingLog]:
    """Train ``theta0`` (``(K, P)``) on ``problem``; Ctrl-C keeps the best weights so far."""
    log = TrainingLog()
    holder = {"theta": theta0}
    try:
        if adam_steps > 0:
            _adam(problem, holder["theta"], adam_steps, adam_lr, stop_loss, log, progress, holder)
        if lm_max_iter > 0:
            with torch.no_grad():
                _levenberg_marquardt(
                    problem, holder["theta"], lm_max_iter, lm_tol, stop_loss, log, progress, holder
                )
    except KeyboardInterrupt:
        log.interrupted = True
        log.stopped_by = "interrupted"
    return holder["theta"].detach(), log
