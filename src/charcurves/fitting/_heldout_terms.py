"""Automatic terms chosen per term on held-out samples: a term a test added stays only where it
predicts samples that the fit was not trained on better than the network alone.

The tests of :func:`._fit_path.resolve_jumps` add terms beside the neural curves (a power of a
curve's argument, a curve's harmonics, a jump of a velocity curve). A term earns its place where
the record says little: towards the ends of a curve's argument range, where a network alone is
flattened by its weight decay and a polynomial truth's ``x^2`` or ``x^3`` carries on. So the samples
held out are those at the ends of the range: for every neural curve, the outer ``TAIL`` of its
weight in the equation at either end (of the samples, for a curve that enters alone; a curve
times a velocity is held out where the record still says something about it). Sets of the added
terms (:func:`candidates`: every subset of up to two terms, else none, each alone and all) are
fitted beside the networks on the other samples, and the set kept is the smallest whose mean
squared equation residual on the held-out samples is within ``GAIN`` (5 %) of the lowest: a term
stays only where it lowers that error by 5 %. The set kept is then fitted on the whole record
(no new fit when every term is kept: the first fit is that one).

Why not a criterion on the whole record: on the first-order system (f2 = 0.5 + x^2, 25 dB on F)
the network alone reached a LOWER loss than the network with its quadratic (0.00747 against
0.00754, effective parameters 13.4 against 10.0) while its curves were 2.6x (f2) and 3.9x (f1)
worse; AIC (``n ln(loss) + 2 gamma``) then prefers the network alone by 2.7, whatever the penalty.
The in-sample loss does not see how a curve behaves where it has no data of its own.
"""

from __future__ import annotations

import numpy as np

from ._auto_terms import describe

__all__ = ["GAIN", "TAIL", "added_terms", "candidates", "choose", "choose_terms", "heldout_mask", "layout_with",
           "term_label"]

#: the fraction of the samples held out at each end of every neural curve's argument range
TAIL = 0.05
#: the relative gain in held-out error a term must bring to stay: on the zoo's tuning half the
#: terms that changed the curves' accuracy moved it by 5-26 %, while ties (0.4-1 % apart) were as
#: often harmful as helpful (a jump on a smooth curve, a quadratic on an arctangent)
GAIN = 0.05


def added_terms(tested, plain) -> list[tuple]:
    """The terms of layout ``tested`` that ``plain`` lacks: ``("jump", curve)``, ``("power", curve, k)``,
    ``("harmonics", curve)`` (a curve's frequencies together), in the layout's order.

    Examples
    --------
    >>> from charcurves.fitting._heldout_terms import added_terms
    >>> added_terms((("f1",), (("f2", (2, 3)),), ()), ((), (("f2", (3,)),), ()))
    [('jump', 'f1'), ('power', 'f2', 2)]
    """
    jumps, powers, harmonics = tested
    p_jumps, p_powers, p_harm = plain
    p_pow = dict(p_powers)
    out: list[tuple] = [("jump", n) for n in jumps if n not in p_jumps]
    out += [("power", n, k) for n, ks in powers for k in ks if k not in p_pow.get(n, ())]
    out += [("harmonics", n) for n, ws in harmonics if ws and n not in dict(p_harm)]
    return out


def layout_with(tested, plain, terms) -> tuple:
    """The layout ``plain`` plus the ``terms`` (of :func:`added_terms`) taken from ``tested``."""
    jumps, powers, harmonics = tested
    p_jumps, p_powers, p_harm = plain
    p_pow, p_h, chosen = dict(p_powers), dict(p_harm), set(terms)
    new_jumps = tuple(n for n in jumps if n in p_jumps or ("jump", n) in chosen)
    new_powers = []
    for n, ks in powers:
        keep = tuple(k for k in ks if k in p_pow.get(n, ()) or ("power", n, k) in chosen)
        if keep:
            new_powers.append((n, keep))
    new_harm = tuple((n, ws) for n, ws in harmonics if n in p_h or ("harmonics", n) in chosen)
    return new_jumps, tuple(new_powers), new_harm


def term_label(term) -> str:
    """``"jump f1"``, ``"f2^3"``, ``"harmonics f2"``."""
    return f"{term[1]}^{term[2]}" if term[0] == "power" else f"{term[0]} {term[1]}"


