"""Residual tests of system identification (Ljung, *System Identification*, ch. 16), on series whose
neighbouring samples may be correlated.

Three statistics of a residual series ``r`` (one equation's residual over time):

* :func:`whiteness` -- the Ljung-Box portmanteau statistic over lags 1..M (chi-square, M degrees
  of freedom): only meaningful where a correct model leaves white residuals;
* :func:`input_correlation` -- the cross-correlation of ``r`` with the input F at lags 1 <= |l| <= M,
  both prewhitened with the residual's AR filter; the largest, Bonferroni over the lags. Lag 0 is
  left out: a residual ``... - g F`` holds the noise of the measured F itself, so a correct model
  correlates with F at lag 0;
* :func:`binned_test` (:func:`binned_tests` for several arguments at once) -- the residual's means in K quantile bins of a curve's argument; equal means
  (a residual that is no function of the argument) give a Wald statistic ~ F(K - 1, N - K), by
  generalised least squares with an AR model of the residual, so that a residual correlated over
  neighbouring samples (estimated derivatives) is not taken for a misfit.

The AR models (:func:`ar_whitener`) come from the residual itself; the distributions are scipy.stats'.
"""

from __future__ import annotations

import numpy as np

__all__ = ["ar_whitener", "autocorrelation", "bin_indices", "binned_test", "binned_tests", "input_correlation", "whiteness"]

#: two-sided 1 % point of the normal distribution: a lag of a white series' normalised
#: autocorrelation lies outside +-Z99/sqrt(N) with probability 1 %
Z99 = 2.5758293035489004


def autocorrelation(r, max_lag: int) -> np.ndarray:
    """Normalised autocorrelation of ``r`` (mean removed) at lags 0..max_lag (FFT, biased estimate).

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.fitting import autocorrelation
    >>> autocorrelation(np.array([1.0, -1.0, 1.0, -1.0]), 2).round(2).tolist()
    [1.0, -0.75, 0.5]
    """
    r = np.asarray(r, dtype=float) - float(np.mean(r))
    n = r.size
    f = np.fft.rfft(r, 2 * n)
    acov = np.fft.irfft(f * np.conj(f))[: max_lag + 1] / n
    return acov / acov[0] if acov[0] > 0 else np.zeros(max_lag + 1)


