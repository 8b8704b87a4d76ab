"""MacKay's evidence for the Levenberg-Marquardt loop of :mod:`._train`: the Bayesian regularisation's
decay re-estimates (Foresee & Hagan), its start, and the sweeps that settle the relevance decays of
single coefficients on the linearised problem (output error)."""

from __future__ import annotations

import torch

__all__ = ["evidence_update", "initial_decay", "with_decay", "set_evidence", "decay_moves", "EvidenceSweeps",
           "EVIDENCE_SETTLED", "EVIDENCE_GUARD", "SWEEP_TOL"]


def evidence_update(problem, theta, JtJ, data_cost):
    """MacKay's evidence approximation (Foresee & Hagan's Bayesian regularisation for LM).

    With E_D the raw sum of squared data residuals over N samples and E_W the squared norm of the
    network weights, the most probable hyperparameters satisfy alpha = gamma / (2 E_W) and
    beta = (N - gamma) / (2 E_D), where gamma = P_w - 2 alpha tr_w(H^-1) is the effective number
    of weights and H = 2 beta J_D^T J_D + 2 alpha I_w the Gauss-Newton Hessian. In the loss
    ||r||^2 + lambda ||w||^2 (r scaled by 1/sqrt(N)) this is lambda = alpha / (beta N).
    ``JtJ`` (decay rows included) and ``data_cost`` (the data rows' sum of squares) are those LM
    already has at ``theta``.
    """
    K, P, _ = JtJ.shape
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
    E_D = data_cost * n_used
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


def initial_decay(problem, theta, shape):
    """The evidence iterations start from a decay of 1e-8 or, in problems that ask for it (output
    error), less where the weights are large against the data misfit (coefficients of physical size,
    e.g. 6e5 V^-2 on the Silverbox): there a fixed start would make the prior outweigh the data on
    the first step and drag the fit away."""
    lam = torch.full(shape, 1e-8, dtype=theta.dtype, device=theta.device)
    if problem.decay_index is None or not problem.scaled_initial_decay:
        return lam
    problem.set_weight_decay(torch.zeros(shape, dtype=theta.dtype, device=theta.device))
    with torch.no_grad():
        data = problem.data_loss(theta)  # (K,)
    G = problem.n_decay_groups
    masks = torch.zeros(G, theta.shape[1], dtype=theta.dtype, device=theta.device)
    masks[problem.decay_group, problem.decay_index] = 1.0
    E_W = (theta.pow(2) @ masks.T).clamp_min(1e-300)  # (K, G)
    cap = 1e-6 * data.view(-1, 1) / E_W
    cap = torch.where(torch.isfinite(cap), cap, torch.full_like(cap, 1e-8))
    lam_g = torch.minimum(torch.full_like(cap, 1e-8), cap)
    return lam_g.min(dim=1).values if len(shape) == 1 else lam_g


def with_decay(problem, theta, normal):
    """The normal equations with the weight decay's rows added: ``(JtJ, Jtr, cost)``."""
    JtJ, g, cost, _ = normal
    if problem.decay_index is None:
        return JtJ, g, cost
    idx = problem.decay_index
    w2, cost_d = problem.decay_terms(theta)
    JtJ = JtJ.clone()
    JtJ[:, idx, idx] += w2
    g = g.clone()
    g[:, idx] += w2 * theta[:, idx]
    return JtJ, g, cost + cost_d


#: A model whose accepted step lowered its loss by less than this (relative) has fitted its data:
#: from then on its evidence is iterated to the fixed point on the linearised problem (``evidence_sweeps``).
EVIDENCE_SETTLED = 0.05


def set_evidence(problem, theta, JtJ, data_cost, rows, groups=None) -> torch.Tensor:
    """One evidence update (:func:`evidence_update` at ``theta``) applied to the decay of the models
    in ``rows`` (``(K,)`` bool); with ``groups`` (``(G,)`` bool) only to those decay groups, and the
    other entries keep their decay and effective parameters. Returns the largest change of an
    updated decay's logarithm per model."""
    K = theta.shape[0]
    gamma_old = problem.gamma
    lam_new, _ = evidence_update(problem, theta, JtJ, data_cost)
    lam_old = torch.as_tensor(problem.weight_decay, device=theta.device).expand_as(lam_new)
    sel = rows.view(K, *([1] * (lam_new.dim() - 1)))
    if groups is not None:
        sel = sel & (groups if lam_new.dim() == 2 else groups[0])
        if gamma_old is not None:
            keep = rows.view(K, 1) & groups.view(1, -1)
            problem.gamma = torch.where(keep, problem.gamma, gamma_old)
    lam = torch.where(sel, lam_new, lam_old)
    problem.set_weight_decay(lam)
    return decay_moves(lam, lam_old, K, sel)


def decay_moves(lam, lam_old, K: int, where=None) -> torch.Tensor:
    """The largest change of a decay's logarithm per model, ``(K,)``, from ``lam_old`` to ``lam``
    (only the entries in ``where`` when given)."""
    lam_old = torch.as_tensor(lam_old, dtype=lam.dtype, device=lam.device).expand_as(lam)
    change = (lam.clamp_min(1e-300).log() - lam_old.clamp_min(1e-300).log()).abs()
    if where is not None:
        change = torch.where(where, change, 0.0)
    return change.reshape(K, -1).max(dim=1).values


