"""Harmonic terms chosen by the data: a periodogram of the equation error against each curve's argument.

Only curves that enter their equation additively (multiplier 1: a restoring or damping force) are
searched; the search needs a large, mostly sinusoidal misfit of the smooth terms (see the thresholds).

A small network follows curves that bend a few times over their range; a curve that oscillates
over many periods of its argument (the restoring torque 9.81 sin x of a pendulum that turns over,
x up to 100 rad) is beyond it, and the fit stays flat. :func:`harmonic_test` looks for such a
curve before training: the target of the equation is regressed by least squares on smooth terms
of every curve (powers of the scaled argument up to 5 under the curve's parity, a sign column for
a learned jump) and, for each candidate frequency ``w`` of one curve, on ``sin(w u)`` and
``cos(w u)`` besides (the sine alone for an odd curve, the cosine alone for an even one). The F
statistic of the added columns is the periodogram of the equation error against that argument.
Frequencies span 2 to 100 periods over the visited range (fewer than 2 periods a network
follows; more than one period per 20 samples cannot be told from noise), 4 per period of
resolution. The largest F over every curve and frequency is compared with
:data:`HARMONIC_F_THRESHOLD`; when above, its frequency is refined by a bounded scalar search on
the residual sum of squares, and if the pair of columns removes at least :data:`HARMONIC_MIN_GAIN`
of that sum (and the smooth terms leave more than :data:`HARMONIC_MIN_MISFIT` of the target's
variance) it joins the smooth terms and the search repeats
(at most :data:`MAX_HARMONICS` frequencies per curve, so a non-sinusoidal periodic curve gets its
overtones). The frequencies found become free linear terms of the neural curve
(:class:`~charcurves.curves.NeuralCurve` ``harmonics``), the network models what is left.

Cost: one batched least-squares sweep (a few hundred frequencies) per curve, about 10-30 ms on a
2 000-sample record, and nothing else when no frequency is significant (the paper's records).
"""

from __future__ import annotations

import math

import numpy as np

from ..curves import neural_input_map
from ..train import subset_indices

__all__ = ["harmonic_test", "HARMONIC_F_THRESHOLD", "HARMONIC_MIN_GAIN", "HARMONIC_MIN_MISFIT", "MAX_HARMONICS", "HARMONIC_PERIODS"]

#: F statistic above which a harmonic is significant. Measured on the paper's Duffing and
#: stick-slip records at 20 dB (seeds 0-2, unconstrained and odd curves): the largest F over the
#: periodogram is 3.4-9.3 (Duffing) and up to 26.2 (stick-slip f2 under the odd prior, where the
#: sticking samples leave some structure); the turning pendulum's restoring curve gives 1.7e6.
#: 100 keeps a margin of about 4 over the paper's records.
HARMONIC_F_THRESHOLD = 100.0
#: ... and it must remove at least this fraction of the residual sum of squares of the smooth terms
#: (on long records a small systematic misfit, e.g. of the derivative estimates, passes any F test:
#: van der Pol at 25 dB reached F > 100 with a gain of a few per cent; the turning pendulum's is > 99 %)
HARMONIC_MIN_GAIN = 0.5
#: ... and only where the smooth terms leave more than this fraction of the target's variance
HARMONIC_MIN_MISFIT = 1e-2
#: Most frequencies given to one curve.
MAX_HARMONICS = 4
#: Periods over the visited range that the search covers (low, high), and grid points per period.
HARMONIC_PERIODS = (2.0, 100.0)
#: rows the test looks at on a long record (a fixed stratified subset beyond this)
HARMONIC_MAX_ROWS = 8192
_GRID_PER_PERIOD = 4
_SAMPLES_PER_PERIOD = 20


def _scaled(z, anchored: bool = True):
    center, half = neural_input_map(z, anchored)
    return (z - center) / half if center else z / half


def _columns(kinds, w, u, m):
    return [m * (np.sin(w * u) if k == "sin" else np.cos(w * u)) for k in kinds]


