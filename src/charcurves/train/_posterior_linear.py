"""The Gaussian posterior of a least-squares fit (:mod:`._linear_fit`): Poly-CC, parametric bases,
any LinearCurve, with their constants, offsets, scalars and a free gain; a sparse (SINDy) fit's on
the terms its regression kept, the support taken as known (:func:`active_design`).

The fit solves ``min ||A beta - y||^2`` on the design ``A`` (columns scaled to unit norm). Under a
flat prior (the least-squares fit has no decays) the posterior of ``beta`` is Gaussian with mean
the solution and covariance

* ``"gauss"``: ``s^2 (A^T A)^-1`` with ``s^2 = RSS / (N - k)``, ``k`` the design's rank (independent, equal-variance noise);
* ``"hac"`` (the default): the Newey-West sandwich ``(A^T A)^-1 S (A^T A)^-1`` where ``S`` sums the
  lagged products of the score rows ``a_t r_t`` with Bartlett weights over a bandwidth from Andrews'
  (1991) AR(1) plug-in rule, ``L = 1.1447 (alpha n)^(1/3)``, ``alpha = 4 rho^2 / ((1 - rho)^2 (1 + rho)^2)``,
  ``rho`` the residual's lag-one autocorrelation. Derivatives estimated by a smoothing filter make
  the equation's residual correlated over the filter's window; the plain formula then counts every
  sample as independent and its bands are too narrow. On white residuals both agree.

Every reported quantity (a curve's value at ``z`` after the template's gauge, the gain, the free
constants and scalars) is a function of ``beta``; its variance is propagated through that
function's Jacobian (exact: the map is linear in the coefficients, and a gain learned on the force
side, which divides them, enters by the delta method). Variances are ``||J R||^2`` with ``R`` a
square-root factor of the covariance, so that a well-determined curve keeps its band when two of
its columns are nearly dependent.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

__all__ = ["LinearPosterior", "COVARIANCE_KINDS", "hac_bandwidth"]

#: How the covariance of the coefficients is estimated (module docstring).
COVARIANCE_KINDS = ("hac", "gauss")
#: A design whose (column-scaled) condition number exceeds this gives a warning naming the weakest direction.
ILL_CONDITIONED = 1e8


def hac_bandwidth(r: np.ndarray) -> int:
    """Andrews' (1991) AR(1) plug-in bandwidth of the Bartlett kernel for the series ``r``.

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.train import hac_bandwidth
    >>> rng = np.random.default_rng(0)
    >>> white = rng.normal(size=2000)
    >>> smooth = np.convolve(white, np.ones(20) / 20, mode="same")
    >>> hac_bandwidth(white) <= 3, hac_bandwidth(smooth) > 20
    (True, True)
    """
    r = np.asarray(r, dtype=float) - np.mean(r)
    n = r.size
    den = float(r @ r)
    if n < 4 or den == 0.0:
        return 0
    rho = float(np.clip((r[1:] @ r[:-1]) / den, -0.99, 0.99))
    alpha = 4 * rho**2 / ((1 - rho) ** 2 * (1 + rho) ** 2)
    return int(min(np.ceil(1.1447 * (alpha * n) ** (1.0 / 3.0)), n // 4))


def active_design(template, D: dict, cols: list, owners: list, rows: np.ndarray, coef: np.ndarray, gain: float):
    """The least-squares problem of a sparse fit on its active terms (the sparse regression's support
    taken as given): ``(A, norms, target, coef_scaled, owners, force_side)`` in the layout of the
    dense fit, the gain's column ``-F`` where the sparse fit learned it (STLSQ, the paper's SINDy)."""
    keep = [j for j, c in enumerate(coef) if c != 0.0]
    A = np.column_stack([cols[j] for j in keep]) if keep else np.zeros((len(D["y"]), 0))
    owners = [owners[j] for j in keep]
    beta = np.asarray(coef, dtype=float)[keep]
    target = template.gain * D["F"] - D["y"]
    if template.free_gain:
        A = np.column_stack([A, -D["F"]])
        owners.append(("__gain", 0))
        beta = np.append(beta, gain)
        target = -D["y"]
    A = A[rows]
    norms = np.linalg.norm(A, axis=0)
    norms[norms == 0] = 1.0
    return A, norms, target, beta * norms, owners, False


def bartlett_sum(score: np.ndarray, L: int) -> np.ndarray:
    """``sum_{|l| <= L} (1 - |l| / (L + 1)) sum_t u_{t+l} u_t^T`` of the rows ``u_t`` of ``score``, exactly,
    as ``B^T B / (L + 1)`` with ``B`` the sums of the rows over every window of ``L + 1`` samples (those
    cut by the ends included): a pair of rows ``l`` apart shares ``L + 1 - l`` windows. One product
    instead of one per lag."""
    n, k = score.shape
    cum = np.vstack([np.zeros((1, k)), np.cumsum(score, axis=0)])
    starts = np.arange(-int(L), n)
    B = cum[np.minimum(starts + L + 1, n)] - cum[np.maximum(starts, 0)]
    return B.T @ B / (L + 1.0)


class LinearPosterior:
    """The posterior of a least-squares fit; built by :func:`charcurves.fitting.fit_linear` and kept as
    ``model.posterior`` (see :meth:`charcurves.FittedModel.curve_band`).

    Attributes
    ----------
    beta, cov : ndarray
        The regression's coefficients and their covariance (unscaled columns).
    gauss_cov : ndarray
        The covariance under independent, equal-variance noise (``"gauss"``), for comparison.
    kind : str
        ``"hac"`` or ``"gauss"``.
    noise_variance : float
        ``RSS / (N - k)`` of the equation's residual (``k`` the design's rank).
    hac_cov : ndarray
        The HAC covariance (``"hac"``).
    bandwidth : int
        The Bartlett bandwidth of the HAC covariance.
    condition_number : float

    Examples
    --------
    >>> import numpy as np
    >>> import charcurves as cc
    >>> from charcurves.systems import get_system
    >>> record = cc.corrupt(get_system("duffing").simulate(), 20, seed=0)
    >>> post = cc.fit(record, method="parametric", basis="f1=z; f2=z, z**3").posterior
    >>> value, sd = post.curve_sd("f2", np.array([1.0]))
    >>> f"{value[0]:.4f} +- {sd[0]:.4f}", post.with_kind("gauss").kind
    ('0.0014 +- 0.0014', 'gauss')
    """

    def __init__(self, *, template, reps: dict, scalings: dict, owners: list, A: np.ndarray, norms: np.ndarray,
                 target: np.ndarray, coef_scaled: np.ndarray, rows: np.ndarray, n: int, force_side: bool,
                 pinned: dict, features, kind: str = "hac"):
        if kind not in COVARIANCE_KINDS:
            from .._errors import ConfigError

            raise ConfigError(f"unknown posterior covariance {kind!r}; choose one of {', '.join(COVARIANCE_KINDS)}")
        self.template, self.reps, self.scalings, self._feature_fn = template, reps, scalings, features
        self._gauge: tuple | None = None
        self.owners, self.force_side, self.pinned, self.kind = list(owners), bool(force_side), dict(pinned), kind
        N, p = A.shape
        self.beta = np.asarray(coef_scaled, dtype=float) / norms
        r = target - A @ coef_scaled
        U, s, Vt = np.linalg.svd(A, full_matrices=False)
        self.condition_number = float(s[0] / s[-1]) if s[-1] > 0 else float("inf")
        s_inv = np.where(s > s[0] * 1e-13, 1.0 / np.where(s > 0, s, 1.0), np.inf)
        self._weak = Vt[-1] if self.condition_number > ILL_CONDITIONED else None
        finite = np.isfinite(s_inv)
        Vf = Vt[finite].T * s_inv[finite]  # columns V_k / s_k: (A^T A)^-1 = Vf Vf^T on the identified subspace
        # the sandwich on the design's orthonormal basis U (A = U s V^T): the scores u_t r_t are
        # well scaled whatever the conditioning of A, and cov = (V / s) S_U (V / s)^T
        k = int(finite.sum())  # the design's rank: the degrees of freedom the fit used
        self.noise_variance = float(r @ r / max(N - k, 1))
        full = np.zeros((rows.size, k))
        full[rows] = U[:, finite] * r[:, None]
        score = full.reshape(-1, n, k).sum(axis=0)  # equations at the same instant share a row
        res = np.zeros(rows.size)
        res[rows] = r
        L = hac_bandwidth(res.reshape(-1, n).sum(axis=0))
        S = bartlett_sum(score, L)
        w, Q = np.linalg.eigh((S + S.T) / 2)  # S = C C^T
        C = Q * np.sqrt(np.clip(w, 0.0, None) * (N / max(N - k, 1)))
        self._factors = {"gauss": np.sqrt(self.noise_variance) * Vf / norms[:, None],
                         "hac": (Vf @ C) / norms[:, None]}
        self.gauss_cov = self._factors["gauss"] @ self._factors["gauss"].T
        self.hac_cov = self._factors["hac"] @ self._factors["hac"].T
        self.bandwidth = int(L)
        self.unidentified = Vt[~finite]  # directions the record does not determine (infinite variance)
        self.cov = self.hac_cov if kind == "hac" else self.gauss_cov
        self._norms = norms

    def with_kind(self, kind: str) -> LinearPosterior:
        """The same fit's posterior with the covariance ``kind`` (both are computed at the fit)."""
        import copy

        if kind not in COVARIANCE_KINDS:
            from .._errors import ConfigError

            raise ConfigError(f"unknown posterior covariance {kind!r}; choose one of {', '.join(COVARIANCE_KINDS)}")
        new = copy.copy(self)
        new.kind = kind
        new.cov = self.hac_cov if kind == "hac" else self.gauss_cov
        return new

    # ------------------------------------------------------------------ the map beta -> reported values
    def _split(self, beta: np.ndarray) -> tuple[np.ndarray, float, np.ndarray, np.ndarray]:
        """``(coef, gain, dcoef/dbeta, dgain/dbeta)``: a gain learned on the force side divides the
        coefficients (the delta method's Jacobian; exact elsewhere)."""
        tpl, P = self.template, beta.size
        if not tpl.free_gain:
            return beta, float(tpl.gain), np.eye(P), np.zeros(P)
        gi = self.owners.index(("__gain", 0))
        dgain = np.zeros(P)
        if not self.force_side:
            dgain[gi] = 1.0
            return beta, float(beta[gi]), np.eye(P), dgain
        bg = float(beta[gi])
        D = np.eye(P) / bg
        D[:, gi] -= beta / bg**2
        dgain[gi] = -1.0 / bg**2
        return beta / bg, 1.0 / bg, D, dgain

    def _features(self, name: str, z: np.ndarray) -> np.ndarray:
        c, h = self.scalings[name]
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return self._feature_fn(self.reps[name], (np.asarray(z, dtype=float).reshape(-1) - c) / h)

    def _gauge_map(self):
        """The template's gauge (:meth:`normalise`) as the linear map it is: shifts and new offsets
        per unit value of each curve at 0 and of each offset (sympy is asked once per input, not once
        per coefficient and grid)."""
        if self._gauge is None:
            names = list(self.template.curve_names)
            offs = sorted({key for owner, key in self.owners if owner == "__offset"})
            columns = []
            for j in range(len(names) + len(offs)):
                raw0 = {nm: float(j == i) for i, nm in enumerate(names)}
                o = {e: float(j == len(names) + i) for i, e in enumerate(offs)}
                columns.append(self.template.normalise(raw0, self.pinned, o))
            keys = sorted({e for _, new_off in columns for e in new_off})
            S = np.array([[c[0][nm] for c in columns] for nm in names], dtype=float).reshape(len(names), len(columns))
            O = np.array([[c[1].get(e, 0.0) for c in columns] for e in keys], dtype=float).reshape(len(keys),
                                                                                                 len(columns))
            self._gauge = (names, offs, keys, S, O)
        return self._gauge

    def _idle_inputs(self) -> np.ndarray:
        """The gauge's inputs (curve values at 0, offsets) that it moves nothing by: a curve infinite
        at 0 (a basis such as 1/z) that no gauge anchors there."""
        *_, S, O = self._gauge_map()
        return ~(np.any(S != 0, axis=0) | np.any(O != 0, axis=0))

    def _values(self, coef: np.ndarray, feats: dict, phi0: dict) -> tuple[dict, dict]:
        """Curves on ``feats``' grids and the free constants and scalars: linear in ``coef``."""
        by_curve: dict[str, dict] = {nm: {} for nm in self.template.curve_names}
        scalars, offs = {}, {}
        for (owner, key), v in zip(self.owners, coef):
            if owner == "__scalar":
                scalars[key] = float(v)
            elif owner == "__offset":
                offs[key] = float(v)
            elif owner != "__gain":
                by_curve[owner][key] = float(v)
        raw0, theta = {}, {}
        for nm, ph in phi0.items():
            theta[nm] = np.array([by_curve[nm].get(j, 0.0) for j in range(ph.shape[1])])
            with np.errstate(all="ignore"):  # infinite at 0 (1/z): used only where a gauge anchors it
                raw0[nm] = float(ph[0] @ theta[nm] + by_curve[nm].get("const", 0.0))
        names, off_keys, new_keys, S, O = self._gauge_map()
        inputs = np.array([raw0[nm] for nm in names] + [offs.get(e, 0.0) for e in off_keys])
        inputs[~np.isfinite(inputs) & self._idle_inputs()] = 0.0
        shifts = dict(zip(names, S @ inputs))
        new_off = dict(zip(new_keys, O @ inputs))
        curves = {nm: ph @ theta[nm] + by_curve[nm].get("const", 0.0) + shifts[nm] for nm, ph in feats.items()}
        out = {"offset": float(new_off.get(0, 0.0)), **scalars}
        out.update({f"b{e + 1}": float(v) for e, v in new_off.items() if e > 0})
        return curves, out

    def _jacobians(self, grids: dict):
        """Values at the posterior mean and their exact Jacobians with respect to ``beta``: the map
        from the coefficients is linear, a curve's column is its feature (1 for its constant) plus
        the gauge's shift through the curves' values at 0 and the offsets."""
        names, off_keys, new_keys, S, O = self._gauge_map()
        feats = {nm: self._features(nm, z) for nm, z in grids.items()}
        phi0 = self._phi0()
        coef, gain, D, dgain = self._split(self.beta)
        P = coef.size
        Jin = np.zeros((len(names) + len(off_keys), P))  # gauge inputs (values at 0, offsets) per coefficient
        direct = {nm: np.zeros((ph.shape[0], P)) for nm, ph in feats.items()}
        js = {k: np.zeros(P) for k in ("offset", *[k for o, k in self.owners if o == "__scalar"],
                                       *[f"b{e + 1}" for e in new_keys if e > 0])}
        for j, (owner, key) in enumerate(self.owners):
            if owner == "__scalar":
                js[key][j] = 1.0
            elif owner == "__offset":
                Jin[len(names) + off_keys.index(key), j] = 1.0
            elif owner != "__gain":
                Jin[names.index(owner), j] = 1.0 if key == "const" else phi0[owner][0, key]
                if owner in direct:
                    direct[owner][:, j] = 1.0 if key == "const" else feats[owner][:, key]
        Jin[self._idle_inputs() & ~np.all(np.isfinite(Jin), axis=1)] = 0.0
        jc = {nm: (direct[nm] + (S[names.index(nm)] @ Jin)[None, :]) @ D for nm in feats}
        dO = O @ Jin
        for r, e in enumerate(new_keys):
            js["offset" if e == 0 else f"b{e + 1}"] += dO[r]
        js = {k: v @ D for k, v in js.items()}
        c0, s0 = self._values(coef, feats, phi0)
        s0, js = {"gain": gain, **s0}, {"gain": dgain, **js}
        return c0, s0, jc, js

    def _phi0(self) -> dict:
        if getattr(self, "_phi0_cache", None) is None:
            self._phi0_cache = {nm: self._features(nm, np.array([0.0])) for nm in self.template.curve_names}
        return self._phi0_cache

    def _variance(self, J: np.ndarray) -> np.ndarray:
        """Rows' variances ``diag(J cov J^T)``; infinite where a row loads on an unidentified direction."""
        var = np.sum((J @ self._factors[self.kind]) ** 2, axis=1)
        if len(self.unidentified):
            load = np.abs((J / self._norms) @ self.unidentified.T).max(axis=1)
            scale = np.abs(J / self._norms).max(axis=1) + 1e-300
            var = np.where(load > 1e-8 * scale, np.inf, var)
        return np.clip(var, 0.0, None)

    # ------------------------------------------------------------------ what users ask for
    def curve_sd(self, name: str, z) -> tuple[np.ndarray, np.ndarray]:
        """``(value, sd)`` of curve ``name`` at ``z`` (the gauge-fixed curve the model reports)."""
        z = np.asarray(z, dtype=float)
        c0, _, jc, _ = self._jacobians({name: z})
        return c0[name].reshape(z.shape), np.sqrt(self._variance(jc[name])).reshape(z.shape)

    def curve_factor(self, name: str, z) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(value, G, infinite)`` of curve ``name`` at ``z``: the posterior of the values is ``value + G u``
        with ``u`` standard normal, shared by every curve and scalar of the fit (so samples and
        sensitivities keep their correlations); ``infinite`` marks points whose variance is infinite."""
        z = np.asarray(z, dtype=float).reshape(-1)
        c0, _, jc, _ = self._jacobians({name: z})
        J = jc[name]
        return c0[name], np.nan_to_num(J @ self._factors[self.kind]), ~np.isfinite(self._variance(J))

    def scalar_factor(self) -> tuple[list, np.ndarray, np.ndarray, np.ndarray]:
        """``(names, mean, G, infinite)`` of the learned scalars, in the layout of :meth:`curve_factor`."""
        _, s0, _, js = self._jacobians({})
        names = [k for k in s0 if np.any(js[k] != 0)]
        J = np.stack([js[k] for k in names]) if names else np.zeros((0, self.beta.size))
        G = np.nan_to_num(J @ self._factors[self.kind])
        return names, np.array([s0[k] for k in names], dtype=float), G, ~np.isfinite(self._variance(J))

    def scalar_stats(self) -> dict[str, Any]:
        """Mean, sd and correlations of the gain, the free constants and the scalars (those the fit
        learned; a fixed gain is left out)."""
        _, s0, _, js = self._jacobians({})
        names = [k for k in s0 if np.any(js[k] != 0)]
        if not names:
            return {"names": [], "mean": {}, "sd": {}, "correlation": []}
        J = np.stack([js[k] for k in names])
        JR = J @ self._factors[self.kind]
        cov = JR @ JR.T
        sd = np.sqrt(np.clip(self._variance(J), 0.0, None))
        with np.errstate(all="ignore"):
            corr = cov / np.outer(np.sqrt(np.diag(cov)), np.sqrt(np.diag(cov)))
        corr = np.where(np.isfinite(corr), corr, np.nan)
        return {"names": names, "mean": {k: s0[k] for k in names}, "sd": dict(zip(names, sd.tolist())),
                "correlation": corr.tolist()}

    def check_against(self, model, *, rtol: float = 1e-7) -> bool:
        """Whether the model still has the curves this posterior describes (an output-error refinement,
        a post-SR distillation or a loaded model replace them)."""
        for nm, curve in model.curves.items():
            lo, hi = curve.domain
            z = np.linspace(lo, hi, 5)
            mine, _ = self._values(self._split(self.beta)[0], {nm: self._features(nm, z)}, self._phi0())
            ref = np.asarray(curve(z), dtype=float)
            if not np.allclose(mine[nm], ref, rtol=rtol, atol=rtol * (np.max(np.abs(ref)) + 1e-300)):
                return False
        return True

    def warnings(self) -> list[str]:
        """One line per problem: an unidentified or a poorly determined direction, naming its columns."""
        out = []
        for v in [*self.unidentified, *([] if self._weak is None or len(self.unidentified) else [self._weak])]:
            order = np.argsort(-np.abs(v))[:3]
            cols = ", ".join(_owner_label(self.owners[i]) for i in order if abs(v[i]) > 0.1)
            what = "does not determine" if len(self.unidentified) else "barely determines"
            out.append(f"uncertainty: the record {what} a combination of {cols} (condition number "
                       f"{self.condition_number:.3g}); what depends on it has wide or infinite intervals: excite "
                       "the curves over a wider range, drop one of those terms or fix a gauge")
        return out


def _owner_label(owner) -> str:
    kind, key = owner
    if kind == "__scalar":
        return f"the scalar {key}"
    if kind == "__offset":
        return f"the free constant b{key + 1}"
    if kind == "__gain":
        return "the gain"
    return f"the constant of {kind}" if key == "const" else f"coefficient {key} of {kind}"
