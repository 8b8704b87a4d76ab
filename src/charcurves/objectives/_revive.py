"""Networks that equation error pruned get a way back in output error.

Equation error's evidence can prune a curve's whole network (every weight at 0, decays of 1e7)
when a term beside it (an automatic cubic, the linear term) fits the biased equation-error target
as well. Output error cannot undo that on its own: with the output layer at 0 the network's
Jacobian in its hidden layer is 0 too, and MacKay's update gives a group of zero weights an
infinite decay again, so the curve stays the term beside it even where the free run needs more
(on the zoo's sinh spring with noise on x the output-error loss stayed at 1.14 times the noise
floor; docs/zoo.md). Here such a network restarts from the curve's own initialisation with its
output weights scaled by ``REVIVE_SCALE``: the curve is unchanged to that fraction of its scale,
the Jacobian sees the hidden layer again, and the evidence decides afresh whether the network
stays (it prunes it again where the record does not support it).
"""

from __future__ import annotations

import numpy as np

__all__ = ["revive_pruned_networks", "network_pruned", "revival_needed", "REVIVE_SCALE", "PRUNED_SPREAD",
           "REVIVE_ABOVE_FLOOR"]

#: The revived network's output weights are its initialisation's times this (in units of the
#: curve's output scale): far below any noise level, large enough for a non-zero Jacobian.
REVIVE_SCALE = 1e-3

#: A member's network counts as pruned when its output varies by less than this (standard
#: deviation over the scaled training range, in units of the curve's output scale).
PRUNED_SPREAD = 1e-9


def _network_values(param, theta: np.ndarray, n: int = 201) -> tuple[np.ndarray, np.ndarray]:
    """Each member's network part over the scaled training range (a neural curve's input is divided
    by its largest magnitude: -1 to 1), ``(K, n)``, and the column through which the output bias
    enters, ``(K, n)``. The curve is linear in its output layer, so the network's values are that
    layer's columns times its weights (the bias last)."""
    import torch

    th = torch.as_tensor(theta, dtype=torch.float64)
    columns, where = param.output_layer(th, torch.linspace(-1.0, 1.0, n, dtype=torch.float64))
    values = (columns * th[:, where].unsqueeze(1)).sum(dim=-1)
    return values.numpy(), columns[:, :, -1].numpy()


def network_spread(param, theta: np.ndarray, n: int = 201) -> np.ndarray:
    """Standard deviation of each member's network part over the scaled training range, ``(K,)``."""
    return _network_values(param, theta, n)[0].std(axis=1)


def revive_pruned_networks(param, theta: np.ndarray, seed: int):
    """``(theta, rows revived)``: the members of a neural curve whose network is pruned get a fresh
    hidden layer and output weights ``REVIVE_SCALE`` times the fresh ones (the output bias and every
    part beside the network are kept); other parametrisations and members are returned as they are.

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.curves import NeuralCurve
    >>> from charcurves.objectives._revive import revive_pruned_networks
    >>> spec = NeuralCurve(hidden=(4,), symmetry="odd")
    >>> theta = np.zeros((2, spec.n_params))
    >>> theta[1, :] = 0.5  # member 1 has a live network, member 0 a pruned one
    >>> new, rows = revive_pruned_networks(spec, theta, seed=0)
    >>> rows.tolist(), bool(np.all(new[1] == theta[1])), bool(np.abs(new[0]).max() > 0)
    ([True, False], True, True)
    """
    theta = np.array(theta, dtype=float)
    if not (hasattr(param, "mlp") and hasattr(param, "output_layer") and hasattr(param, "init")):
        return theta, np.zeros(theta.shape[0], dtype=bool)
    rows = network_spread(param, theta) < PRUNED_SPREAD
    if not rows.any():
        return theta, rows
    import torch

    n_mlp = int(param.mlp.n_params)
    n_out = int(param.hidden[-1])  # the output layer: n_out weights, then its bias
    fresh = param.init(theta.shape[0], torch.Generator().manual_seed(int(seed)), torch.float64).numpy()
    hidden = slice(0, n_mlp - n_out - 1)
    out = slice(n_mlp - n_out - 1, n_mlp - 1)
    before, _ = _network_values(param, theta)
    theta[rows, hidden] = fresh[rows, hidden]
    theta[rows, out] = REVIVE_SCALE * fresh[rows, out]
    # A pruned network may still hold a level (saturated hidden units times non-zero output weights:
    # the constant of a curve such as 0.5 + x^2). The output bias takes that level back, so the
    # revived curve differs from the pruned one by the small network alone.
    after, bias_column = _network_values(param, theta)
    scale = bias_column.mean(axis=1)
    keep = rows & (np.abs(scale) > 1e-12)
    theta[keep, n_mlp - 1] += (before - after)[keep].mean(axis=1) / scale[keep]
    return theta, rows


#: Output error revives a pruned network only when the fit without it ends above the noise: its
#: segmented RMSE over this many times the measured positions' noise estimate. Chosen from the
#: zoo's tuning half (the sinh spring, pruned, ended at 1.14 times the noise; revived, 0.99) and
#: Duffing's records (at the noise without revival; revived, the networks fitted it: nn-cc+sym from
#: Savitzky-Golay, 40 dB, seed 4, worst curve 1.4e-3 against 7.0e-4).
REVIVE_ABOVE_FLOOR = 1.05


def network_pruned(param, theta: np.ndarray) -> bool:
    """True when a neural curve has a member whose network is pruned (:data:`PRUNED_SPREAD`)."""
    if not (hasattr(param, "mlp") and hasattr(param, "output_layer") and hasattr(param, "init")):
        return False
    return bool(np.any(network_spread(param, np.asarray(theta, dtype=float)) < PRUNED_SPREAD))


def revival_needed(report: dict, measured) -> tuple[bool, str]:
    """Whether output error should run again with the pruned networks revived, and why: the first
    run (without revival) ended above :data:`REVIVE_ABOVE_FLOOR` times the noise of the measured
    positions (``data.noise_variance``, the mean over the positions)."""
    from .._errors import DataError
    from ..data import Trajectory, noise_variance

    status = str(report.get("status", ""))
    if not report.get("pruned_networks") or not status.startswith(("ok", "failed: the free run did not improve")):
        return False, ""
    record = getattr(measured, "joined", measured)
    cols = [record.x] if isinstance(record, Trajectory) else list(getattr(record, "states", {}).values())
    try:
        sigma = float(np.sqrt(np.mean([noise_variance(c) for c in cols])))
    except DataError:
        return True, "revived: the record is too short to estimate its noise"
    rmse = report.get("segmented_rmse_after" if status.startswith("ok") else "segmented_rmse_before")
    if rmse is None or not np.isfinite(rmse) or not sigma > 0:
        return True, "revived: no noise estimate to compare with"
    ratio = float(rmse) / sigma
    if ratio > REVIVE_ABOVE_FLOOR:
        return True, f"revived: without them the segmented RMSE was {ratio:.3g} times the noise estimate"
    return False, f"not revived: the segmented RMSE is {ratio:.3g} times the noise estimate without them"