def ar_whitener(r, max_order: int = 40) -> np.ndarray:
    """The prediction-error filter ``[1, -a_1, ..., -a_p]`` of an autoregressive model of ``r``
    (Yule-Walker, the order p <= ``max_order`` by BIC; ``[1.0]`` for a white series): filtering with
    it leaves ``r``'s innovations, white when the AR model holds.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from charcurves.fitting import ar_whitener
    >>> e = np.random.default_rng(0).normal(size=5000)
    >>> ar_whitener(lfilter([1.0], [1.0, -0.8], e)).round(1).tolist()
    [1.0, -0.8]
    """
    from scipy.linalg import solve_toeplitz

    r = np.asarray(r, dtype=float)
    n = r.size
    p_max = int(min(max_order, n // 10))
    g = autocorrelation(r, p_max)
    best, taps = 0.0, np.zeros(0)  # BIC relative to order 0: n log(s2_p / s2_0) + p log n
    if not g[0] > 0:  # a constant (e.g. zero) residual: nothing to whiten
        return np.ones(1)
    for p in range(1, p_max + 1):
        try:
            a = solve_toeplitz(g[:p], g[1:p + 1])
        except np.linalg.LinAlgError:  # a degenerate autocorrelation (a residual at round-off): stop here
            break
        s2 = float(g[0] - a @ g[1:p + 1])
        aic = n * np.log(max(s2, 1e-300)) + np.log(n) * p
        if aic < best:
            best, taps = aic, a
    return np.concatenate([[1.0], -taps])


def _whiten(filt: np.ndarray, *arrays):
    """Each array filtered with ``filt`` along its first axis, the first ``len(filt) - 1`` samples
    (the filter's start-up) dropped."""
    from scipy.signal import lfilter

    p = len(filt) - 1
    return [lfilter(filt, [1.0], np.asarray(a, dtype=float), axis=0)[p:] for a in arrays]


def whiteness(r, lags: int = 20) -> dict:
    """Portmanteau (Ljung-Box) test of ``r`` over lags 1..``lags``, each lag's autocovariance over its
    heteroscedasticity-robust standard error, ``Q = sum_k (sum_t r_t r_(t-k))^2 / sum_t r_t^2 r_(t-k)^2``
    ~ chi-square(lags) for an uncorrelated series.

    Returns ``{"statistic", "dof", "p_value", "lags_outside"}`` (the share of lags whose normalised
    autocorrelation lies outside +-2.58/sqrt(N), 1 % for a white series).

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.fitting import whiteness
    >>> rng = np.random.default_rng(0)
    >>> white = whiteness(rng.normal(size=2000))
    >>> white["p_value"] > 0.01, white["dof"]
    (True, 20)
    >>> whiteness(np.convolve(rng.normal(size=2000), np.ones(5), "same"))["p_value"] < 1e-10
    True
    """
    from scipy import stats

    r = np.asarray(r, dtype=float)
    n = r.size
    m = int(min(lags, n // 5))
    rho = autocorrelation(r, m)[1:]
    d = r - float(np.mean(r))
    # each lag's sum over its heteroscedasticity-robust standard error: noise in a curve's argument
    # makes the residual's variance vary with the state, which inflates the plain Ljung-Box statistic
    q = float(sum(np.dot(d[k:], d[:-k]) ** 2 / max(float(np.dot(d[k:] ** 2, d[:-k] ** 2)), 1e-300)
                  for k in range(1, m + 1)))
    return {"statistic": q, "dof": m, "p_value": float(stats.chi2.sf(q, m)),
            "lags_outside": float(np.mean(np.abs(rho) > Z99 / np.sqrt(n)))}


def input_correlation(r, u, lags: int = 20, *, input_noise: float = 0.0, gain: float = 1.0) -> dict:
    """Cross-correlation of the residual ``r`` with the input ``u`` (``r_t`` against ``u_{t-l}``) at
    lags 1 <= |l| <= ``lags``, after both are filtered with the residual's whitening filter
    (:func:`ar_whitener`): the filtered residual is white under the hypothesis of no correlation,
    so each lag's normalised correlation has standard error 1/sqrt(N) (Ljung, ch. 16.6).

    ``input_noise`` (the variance of the measured input's white noise) and ``gain``: a residual
    ``... - g u`` holds ``-g`` times that noise, which the filter spreads over lags 1..p; its expected
    share of each lag's correlation is taken off.

    Returns ``{"max_abs_z", "at_lag", "lags", "p_value"}``: the p-value of the largest |z|, times
    the number of lags (Bonferroni; the lags of a smooth input are correlated, so this is conservative).

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.fitting import input_correlation
    >>> rng = np.random.default_rng(1)
    >>> u = np.sin(np.linspace(0, 60, 3000)) + 0.3 * rng.normal(size=3000)
    >>> input_correlation(rng.normal(size=3000), u)["p_value"] > 0.01
    True
    >>> input_correlation(rng.normal(size=3000) + 0.2 * np.roll(u, 3), u)["p_value"] < 1e-6
    True
    """
    from scipy import stats

    r = np.asarray(r, dtype=float) - float(np.mean(r))
    u = np.asarray(u, dtype=float) - float(np.mean(u))
    filt = ar_whitener(r)
    rf, uf = _whiten(filt, r, u)
    n = rf.size
    m = int(min(lags, n // 5))
    sr, su = float(np.std(rf)), float(np.std(uf))
    if sr == 0 or su == 0:
        return {"max_abs_z": 0.0, "at_lag": 0, "lags": 2 * m, "p_value": 1.0}
    ls = np.array([lag for lag in range(-m, m + 1) if lag != 0])
    c = np.array([np.dot(rf[lag:], uf[:n - lag]) if lag > 0 else np.dot(rf[:n + lag], uf[-lag:]) for lag in ls]) / n
    if input_noise > 0:  # E[(A(-g e))_t (A e)_(t-l)] = -g s2 sum_i f_i f_(i-l)
        acf = np.correlate(filt, filt, "full")  # index len(filt) - 1 is lag 0
        mid = len(filt) - 1
        c = c + gain * input_noise * np.array([acf[mid + lag] if abs(lag) <= mid else 0.0 for lag in ls])
    z = np.abs(c) / (sr * su) * np.sqrt(n)
    k = int(np.argmax(z))
    p = float(min(1.0, len(ls) * 2.0 * stats.norm.sf(z[k])))
    return {"max_abs_z": float(z[k]), "at_lag": int(ls[k]), "lags": int(len(ls)), "p_value": p,
            "whitening_order": len(filt) - 1}


def bin_indices(z: np.ndarray, bins: int) -> tuple[np.ndarray, np.ndarray]:
    """Each sample's quantile bin of ``z`` (empty bins dropped) and the bins' sample counts.

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.fitting import bin_indices
    >>> idx, counts = bin_indices(np.arange(10.0), 5)
    >>> idx.tolist(), counts.tolist()
    ([0, 0, 1, 1, 2, 2, 3, 3, 4, 4], [2, 2, 2, 2, 2])
    """
    edges = np.unique(np.quantile(z, np.linspace(0.0, 1.0, int(bins) + 1)))
    idx = np.clip(np.searchsorted(edges, z, side="right") - 1, 0, max(len(edges) - 2, 0))
    counts = np.bincount(idx, minlength=max(len(edges) - 1, 1))
    keep = counts > 0
    return np.cumsum(keep)[idx] - 1, counts[keep]


def binned_tests(r, arguments: dict, bins: int = 10) -> dict:
    """:func:`binned_test` of ``r`` against several arguments at once (one per curve): the residual is
    regressed on the bins of all of them together (an additive model: a constant and, per argument,
    its bins but the first), so that a misfit along one argument is not noise in the test of another.

    Returns ``{name: result}`` with :func:`binned_test`'s keys for each argument.

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.fitting import binned_tests
    >>> rng = np.random.default_rng(3)
    >>> t = np.linspace(0, 60, 3000)
    >>> x, v = np.sin(t), np.cos(1.7 * t)
    >>> res = binned_tests(rng.normal(size=3000) + np.abs(x), {"x": x, "v": v})
    >>> bool(res["x"]["p_value"] < 1e-6), bool(res["v"]["p_value"] > 0.001)
    (True, True)
    """
    from scipy import stats

    r = np.asarray(r, dtype=float)
    n = r.size
    names = list(arguments)
    blocks, cols, layout = [], [np.ones(n)], {}
    for name in names:
        idx, counts = bin_indices(np.asarray(arguments[name], dtype=float), bins)
        K = counts.size
        B = np.zeros((n, K))
        B[np.arange(n), idx] = 1.0
        layout[name] = (len(cols), K, counts)
        cols.extend(B[:, 1:].T)
        blocks.append(B)
    X = np.column_stack(cols)
    beta = np.linalg.lstsq(X, r, rcond=None)[0]
    u = r - X @ beta
    if not np.any(u):
        return {name: {"statistic": 0.0, "dof": layout[name][1] - 1, "p_value": 1.0, "bins": layout[name][1],
                       "z_scores": [0.0] * layout[name][1], "whitening_order": 0} for name in names}
    for _ in range(2):  # feasible GLS: the AR model of the residual around the bin means, then the means
        filt = ar_whitener(u)
        rf, Xf = _whiten(filt, r, X)
        beta = np.linalg.lstsq(Xf, rf, rcond=None)[0]
        u = r - X @ beta
    e = rf - Xf @ beta
    dof = max(rf.size - X.shape[1], 1)
    V = float(e @ e) / dof * np.linalg.pinv(Xf.T @ Xf)
    out = {}
    for name in names:
        start, K, counts = layout[name]
        if K < 2:
            out[name] = {"statistic": 0.0, "dof": 0, "p_value": 1.0, "bins": K, "z_scores": [0.0] * K,
                         "whitening_order": len(filt) - 1}
            continue
        sl = slice(start, start + K - 1)
        d, Vd = beta[sl], V[sl, sl]
        W = float(d @ np.linalg.lstsq(Vd, d, rcond=None)[0])
        # each bin against the count-weighted mean of the bins, for the message (where the residual sits)
        L = np.zeros((K, K - 1))
        L[1:] = np.eye(K - 1)
        L -= (counts / n) @ L
        dev, se = L @ d, np.sqrt(np.maximum(np.diag(L @ Vd @ L.T), 1e-300))
        out[name] = {"statistic": W, "dof": K - 1, "p_value": float(stats.f.sf(W / (K - 1), K - 1, dof)), "bins": K,
                     "z_scores": (dev / se).tolist(), "whitening_order": len(filt) - 1}
    return out


def binned_test(r, z, bins: int = 10) -> dict:
    """Whether the residual ``r`` is a function of the argument ``z``: the means of ``r`` in
    ``bins`` quantile bins of ``z`` and the Wald statistic of their equality over K - 1,
    ~ F(K - 1, N - K), by generalised least squares: the residual around the bin means is modelled
    as autoregressive (:func:`ar_whitener`), the residual and the bin indicators are filtered with
    its whitening filter and the means regressed on them (twice, the AR model refitted around the
    new means).

    Returns ``{"statistic", "dof", "p_value", "bins", "z_scores", "whitening_order"}``: ``z_scores`` are
    each bin's mean minus the overall mean, over its standard error.

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.fitting import binned_test
    >>> rng = np.random.default_rng(2)
    >>> z = np.sin(np.linspace(0, 40, 2000))
    >>> binned_test(rng.normal(size=2000), z)["p_value"] > 0.01
    True
    >>> binned_test(rng.normal(size=2000) + z ** 3 - 0.6 * z, z)["p_value"] < 1e-6
    True
    """
    return binned_tests(r, {"z": z}, bins)["z"]