#: The sweeps stop once no decay's logarithm moves by more than this: the decays are known to about
#: 1 %, and a Levenberg-Marquardt step that moves none by more counts as leaving them at their fixed point.
SWEEP_TOL = 1e-2


#: A step after evidence sweeps that raises a model's data loss by more than this (relative) undoes
#: them: the model returns to where they were made and keeps one evidence update per step.
EVIDENCE_GUARD = 0.25


class EvidenceSweeps:
    """The evidence sweeps of :func:`._train._levenberg_marquardt` (``evidence_sweeps`` > 0).

    MacKay's update moves the decay of a coefficient the record does not support up by a bounded
    factor, one update per Levenberg-Marquardt step: pruning a polynomial's spare terms took some 20
    steps (one free run each in output error) after the record was fitted. Here, for a model whose
    accepted step lowered its loss by less than ``EVIDENCE_SETTLED``, the relevance decays of single
    coefficients (a polynomial's, a library's or a closed form's; the problem's ``relevance_groups``)
    are iterated to their fixed point on the problem linearised at the step (each sweep solves the
    Gauss-Newton normal equations under the current decays, reusing them: no new free run, and
    re-estimates those decays at that solution; until none moves by ``SWEEP_TOL`` (1 %) or ``n`` sweeps). Network
    weight groups keep one update per step: swept, they settled at decays that held two-DOF and van
    der Pol fits far from the record. A fixed point of the linearised problem can be far from the
    nonlinear one (correlated terms, such as radial basis functions, all pruned at once): when the
    next step raises the data loss by more than ``EVIDENCE_GUARD``, the model goes back to the point
    and decays of the sweeps and takes no more of them.
    """

    def __init__(self, theta, n: int):
        K = theta.shape[0]
        self.n = int(n)
        self.ref = torch.full((K,), float("nan"), dtype=theta.dtype, device=theta.device)
        self.off = torch.zeros(K, dtype=torch.bool, device=theta.device)
        self.saved: tuple | None = None

    def guard(self, problem, theta, normal, moved):
        """Undo the sweeps of the models whose accepted step raised the data loss too much:
        ``(theta, normal equations, undone rows)``. An undone model is back at the point, decays and
        effective parameters of its sweeps (the step's own evidence update included), which costs one
        free run of the batch (the normal equations at the restored point)."""
        bad = moved & torch.isfinite(self.ref) & (normal[3] > self.ref * (1 + EVIDENCE_GUARD))
        if not bool(bad.any()) or self.saved is None:
            return theta, normal, bad
        theta0, lam0, gamma0 = self.saved
        K = theta.shape[0]
        theta = torch.where(bad.view(K, 1), theta0, theta)
        lam = torch.as_tensor(problem.weight_decay, device=theta.device)
        problem.set_weight_decay(torch.where(bad.view(K, *([1] * (lam.dim() - 1))), lam0, lam))
        if gamma0 is not None:
            problem.gamma = torch.where(bad.view(K, 1), gamma0, problem.gamma)
        self.off |= bad
        self.ref = torch.where(bad, torch.full_like(self.ref, float("nan")), self.ref)
        return theta, problem.normal_equations(theta), bad

    def settle(self, problem, theta, normal, rows):
        """Sweep the models in ``rows`` (not those whose sweeps were undone); the normal equations
        with the new decays."""
        rows = rows & ~self.off
        relevance = getattr(problem, "relevance_groups", None)
        if problem.decay_group is not None and relevance is not None and bool(relevance.any()) and bool(rows.any()):
            K = theta.shape[0]
            lam = torch.as_tensor(problem.weight_decay, device=theta.device).clone()
            gamma = problem.gamma.clone() if problem.gamma is not None else None
            JtJ, g, _ = with_decay(problem, theta, normal)
            P = theta.shape[1]
            eye = torch.eye(P, dtype=theta.dtype, device=theta.device)
            swept = torch.zeros_like(rows)  # the models whose decays the sweeps moved
            for _ in range(self.n):
                if not bool(rows.any()):
                    break
                L, info = torch.linalg.cholesky_ex(JtJ + 1e-12 * eye)
                star = theta - torch.cholesky_solve(g.unsqueeze(-1), L).squeeze(-1)
                rows = rows & (info == 0)
                change = set_evidence(problem, star, JtJ, normal[3], rows, relevance)
                JtJ, g, _ = with_decay(problem, theta, normal)
                swept = swept | (rows & (change > 0))
                rows = rows & (change > SWEEP_TOL)
            # what the guard restores: the point, decays and effective parameters before these sweeps
            sel, lsel = swept.view(K, 1), swept.view(K, *([1] * (lam.dim() - 1)))
            if self.saved is None:
                self.saved = (theta.clone(), lam, gamma)
            else:
                t0, l0, g0 = self.saved
                self.saved = (torch.where(sel, theta, t0), torch.where(lsel, lam, l0),
                              torch.where(sel, gamma, g0) if gamma is not None and g0 is not None else gamma)
            self.ref = torch.where(swept, normal[3], self.ref)
        return with_decay(problem, theta, normal)