def harmonic_test(traj, template, syms: dict, candidates, jumps=()) -> dict[str, tuple[float, ...]]:
    """Frequencies (in each curve's scaled argument ``u``, as its network sees it: ``z / max|z|``, or
    ``(z - c) / h`` onto [-1, 1] for an unconstrained curve whose range excludes 0) of the significant harmonics.

    Parameters
    ----------
    traj : Trajectory
        A prepared record.
    template : EquationTemplate
    syms : dict
        Curve name -> parity ("none", "odd", "even") of every curve of the template.
    candidates : sequence of str
        The curves that may get harmonic terms.
    jumps : sequence of str
        Curves with a learned jump (a sign column among the smooth terms).

    Returns
    -------
    dict
        Curve name -> tuple of angular frequencies, for the curves that got any.

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.data import Trajectory
    >>> from charcurves.fitting import harmonic_test
    >>> from charcurves.templates import get_template
    >>> t = np.linspace(0, 60, 1000)
    >>> x, v, a = 12 * np.sin(0.3 * t), 3.6 * np.cos(0.3 * t), -1.08 * np.sin(0.3 * t)
    >>> record = Trajectory(t=t, x=x, F=a + 0.2 * v + 9.81 * np.sin(x), v=v, a=a)  # f2(x) = 9.81 sin x
    >>> found = harmonic_test(record, get_template(), {"f1": "none", "f2": "none"}, ["f1", "f2"])
    >>> {name: [round(w, 3) for w in freqs] for name, freqs in found.items()}  # sin(x) = sin(12 u), u = x / 12
    {'f2': [12.0]}
    """
    D = template.design(traj)
    E, n = D["E"], D["n"]
    # only curves that enter their equation as they are (a restoring or damping force): for a curve
    # multiplied by a signal (f1(x) x' of position damping) the periodogram in its argument picks up
    # the trajectory's own periodicity (van der Pol's limit cycle fired it at 25 dB with a gain > 50 %)
    candidates = [c for c in candidates if np.allclose(D["mult"][c], 1.0)]
    cols = [np.ones(E * n)] if E == 1 else []
    scaled, kinds_of = {}, {}
    for cname in template.curve_names:
        sym = syms[cname]
        u = np.tile(_scaled(D["args"][cname], sym != "none" or cname in jumps), E)
        scaled[cname] = u
        m = D["mult"][cname]
        kinds_of[cname] = {"none": ("sin", "cos"), "odd": ("sin",), "even": ("cos",)}[sym]
        powers = {"none": (1, 2, 3, 4, 5), "odd": (1, 3, 5), "even": (0, 2, 4)}[sym]
        cols += [m * u**k for k in powers if not (k == 0 and E == 1)]
        if cname in jumps:
            cols.append(m * np.sign(u))
    cols += list(D["scalars"].values())
    y = template.gain * D["F"] - D["y"]
    if template.free_gain:
        cols.append(D["F"])
        y = -D["y"]
    base = np.column_stack(cols)
    mults = {c: np.broadcast_to(D["mult"][c], y.shape) for c in template.curve_names}
    if y.size > HARMONIC_MAX_ROWS:
        # a long record: the test on a fixed stratified subset of its rows (a few thousand samples
        # detect any oscillation the thresholds accept; the cost of the periodogram grows with the rows)
        keep = subset_indices(y.size, HARMONIC_MAX_ROWS, seed=0)
        base, y = base[keep], y[keep]
        scaled = {c: u[keep] for c, u in scaled.items()}
        mults = {c: m[keep] for c, m in mults.items()}
    found: dict[str, list[float]] = {}
    while True:
        Q, _ = np.linalg.qr(base)
        r = y - Q @ (Q.T @ y)
        best = None
        for cname in candidates:
            if len(found.get(cname, ())) >= MAX_HARMONICS:
                continue
            u, m, kinds = scaled[cname], mults[cname], kinds_of[cname]
            span = float(u.max() - u.min())
            if span <= 0:
                continue
            hi = min(HARMONIC_PERIODS[1], n / _SAMPLES_PER_PERIOD)
            periods = np.arange(HARMONIC_PERIODS[0], hi + 1e-9, 1.0 / _GRID_PER_PERIOD)
            if periods.size == 0:
                continue
            ws = 2 * math.pi * periods / span
            F = _periodogram(Q, r, u, m, ws, kinds, dof=y.size - base.shape[1] - len(kinds))
            i = int(np.argmax(F))
            if best is None or F[i] > best[0]:
                best = (float(F[i]), cname, float(ws[i]), float(ws[1] - ws[0]) if ws.size > 1 else ws[i] / 10)
        if best is None or best[0] <= HARMONIC_F_THRESHOLD:
            break
        if float(r @ r) < HARMONIC_MIN_MISFIT * float(np.sum((y - y.mean()) ** 2)):
            break  # the smooth terms already hold the curve (a clean record: any residual is "significant")
        _, cname, w, step = best
        w = _refine(Q, r, scaled[cname], mults[cname], kinds_of[cname], w, step)
        if w in found.get(cname, ()):
            break
        grown = np.column_stack([base, *_columns(kinds_of[cname], w, scaled[cname], mults[cname])])
        Q2, _ = np.linalg.qr(grown)
        r2 = y - Q2 @ (Q2.T @ y)
        if float(r2 @ r2) > (1.0 - HARMONIC_MIN_GAIN) * float(r @ r):
            break  # significant but small: a curve the network holds, not an oscillation it cannot
        found.setdefault(cname, []).append(w)
        base = grown
    return {k: tuple(sorted(v)) for k, v in found.items()}


def _periodogram(Q, r, u, m, ws, kinds, dof: int) -> np.ndarray:
    """F statistic of the harmonic columns at each frequency, added to the columns spanned by ``Q``
    (``r``: the residual of that fit), all frequencies in one batched solve."""
    S = np.stack([m[None, :] * (np.sin(np.outer(ws, u)) if k == "sin" else np.cos(np.outer(ws, u)))
                  for k in kinds], axis=1)  # (W, k, N)
    S = S - np.einsum("wkn,nj->wkj", S, Q) @ Q.T  # project out the smooth terms
    G = np.einsum("wkn,wln->wkl", S, S) + 1e-12 * np.eye(len(kinds))
    b = np.einsum("wkn,n->wk", S, r)
    gain = np.einsum("wk,wk->w", b, np.linalg.solve(G, b[..., None])[..., 0])
    sse1 = np.maximum(float(r @ r) - gain, 1e-300)
    return (gain / len(kinds)) / (sse1 / max(dof, 1))


def _refine(Q, r, u, m, kinds, w: float, step: float) -> float:
    """The frequency within one grid step of ``w`` with the smallest residual sum of squares."""
    from scipy.optimize import minimize_scalar

    def neg_gain(x):
        return -float(_periodogram(Q, r, u, m, np.array([x]), kinds, dof=1)[0])

    res = minimize_scalar(neg_gain, bounds=(w - step, w + step), method="bounded",
                          options={"xatol": 1e-9 * w})
    return float(res.x) if res.fun <= neg_gain(w) else w