def heldout_mask(record, template, names, mask, tail: float = TAIL) -> np.ndarray:
    """The fitted samples (``mask``) at the ends of the range of any curve in ``names``: sorted by the
    curve's argument, the samples at either end that hold the outer ``tail`` fraction of the
    curve's weight in the equation (the square of the signal it multiplies, summed over the
    equations; 1 per sample for a curve that enters alone, so then simply the outer ``tail`` of the
    samples). A curve that enters times a velocity (the first-order ``f2(x) x'``) is thus held out
    where the record still says something about it, not only at turning points where it says nothing."""
    D = template.design(record)
    n, E = int(D["n"]), int(D["E"])
    idx = np.flatnonzero(mask)
    out = np.zeros(n, bool)
    for name in names:
        z = np.asarray(D["args"][name], dtype=float)[:n][idx]
        w = (np.broadcast_to(np.asarray(D["mult"][name], dtype=float), (E * n,)).reshape(E, n) ** 2).sum(0)[idx]
        total = float(w.sum())
        if not total > 0:
            continue
        order = np.argsort(z, kind="stable")
        cum = np.cumsum(w[order]) / total
        ends = (cum <= tail) | (cum - w[order] / total >= 1.0 - tail)
        out[idx[order[ends]]] = True
    return out


def _heldout_error(model, record, held) -> float:
    r = np.asarray(model.force_residual(record), dtype=float)
    r = r.reshape(r.shape[0], -1)[held]
    return float(np.mean(r**2)) if r.size else float("inf")


def candidates(terms) -> list[tuple]:
    """The sets of terms fitted on the reduced record: every subset of up to two terms; of more,
    none, each alone and all (``1 + n + 1`` fits in place of ``2^n``).

    Examples
    --------
    >>> from charcurves.fitting._heldout_terms import candidates
    >>> candidates(["a", "b"])
    [(), ('a',), ('b',), ('a', 'b')]
    >>> len(candidates(["a", "b", "c", "d"]))
    6
    """
    terms = list(terms)
    out: list[tuple] = [()] + [(t,) for t in terms]
    if len(terms) > 1:
        out.append(tuple(terms))
    return out


def choose(errors: dict, gain: float = GAIN) -> tuple:
    """The set of terms to keep from ``{terms: held-out error}``: the fewest terms whose error is
    within ``gain`` of the lowest (``error * (1 - gain) <= lowest``); of those, the lowest error.

    Examples
    --------
    >>> from charcurves.fitting._heldout_terms import choose
    >>> choose({(): 0.0339, ("f1^3",): 0.00845, ("f2^2",): 0.0348, ("f1^3", "f2^2"): 0.0070})
    ('f1^3', 'f2^2')
    >>> choose({(): 0.00449, ("jump",): 0.00436})  # 3 % lower: not enough
    ()
    """
    best = min(errors.values())
    near = [c for c, e in errors.items() if e * (1.0 - gain) <= best]
    return min(near, key=lambda c: (len(c), errors[c]))


def choose_terms(records, models, masks, tested, plain, template, names, fit, tail: float = TAIL,
                 gain: float = GAIN):
    """Per record, the automatic terms to keep and the models of the kept layout.

    ``fit(indices, layouts, masks)`` fits records ``indices`` (repeats allowed) with those layouts
    and sample masks and returns their models. Each set of :func:`candidates` is fitted on the
    record less its :func:`heldout_mask` and the set kept is :func:`choose`'s. Records whose tests
    added nothing keep their model; so does a record that keeps every term (its first fit is the
    fit of that layout). Returns ``(models, layouts, notes)``; a note (for
    ``info["automatic_terms"]``) lists the terms tested and kept, the held-out mean squared
    residual of each set and the samples held out, None where nothing was added."""
    n_rec = len(records)
    notes: list = [None] * n_rec
    layouts, out = list(tested), list(models)
    terms = {i: added_terms(tested[i], plain[i]) for i in range(n_rec) if tested[i] != plain[i]}
    if not terms:
        return out, layouts, notes
    held = {i: heldout_mask(records[i], template, names, masks[i], tail) for i in terms}
    jobs = [(i, c) for i in terms for c in candidates(terms[i])]
    screened = fit([i for i, _ in jobs], [layout_with(tested[i], plain[i], c) for i, c in jobs],
                   [masks[i] & ~held[i] for i, _ in jobs])
    errors: dict = {i: {} for i in terms}
    for (i, c), m in zip(jobs, screened):
        errors[i][c] = _heldout_error(m, records[i], held[i])
    refit = []
    for i in terms:
        kept = choose(errors[i], gain)
        layouts[i] = layout_with(tested[i], plain[i], kept)
        if layouts[i] != tested[i]:
            refit.append(i)
        notes[i] = {"rule": "held-out", "tested": describe(tested[i]), "kept": [term_label(t) for t in kept],
                    "held_out_samples": int(held[i].sum()),
                    "held_out_mse": {" + ".join(term_label(t) for t in c) or "network alone": e
                                     for c, e in errors[i].items()}}
    if refit:
        for i, m in zip(refit, fit(refit, [layouts[i] for i in refit], [masks[i] for i in refit])):
            out[i] = m
    return out, layouts, notes
