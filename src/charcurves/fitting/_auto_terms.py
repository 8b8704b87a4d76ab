"""Automatic terms that only help: a test-added term stays where it lowers the held-out error.

The tests of :func:`._fit_path.resolve_jumps` add terms beside a neural curve -- polynomial powers
(``powers="auto"``), harmonics (``harmonics="auto"``) and a learned jump (``jump="auto"``) -- from
least-squares fits on the record. A term can then displace the network it was meant to help: with
a cubic beside it, the evidence may prune the network of a tanh spring and leave ``a + b z^3``. So
where the tests added a term, the record is fitted twice on the same samples minus held-out blocks
(every third of ten contiguous blocks of time), with the tests' layout and with no automatic term,
and the terms stay only when their fit's equation error on the held-out blocks is lower (by
``HELD_OUT_MARGIN``, relative). The fit itself is then made on every sample with the layout chosen.

``TrainingPreset(auto_terms=False)`` turns the automatic terms off (only the terms a curve or the
preset names stay); ``check_auto_terms=False`` keeps whatever the tests add, unchecked.
"""

from __future__ import annotations

import numpy as np

__all__ = ["held_out_mask", "choose_layouts", "HELD_OUT_BLOCKS", "HELD_OUT_EVERY", "HELD_OUT_MARGIN"]

#: the record is cut into this many contiguous blocks of time ...
HELD_OUT_BLOCKS = 10
#: ... and every this-many-th block, starting with the second, is held out (3 of 10)
HELD_OUT_EVERY = 3
#: the automatic terms stay when they lower the held-out equation error by more than this (relative)
HELD_OUT_MARGIN = 0.0


def held_out_mask(n: int, blocks: int = HELD_OUT_BLOCKS, every: int = HELD_OUT_EVERY) -> np.ndarray:
    """The held-out samples of a record of ``n``: blocks 1, 1 + every, ... of ``blocks`` contiguous ones.

    Examples
    --------
    >>> from charcurves.fitting._auto_terms import held_out_mask
    >>> m = held_out_mask(20)
    >>> int(m.sum()), [int(i) for i in np.flatnonzero(m)[:4]]
    (6, [2, 3, 8, 9])
    """
    block = np.minimum(np.arange(n) * blocks // max(n, 1), blocks - 1)
    return (block % every) == 1


def _held_out_loss(model, record, held: np.ndarray) -> float:
    """Mean squared equation error of ``model`` on the ``held`` samples of ``record``."""
    r = np.asarray(model.force_residual(record), dtype=float)
    if r.ndim == 2 and r.shape[0] != held.size:
        r = r.T
    r = r[held]
    return float(np.mean(r**2)) if r.size else float("nan")


def choose_layouts(records, template, reps, preset, seeds, *, method: str, masks, tested, plain, fit):
    """Per record, the layout to fit: the tests' (``tested``) where its held-out error is lower, else
    ``plain`` (no automatic term), and what was compared (``info["automatic_terms"]`` of the fit).

    ``fit(records, preset, seeds, masks, layouts)`` fits records with a layout each (the one fitting
    path). Records whose tests added nothing keep their layout and are not refitted.
    """
    layouts, notes = [], []
    for i, rec in enumerate(records):
        if tested[i] == plain[i]:
            layouts.append(tested[i])
            notes.append(None)
            continue
        held = held_out_mask(rec.n_samples) & np.asarray(masks[i], bool)
        train = np.asarray(masks[i], bool) & ~held
        with_terms, without = fit([rec, rec], preset, [seeds[i], seeds[i]], [train, train], [tested[i], plain[i]])
        loss_with, loss_without = _held_out_loss(with_terms, rec, held), _held_out_loss(without, rec, held)
        keep = bool(np.isfinite(loss_with) and loss_with < (1.0 - HELD_OUT_MARGIN) * loss_without)
        layouts.append(tested[i] if keep else plain[i])
        notes.append({"tested": describe(tested[i]), "held_out_loss_with": loss_with,
                      "held_out_loss_without": loss_without, "kept": keep,
                      "held_out": f"{int(held.sum())} of {rec.n_samples} samples ({HELD_OUT_BLOCKS} blocks, every "
                                  f"{HELD_OUT_EVERY}rd from the 2nd)"})
    return layouts, notes


def describe(layout) -> dict:
    """A layout ``(jumps, powers, harmonics)`` as JSON-ready lists."""
    jumps, powers, harmonics = layout
    return {"jumps": list(jumps), "powers": {n: list(p) for n, p in powers},
            "harmonics": {n: [float(w) for w in ws] for n, ws in harmonics}}
