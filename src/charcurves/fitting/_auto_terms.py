"""Automatic terms that only help: a test-added term stays where the fit with it is the better model.

The tests of :func:`._fit_path.resolve_jumps` add terms beside a neural curve -- polynomial powers
(``powers="auto"``), harmonics (``harmonics="auto"``) and a learned jump (``jump="auto"``) -- from
least-squares fits on the record. A term can then displace the network it was meant to help: with
a cubic beside it, the evidence may prune the network of a tanh spring and leave ``a + b z^3``, or
training may settle with the term in a worse minimum. So where the tests added a term, the record
is fitted a second time with no automatic term, and the terms stay only when their fit has the
lower Akaike criterion ``n ln(loss) + 2 gamma`` (``gamma``: the evidence's effective number of
parameters of the fit; a fit without Bayesian regularisation counts its added terms), an estimate
of the error on data the fit has not seen. Both fits are of the whole record: the one kept is the
answer, no third fit is made.

This is ``TrainingPreset(auto_terms_rule="aic")``; the default rule chooses per term on held-out
samples (:mod:`._heldout_terms`), since on polynomial truths the whole-record criterion dropped
terms the curves need. ``TrainingPreset(auto_terms=False)`` turns the automatic terms off (only
the terms a curve or the preset names stay); ``check_auto_terms=False`` keeps whatever the tests
add, unchecked.
"""

from __future__ import annotations

import numpy as np

__all__ = ["aic", "check_layouts", "describe"]


def aic(model, n: int, extra: int = 0) -> float:
    """``n ln(loss) + 2 gamma`` of a fitted model over ``n`` fitted samples (``gamma``: its effective
    parameters from the evidence, else ``extra``).

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> from charcurves.fitting._auto_terms import aic
    >>> round(aic(SimpleNamespace(loss=0.01, info={"effective_parameters": 4.0}), 100), 2)
    -452.52
    """
    gamma = (getattr(model, "info", None) or {}).get("effective_parameters")
    gamma = float(extra) if gamma is None else float(gamma)
    return float(n * np.log(max(float(model.loss), 1e-300)) + 2.0 * gamma)


def _n_terms(layout) -> int:
    jumps, powers, harmonics = layout
    return len(jumps) + sum(len(p) for _, p in powers) + 2 * sum(len(w) for _, w in harmonics)


def check_layouts(records, models, masks, tested, plain, refit, n_equations: int = 1):
    """The models to keep: where the tests added terms (``tested[i] != plain[i]``), the fit without
    them (``refit(indices)``: the models of those records fitted with ``plain``) replaces the fit
    with them unless the latter has the lower :func:`aic`. Returns ``(models, notes)``; a note (for
    ``info["automatic_terms"]``) says what was tested and compared, None where nothing was added."""
    idx = [i for i in range(len(records)) if tested[i] != plain[i]]
    notes: list = [None] * len(records)
    if not idx:
        return list(models), notes
    others = dict(zip(idx, refit(idx)))
    out = list(models)
    for i in idx:
        n = int(np.count_nonzero(masks[i])) * max(1, int(n_equations))
        a_with = aic(models[i], n, _n_terms(tested[i]))
        a_without = aic(others[i], n, 0)
        keep = bool(np.isfinite(a_with) and a_with < a_without)
        if not keep:
            out[i] = others[i]
        notes[i] = {"tested": describe(tested[i]), "kept": keep, "aic_with": a_with, "aic_without": a_without,
                    "loss_with": float(models[i].loss), "loss_without": float(others[i].loss)}
    return out, notes


def describe(layout) -> dict:
    """A layout ``(jumps, powers, harmonics)`` as JSON-ready lists."""
    jumps, powers, harmonics = layout
    return {"jumps": list(jumps), "powers": {n: list(p) for n, p in powers},
            "harmonics": {n: [float(w) for w in ws] for n, ws in harmonics}}
