"""The Laplace posterior of a gradient-trained fit (NN-CC, NN-CC+sym, any mix of curves trained by
:func:`._gradient_fit.fit_gradient`; equation error).

At the optimum ``theta`` of the loss ``sum_t r_t^2 + theta^T Lambda theta`` (the residuals weighted
by ``1/sqrt(N)``, ``Lambda`` the evidence's per-layer decays on the decayed weights), the
posterior of the weights is Gaussian around ``theta`` with precision ``H = J^T J + Lambda`` (the
Gauss-Newton matrix of the objective that ran, the soft symmetry penalty's rows included in
``J^T J``). Its covariance is

* ``"gauss"``: ``s^2 H^-1`` (MacKay's), ``s^2 = RSS_w / (N - gamma)`` with ``gamma = tr(H^-1 J^T J)``
  the evidence's effective number of parameters;
* ``"hac"`` (the default): ``H^-1 (S + s^2 (H - J^T J)) H^-1``, where ``S`` is the Newey-West sum
  of the lagged products of the scores ``j_t r_t`` (Bartlett weights, Andrews' bandwidth, as in
  :mod:`._posterior_linear`) times ``N / (N - gamma)``. On white residuals ``S = s^2 J^T J`` and the
  two agree; residuals correlated by a smoothing differentiator widen it.

Every reported quantity (a curve's value at ``z`` after the template's gauge, the gain, the free
constants and scalars) is a function of the weights; its variance is propagated through that
function's exact Jacobian (the curves' own ``evaluate_jacobian``), which includes the gain's division of the
curves (force side) and the gauge's shifts (a curve anchored at 0 has a zero-width band there).

A fit that averages several starts (``combine="mean"``) is reported as the mixture of its members'
posteriors: the variance of each quantity is the mean of its members' variances plus the spread of
the members' own values (the optimisation's share of the uncertainty). Directions of ``H`` the
record does not determine give infinite variance to what loads on them, and a warning names the
curve or scalar; a precision whose (Jacobi-scaled) condition number exceeds
:data:`ILL_CONDITIONED` gives a warning naming the weights of its weakest direction.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from ._posterior_linear import COVARIANCE_KINDS, bartlett_sum, hac_bandwidth
from ._posterior_map import EquationErrorMap

__all__ = ["NetworkPosterior", "EquationErrorMap", "network_posteriors", "laplace_posterior", "attach_posterior",
           "gauge_map"]

#: Jacobi-scaled precision whose condition number exceeds this: a warning naming its weakest direction.
ILL_CONDITIONED = 1e12
#: eigenvalues of the scaled precision below this times the largest are directions the record does not determine
UNIDENTIFIED = 1e-14


class NetworkPosterior:
    """The Laplace posterior of a gradient-trained fit; built by :func:`network_posteriors` and kept
    as ``model.posterior`` (see :meth:`charcurves.FittedModel.curve_band`).

    It has the interface of :class:`LinearPosterior` that :mod:`charcurves.model` uses:
    ``curve_sd``, ``scalar_stats``, ``check_against``, ``warnings``, ``with_kind`` and the attributes
    ``kind``, ``bandwidth``, ``noise_variance`` (in the equation's units, the members' mean),
    ``condition_number`` (the worst member's) and ``effective_parameters``.

    Examples
    --------
    >>> import numpy as np
    >>> import charcurves as cc
    >>> from charcurves.systems import get_system
    >>> record = cc.corrupt(get_system("duffing").simulate(t_end=20.0, n_points=400), 20, seed=0)
    >>> model = cc.fit(record, method="nn-cc", random_state=0)
    >>> value, sd = model.posterior.curve_sd("f2", np.array([0.0, 1.0]))
    >>> float(sd[0]), bool(sd[1] > 0), model.posterior.kind   # f2(0) = 0 is the gauge: no width there
    (0.0, True, 'hac')
    """

    def __init__(self, *, mapping, thetas: torch.Tensor, factors: dict, unidentified: list,
                 noise_variance: float, bandwidth: int, condition_number: float, effective_parameters: float,
                 weak: list, kind: str = "hac", label: str | None = None):
        self.mapping, self._thetas, self._factors = mapping, thetas, factors
        self._unidentified, self._weak = unidentified, weak
        self.kind = kind
        self.noise_variance, self.bandwidth = float(noise_variance), int(bandwidth)
        self.condition_number, self.effective_parameters = float(condition_number), float(effective_parameters)
        self.template = mapping.template
        if label is not None:
            self.label = label

    #: ``result.json`` ``uncertainty`` ``method``
    label = "laplace (gauss-newton, evidence decays)"

    def with_kind(self, kind: str) -> NetworkPosterior:
        """The same fit's posterior with the covariance ``kind`` (both are computed at the fit)."""
        import copy

        if kind not in COVARIANCE_KINDS:
            from .._errors import ConfigError

            raise ConfigError(f"unknown posterior covariance {kind!r}; choose one of {', '.join(COVARIANCE_KINDS)}")
        new = copy.copy(self)
        new.kind = kind
        return new

    def _moments(self, grids: dict, factor: bool = False):
        """``(value, variance, covariance of the scalars)`` of every reported quantity (the mixture of
        the members' Gaussians; see the module docstring); with ``factor``, also ``G`` whose ``G G^T``
        is the mixture's covariance of all of them (the members' factors and spreads side by side)."""
        Th = self._thetas
        with torch.no_grad():
            center = self.mapping.report(Th, grids).numpy()
        ns = len(self.mapping.scalar_names())
        var = np.zeros(center.size)
        cov_s = np.zeros((ns, ns))
        singles, blocks = [], []
        for m in range(Th.shape[0]):
            with np.errstate(all="ignore"):
                one, J = self.mapping.report_jacobian(Th[m], grids)
            singles.append(one)
            JR = J @ self._factors[self.kind][m]
            v = np.sum(JR**2, axis=1)
            U = self._unidentified[m]
            if len(U):
                load = np.abs(J @ U.T).max(axis=1)
                scale = np.abs(J).max(axis=1) * np.abs(U).max() + 1e-300
                v = np.where(load > 1e-6 * scale, np.inf, v)
            var += v
            if factor:
                blocks.append(JR)
            if ns:
                cov_s += JR[-ns:] @ JR[-ns:].T
        M = Th.shape[0]
        one = np.stack(singles)
        var = var / M + one.var(axis=0)
        if ns:
            d = one[:, -ns:] - one[:, -ns:].mean(axis=0)
            cov_s = cov_s / M + d.T @ d / M
        if factor:
            G = np.concatenate([*blocks, (one - one.mean(axis=0)).T], axis=1) / np.sqrt(M)
            return center, var, cov_s, G
        return center, var, cov_s

    def simultaneous_factor(self, grids: dict, level: float = 0.95, draws: int = 4000) -> float:
        """The multiplier ``c`` of the pointwise sd such that the band ``value +- c sd`` holds all of
        ``grids`` (curve name -> points) at once with probability ``level`` under the posterior (the
        sup-t band: the ``level`` quantile of ``max |delta| / sd`` over Gaussian draws, seeded);
        ``inf`` where a point has infinite variance.

        Examples
        --------
        >>> import numpy as np
        >>> import charcurves as cc
        >>> from charcurves.systems import get_system
        >>> record = cc.corrupt(get_system("duffing").simulate(t_end=20.0, n_points=400), 20, seed=0)
        >>> post = cc.fit(record, method="nn-cc", random_state=0).posterior
        >>> c = post.simultaneous_factor({"f1": np.linspace(-1, 1, 50)})
        >>> bool(1.96 < c < 3.5)  # wider than the pointwise 95 % band, narrower than Bonferroni's
        True
        """
        from ..model import sup_t_factor

        _, var, _, G = self._moments({k: np.asarray(v, dtype=float).reshape(-1) for k, v in grids.items()},
                                     factor=True)
        n = sum(np.asarray(v).size for v in grids.values())
        return sup_t_factor(G[:n], var[:n], level, draws)

    # ------------------------------------------------------------------ what users ask for
    def curve_sd(self, name: str, z) -> tuple[np.ndarray, np.ndarray]:
        """``(value, sd)`` of curve ``name`` at ``z`` (the gauge-fixed curve the model reports)."""
        z = np.asarray(z, dtype=float)
        center, var, _ = self._moments({name: z.reshape(-1)})
        n = z.size
        return center[:n].reshape(z.shape), np.sqrt(np.clip(var[:n], 0.0, None)).reshape(z.shape)

    def curve_factor(self, name: str, z) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(value, G, infinite)`` of curve ``name`` at ``z``: the posterior of the values is ``value + G u``
        with ``u`` standard normal and shared by every curve and scalar (the members' factors and spreads
        side by side, as in :meth:`simultaneous_factor`), so a saved posterior keeps the correlations."""
        z = np.asarray(z, dtype=float).reshape(-1)
        center, var, _, G = self._moments({name: z}, factor=True)
        n = z.size
        return center[:n], np.nan_to_num(G[:n]), ~np.isfinite(var[:n])

    def scalar_factor(self) -> tuple[list, np.ndarray, np.ndarray, np.ndarray]:
        """``(names, mean, G, infinite)`` of the learned scalars, in the layout of :meth:`curve_factor`."""
        names = self.mapping.scalar_names()
        center, var, _, G = self._moments({}, factor=True)
        return list(names), center, np.nan_to_num(G), ~np.isfinite(var)

    def scalar_stats(self) -> dict[str, Any]:
        """Mean, sd and correlations of the gain, the free constants and the scalars (those the fit learned)."""
        names = self.mapping.scalar_names()
        if not names:
            return {"names": [], "mean": {}, "sd": {}, "correlation": []}
        center, var, cov = self._moments({})
        sd = np.sqrt(np.clip(var, 0.0, None))
        with np.errstate(all="ignore"):
            corr = cov / np.outer(np.sqrt(np.diag(cov)), np.sqrt(np.diag(cov)))
        corr = np.where(np.isfinite(corr), corr, np.nan)
        return {"names": names, "mean": dict(zip(names, center.tolist())), "sd": dict(zip(names, sd.tolist())),
                "correlation": corr.tolist()}

    def check_against(self, model, *, rtol: float = 1e-7) -> bool:
        """Whether the model still has the curves this posterior describes (an output-error refinement,
        a post-SR distillation or a loaded model replace them)."""
        grids = {}
        for nm, curve in model.curves.items():
            lo, hi = curve.domain
            grids[nm] = np.linspace(lo, hi, 5)
        with torch.no_grad():
            mine = self.mapping.report(self._thetas, grids).numpy()
        o = 0
        for nm, curve in model.curves.items():
            ref = np.asarray(curve(grids[nm]), dtype=float)
            if not np.allclose(mine[o:o + 5], ref, rtol=rtol, atol=rtol * (np.max(np.abs(ref)) + 1e-300)):
                return False
            o += 5
        return True

    def warnings(self) -> list[str]:
        """One line per problem: a direction of the weights the record does not or barely determines."""
        out = []
        for what, owners in self._weak:
            out.append(f"uncertainty: the record {what} a combination of the weights of {owners} (condition number "
                       f"{self.condition_number:.3g}); what depends on it has wide or infinite bands: excite the "
                       "curve over a wider range, simplify it or fix a gauge")
        return out


def gauge_map(template, names: list, off_keys: list, pinned: dict):
    """The template's gauge (:meth:`normalise`) as the linear map it is: ``(names, off_keys, new_keys, S, O)``
    with the curves' shifts ``S @ inputs`` and the new offsets ``O @ inputs``, ``inputs`` the curves'
    values at 0 and the offsets ``off_keys``.

    Examples
    --------
    >>> from charcurves.templates import get_template
    >>> from charcurves.train import gauge_map
    >>> names, offs, keys, S, O = gauge_map(get_template(), ["f1", "f2"], [0], {"f1": True, "f2": False})
    >>> S.tolist(), keys, O.tolist()  # f1 is odd: f2(0) moves to the free constant b
    ([[0.0, 0.0, 0.0], [0.0, -1.0, 0.0]], [0], [[0.0, 1.0, 1.0]])
    """
    columns = []
    for j in range(len(names) + len(off_keys)):
        raw0 = {nm: float(j == i) for i, nm in enumerate(names)}
        o = {e: float(j == len(names) + i) for i, e in enumerate(off_keys)}
        columns.append(template.normalise(raw0, pinned, o))
    keys = sorted({e for _, new_off in columns for e in new_off} | ({0} if 0 in off_keys else set()))
    S = np.array([[c[0][nm] for c in columns] for nm in names], dtype=float).reshape(len(names), len(columns))
    O = np.array([[c[1].get(e, 0.0) for c in columns] for e in keys], dtype=float).reshape(len(keys), len(columns))
    return names, off_keys, keys, S, O


def _owner_names(problem, names: list, const_names: list) -> list[str]:
    """What each weight belongs to: a curve's name, "the gain", "the free constant", a scalar's name."""
    out = ["?"] * problem.n_params
    for i, o in enumerate(problem.offsets):
        n = problem.terms[i].curve.n_params
        label = names[i] if i < len(names) else const_names[i - len(names)]
        out[o:o + n] = [label.removeprefix("const:")] * n
    if problem.gain_index is not None:
        out[problem.gain_index] = "the gain"
    if problem.bias_index is not None:
        out[problem.bias_index] = "the free constant"
    return out


def _member_factors(problem, theta: torch.Tensor, instants):
    """Per row of ``theta`` (a problem of those rows): the square-root factors of both covariances
    (weight space), the unidentified directions, the noise variance (weighted units), the HAC
    bandwidth, the Jacobi-scaled condition number, gamma and the weakest direction. ``instants``
    maps the data rows ``(rows, ...)`` to one row per instant of the record (summed), in time order.
    Frozen parameters (``problem.frozen``) are known: they carry no variance."""
    if hasattr(problem, "_data_rows"):  # equation error: the normal equations over chunks of samples
        JtJ_all, _, _, data_cost = problem.normal_equations(theta)
        r, J = problem._data_rows(theta)
    else:  # one Jacobian (output error: one free run with its sensitivities)
        r, J = problem.residuals_jacobian(theta)
        m = 0 if problem.decay_index is None else problem.decay_index.numel()
        Jp = J[:, :J.shape[1] - m]
        JtJ_all = Jp.transpose(1, 2) @ Jp
        r, J = r[:, :problem.n_data], J[:, :problem.n_data]
        data_cost = r.pow(2).sum(1)
    K, P = theta.shape
    prior = torch.zeros(K, P, P, dtype=theta.dtype)
    if problem.decay_index is not None:
        w2, _ = problem.decay_terms(theta)
        idx = problem.decay_index
        prior[:, idx, idx] = w2
    free = np.ones(P, dtype=bool) if problem.frozen is None else ~problem.frozen.cpu().numpy()
    out = []
    for m in range(K):
        Jm, rm = J[m].double().numpy()[:, free], r[m].double().numpy()
        Jd = Jm.T @ Jm
        # the decay, the soft symmetry penalty and continuity rows: the prior's share of H
        Pm = (prior[m].double().numpy() + JtJ_all[m].double().numpy())[np.ix_(free, free)] - Jd
        H = Jd + Pm
        d = np.sqrt(np.clip(np.diag(H), 0.0, None))
        d = np.where(d > 0, d, 1.0)
        Hs = H / np.outer(d, d)
        e, Q = np.linalg.eigh((Hs + Hs.T) / 2)
        emax = max(float(e[-1]), 1e-300)
        ok = e > UNIDENTIFIED * emax
        cond = float(emax / e[0]) if e[0] > 0 else float("inf")
        Vf = (Q[:, ok] / np.sqrt(e[ok])) / d[:, None]  # H^-1 = Vf Vf^T on the identified subspace
        Hinv = Vf @ Vf.T
        N_used = float(problem.n_used[m])
        gamma = float(np.sum(Hinv * Jd))
        dof = max(N_used - gamma, 1.0)
        s2 = float(data_cost[m]) / dof
        score = instants(Jm * rm[:, None])
        L = hac_bandwidth(instants(rm[:, None])[:, 0])
        Sh = bartlett_sum(score, L) * (N_used / dof) + s2 * Pm
        w, C = np.linalg.eigh((Sh + Sh.T) / 2)
        C = C * np.sqrt(np.clip(w, 0.0, None))
        factors = {"gauss": np.sqrt(s2) * Vf, "hac": Hinv @ C}
        unid = (Q[:, ~ok] / d[:, None]).T
        embed = lambda A: _embed(A, free, P)  # noqa: E731
        factors = {k: embed(f) for k, f in factors.items()}
        unid = embed(unid.T).T
        weak = None
        if (~ok).any():
            weak = ("does not determine", unid[0])
        elif cond > ILL_CONDITIONED:
            weak = ("barely determines", embed((Q[:, 0] / d)[:, None])[:, 0])
        out.append((factors, unid, s2, L, cond, gamma, weak))
    return out


def _embed(A: np.ndarray, free: np.ndarray, P: int) -> np.ndarray:
    """Rows of ``A`` (one per free parameter) placed among ``P`` parameters, zero for frozen ones."""
    out = np.zeros((P, A.shape[1]))
    out[free] = A
    return out


def laplace_posterior(problem, theta: torch.Tensor, mapping, owners: list, *, instants, noise_scale: float = 1.0,
                      label: str | None = None, report_theta: torch.Tensor | None = None) -> NetworkPosterior:
    """The :class:`NetworkPosterior` of the fit whose members are the rows ``theta`` of ``problem``
    (a problem of those rows, with their final weight decay): ``mapping`` gives the reported values
    and their Jacobians, ``owners`` names what each parameter belongs to (for the warnings),
    ``instants`` sums the data rows of one instant (see :func:`_member_factors`), ``noise_scale``
    turns the weighted residuals' variance into the equation's units; ``report_theta``: the rows the
    model reports where they differ from the trained ones in frozen columns only (a jump sharpened
    after training)."""
    with torch.no_grad():
        parts = _member_factors(problem, theta, instants)
    weak = []
    for *_, w in parts:
        if w is not None:
            v = np.abs(w[1])
            top = [owners[i] for i in np.argsort(-v)[:3] if v[i] > 0.1 * v.max()]
            weak.append((w[0], ", ".join(dict.fromkeys(top))))
    return NetworkPosterior(
        mapping=mapping, thetas=(theta if report_theta is None else report_theta).double(), factors={kk: [p[0][kk] for p in parts] for kk in COVARIANCE_KINDS},
        unidentified=[p[1] for p in parts], noise_variance=float(np.mean([p[2] for p in parts])) * noise_scale,
        bandwidth=max(p[3] for p in parts), condition_number=max(p[4] for p in parts),
        effective_parameters=float(np.mean([p[5] for p in parts])), weak=list(dict.fromkeys(weak)), label=label)


def attach_posterior(model, post: NetworkPosterior, seconds_since: float) -> None:
    """``model.posterior = post`` where it reproduces the model's curves (else a warning and none),
    with its seconds and warnings in ``model.info``."""
    import time

    if not post.check_against(model, rtol=1e-6):
        model.info.setdefault("warnings", []).append(
            "uncertainty: no posterior for this fit (its curves could not be reproduced from the weights)")
        return
    model.posterior = post
    model.info["posterior_seconds"] = time.perf_counter() - seconds_since
    if post.warnings():
        model.info.setdefault("warnings", []).extend(post.warnings())


#: Above these sizes a network fit gets no posterior (a note in ``info["posterior"]`` says why): the
#: dense Gauss-Newton matrix is parameters^2 and the Jacobian rows x parameters doubles (the default
#: preset's 8-unit networks have about 50 parameters per curve; the paper's 100-100-100 about 20 000).
MAX_DENSE_PARAMS = 3000
MAX_JACOBIAN_ENTRIES = 5e7


def network_posteriors(problem, theta: torch.Tensor, decay: torch.Tensor, ctx: dict, members: list,
                       models: list) -> None:
    """Attach a :class:`NetworkPosterior` to each of ``models`` (record ``k``: the rows
    ``members[k]`` of ``theta``, the fitted weights of the batched ``problem``; ``decay`` ``(KR, G)``
    the evidence's final decays; ``ctx`` the fit's scalings, one entry per record where they differ).
    A posterior that cannot be formed (its model does not match it) is left out with a warning."""
    import time

    E, n = ctx["E"], ctx["n"]
    for k, (rows, model) in enumerate(zip(members, models)):
        t0 = time.perf_counter()
        idx = torch.as_tensor(np.asarray(rows, dtype=np.int64))
        sub = problem.subset(idx)
        if sub.decay_index is not None:
            sub.set_weight_decay(decay[idx].to(sub.y.dtype))
        c = dict(ctx, **ctx["per_record"][k])
        n_rows = int(sub.y.shape[-1]) * max(1, len(rows))
        if sub.n_params > MAX_DENSE_PARAMS or n_rows * sub.n_params > MAX_JACOBIAN_ENTRIES:
            # the dense Laplace approximation holds a rows x parameters Jacobian and a parameters^2
            # matrix: the paper preset's 100-100-100 networks would need tens of GB
            model.info["posterior"] = (f"skipped: {sub.n_params} parameters per member and {n_rows} residual rows "
                                       f"exceed the dense Laplace approximation's limits ({MAX_DENSE_PARAMS} "
                                       f"parameters, {MAX_JACOBIAN_ENTRIES:.0e} Jacobian entries); use --bands N "
                                       "for bootstrap bands")
            continue
        widths = [o + t.curve.slices()["jump_log_eps"].start for t, o in zip(sub.terms, sub.offsets)
                  if getattr(t.curve, "jump", False) and hasattr(t.curve, "slices")]
        if widths:  # a jump's width is a shape the fit chose (sharpened where unresolved): taken as known
            sub.frozen = torch.zeros(sub.n_params, dtype=torch.bool)
            sub.frozen[widths] = True
        post = laplace_posterior(sub, theta[idx].to(sub.y.dtype), EquationErrorMap(c),
                                 _owner_names(problem, c["names"], c["const_names"]),
                                 instants=lambda a: a.reshape(E, n, -1).sum(axis=0),  # equations of one instant
                                 noise_scale=float(c["s_out"]) ** 2 * ctx["N_rows"])
        attach_posterior(model, post, t0)
