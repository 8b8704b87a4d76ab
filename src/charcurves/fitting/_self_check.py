"""Every fit checks itself: the loss of each equation against the noise floor of its record.

A model that captured the system leaves residuals of the size of the measurement noise, so its
equation-error loss is near the noise floor (:func:`charcurves.data.noise_floor`, the estimate
selection's inner loop uses: Savitzky-Golay residuals of the forcing and of a measured x'', or a
given SNR). A loss far above the floor (ratio > :data:`SELF_CHECK_FACTOR`) means the fit missed
something; the fit then warns, naming the likely causes in order and what to try for each.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..data import REL_FLOOR, equation_floors, noise_variance

__all__ = ["self_check", "SELF_CHECK_FACTOR", "self_check_warning"]

#: a loss more than this multiple of the noise floor gets a warning (the inner loop of model
#: selection accepts 1.5; this bound flags fits that clearly failed, not marginal ones)
SELF_CHECK_FACTOR = 10.0
#: a measured x or x' column whose Savitzky-Golay noise variance is below this fraction of its
#: variance (an SNR above 50 dB) is taken as clean by :func:`measured_state_noise`
CLEAN_COLUMN = 1e-5


def _equation_losses(model, record, mask) -> list[float]:
    """Mean squared equation residual per equation over the fitted samples (sticking phases left out)."""
    r = np.asarray(model.force_residual(record), dtype=float)
    r = r.reshape(r.shape[0], -1)
    if mask is not None and len(mask) == r.shape[0]:
        r = r[np.asarray(mask, bool)]
    return [float(np.mean(r[:, e] ** 2)) for e in range(r.shape[1])]


def _states_of(record) -> dict:
    states = getattr(record, "states", None)
    return dict(states) if states is not None else {"x": record.x}


def derivative_noise(model, raw, prepared, prepare, mask=None, seed: int = 0) -> tuple[list[float], float]:
    """The part of the floor that noise on the measured state puts into the equation through the
    estimated derivatives (and the curves), per equation; and the largest state-noise variance.

    The state's white-noise variance σ² is estimated (Savitzky-Golay residuals of each state); a
    copy of the raw record with a further N(0, σ²) on every state is prepared like the record
    (``prepare``: the same differentiator, settings and checks) and the variance of the change of
    the model's equation residual is the noise the estimate carries: the differentiators are (near)
    linear in the data, so the noise already in the record passes through the same way.
    """
    rng = np.random.default_rng(int(seed))
    states = _states_of(raw)
    sig2 = {k: noise_variance(v) for k, v in states.items()}
    noisy = {k: np.asarray(v, dtype=float) + rng.normal(scale=np.sqrt(max(sig2[k], 0.0)), size=np.shape(v))
             for k, v in states.items()}
    changes: dict[str, Any] = {"states": noisy} if getattr(raw, "states", None) is not None else {"x": noisy["x"]}
    if getattr(raw, "states", None) is None:
        changes.update(v=None, a=None)
    perturbed = prepare(raw.replace(**changes))
    r0 = np.asarray(model.force_residual(prepared), dtype=float)
    r1 = np.asarray(model.force_residual(perturbed), dtype=float)
    d = (r1 - r0).reshape(r0.shape[0], -1)
    if mask is not None and len(mask) == d.shape[0]:
        d = d[np.asarray(mask, bool)]
    return [float(np.var(d[:, e])) for e in range(d.shape[1])], float(max(sig2.values()))


def measured_state_noise(model, prepared, mask=None, seed: int = 0) -> tuple[list[float], float]:
    """The part of the floor that noise on *measured* x and x' columns puts into the equation through
    the curves (errors in variables: a curve's argument is noisy, so its value is), per equation;
    and the largest noise variance of those columns.

    Each state and velocity column's white-noise variance σ² is estimated (Savitzky-Golay
    residuals); a copy of the prepared record with a further N(0, σ²) on each of them gives the
    variance of the change of the model's equation residual, about Σ σ² f'(z)² over the curves
    (x'' is not perturbed: a measured x'' is in the floor already). A column whose estimate is below
    :data:`CLEAN_COLUMN` of its variance (50 dB) counts as clean and adds nothing: there the estimate
    is the signal's own roughness (a stick-slip velocity's kinks), not noise, and a steep curve (a
    friction jump) would turn it into a floor far too high.
    """
    rng = np.random.default_rng(int(seed))
    multi = getattr(prepared, "states", None) is not None
    fields = {"states": prepared.states, "velocities": prepared.velocities} if multi else \
        {"x": {"x": prepared.x}, "v": {"v": getattr(prepared, "v", None)}}
    sig2: dict[tuple, float] = {}
    changes: dict[str, Any] = {}
    for field, columns in fields.items():
        if not columns or all(v is None for v in columns.values()):
            continue
        noisy = {}
        for name, v in columns.items():
            v = np.asarray(v, dtype=float)
            s2 = noise_variance(v)
            s2 = s2 if s2 > CLEAN_COLUMN * float(np.var(v)) else 0.0
            sig2[(field, name)] = s2
            noisy[name] = v + rng.normal(scale=np.sqrt(s2), size=v.shape) if s2 > 0 else v
        changes[field] = noisy if multi else noisy[field]
    r0 = np.asarray(model.force_residual(prepared), dtype=float)
    r1 = np.asarray(model.force_residual(prepared.replace(**changes)), dtype=float)
    d = (r1 - r0).reshape(r0.shape[0], -1)
    if mask is not None and len(mask) == d.shape[0]:
        d = d[np.asarray(mask, bool)]
    return [float(np.var(d[:, e])) for e in range(d.shape[1])], float(max(sig2.values(), default=0.0))


def _derivative_scales(record, order: int) -> list[float]:
    """Variance of each equation's highest derivative (x'', or x' for first-order templates)."""
    if getattr(record, "forces", None) is None:
        d = getattr(record, "a", None) if order >= 2 else None
        d = d if d is not None else getattr(record, "v", None)
        return [0.0 if d is None else float(np.var(np.asarray(d, dtype=float)))]
    accs = record.accelerations or {}
    states = list(record.states)
    return [float(np.var(np.asarray(accs[s], dtype=float))) if s in accs else 0.0
            for s in (states[min(k, len(states) - 1)] for k in range(len(record.forces)))]


def self_check_warning(ratio: float, floor: float, source: str, equation: str = "", *,
                       output_error: bool = False) -> str:
    """The one-line warning of a fit whose loss is ``ratio`` times the noise floor."""
    what = "the output-error loss (free runs against the measured states)" if output_error else \
        "the equation-error loss" + (f" of equation {equation}" if equation else "")
    return (f"self-check: {what} is {ratio:.3g} times the noise floor ({floor:.3g}, {source}); "
            "a fit that captured the system is near 1. Likely causes, most likely first: "
            "(1) curve capacity: a curve too small for its law (e.g. periodic over many periods) -- try a "
            "larger network (Neural(hidden=(32, 32))) or a richer basis (--method poly-cc, --basis); "
            "(2) wrong family or missing term (e.g. a cross term f(x)*x' the family cannot hold) -- run "
            "`charcurves select` or write the term into --equation; "
            "(3) derivative estimation -- try another --derivatives (spline, savgol, spectral) or give "
            "measured v, a columns; "
            "(4) forcing scale -- check the forcing's units and gain (or learn it: --free-gain)")


def _state_floor(raw) -> tuple[float, str]:
    """Noise variance of the measured states (mean over them): Savitzky-Golay residuals, at least
    1e-4 of their variance (the 40 dB floor of a noise-free record)."""
    states = [np.asarray(v, dtype=float) for v in _states_of(raw).values()]
    s2 = float(np.mean([noise_variance(v) for v in states]))
    guard = REL_FLOOR * float(np.mean([np.var(v) for v in states]))
    return max(s2, guard), (f"Savitzky-Golay residual of the measured state{'s' if len(states) > 1 else ''}, "
                            "at least 1e-4 of its variance")


def _output_error_check(model, raw) -> dict | None:
    """The ratio of a fit by output error: its own loss (mean squared error of the segments' free runs
    against the measured states, after the refit) over the states' noise variance."""
    oe = model.info.get("output_error") or {}
    if raw is None or not str(oe.get("status", "")).startswith("ok") or oe.get("segmented_rmse_after") is None:
        return None
    floor, source = _state_floor(raw)
    loss = float(oe["segmented_rmse_after"]) ** 2
    return {"loss_over_floor": [loss / floor if floor > 0 else float("inf")], "loss_value": [loss],
            "noise_floor": [floor], "floor_source": source,
            "loss": "output error: mean squared error of the segments' free runs against the measured states"}


def self_check(model, record, mask=None, *, estimated: bool = False, snr_db: float | None = None,
               state_noise: tuple[list[float], float] | None = None, raw=None,
               state_noise_via: str = "the estimated derivatives") -> dict:
    """Add ``info["self_check"]`` to ``model`` and, when a ratio exceeds :data:`SELF_CHECK_FACTOR`,
    a line to ``info["warnings"]``; returns the check.

    Equation error: the loss is the equation-error loss (mean squared residual of each equation,
    sticking samples left out) of the model's final curves -- after post-SR -- on ``record``, the
    prepared record the fit used (the record's own derivative columns, or those the differentiator
    estimated), and the floor is :func:`charcurves.data.equation_floors`. With ``estimated``
    derivatives x'' is not taken as measured (its noise is not added to the floor); ``state_noise``
    (:func:`derivative_noise`: what the state's noise carries into the equation through the
    differentiator) is added instead. With measured derivatives, ``state_noise`` is
    :func:`measured_state_noise` (the noise of the measured x and x' columns through the curves),
    added where it is more than 1 % of a floor.

    Output error (``info["output_error"]`` finished): the model's loss (``model.loss``) may be the
    equation-error loss of the start, and the equation-error loss of the final curves on estimated
    derivatives holds the differentiator's smoothing bias, which no floor estimates (a correct
    Duffing model at 30 dB of state noise: 31 times the floor). The ratio is then output error's
    own: the mean squared error of the segments' free runs against the measured states (``raw``)
    over the states' noise variance; the equation-error figures are kept under ``equation_error``.
    """
    losses = _equation_losses(model, record, mask)
    # a measured x'' adds its noise to the floor only where the equation holds x'' (not first order)
    order = int(getattr(model.template, "order", 2))
    floors = equation_floors(record, gain=float(model.gain), snr_db=snr_db,
                             acceleration_given=not estimated and order >= 2)
    scales = _derivative_scales(record, order)
    if len(floors) != len(losses):  # one forcing column shared by several equations
        floors, scales = [floors[0]] * len(losses), [scales[0]] * len(losses)
    # the floor's noise-free part is 1e-4 (40 dB) of var(g F); a free response (F constant) has only
    # the derivative term to balance the curves, so there the same fraction of its variance stands in
    extra = list(state_noise[0]) if state_noise is not None else [0.0] * len(losses)
    if len(extra) != len(losses):
        extra = [float(np.mean(extra))] * len(losses)
    if not estimated and not any(e > 0.01 * nf.floor for e, nf in zip(extra, floors)):
        state_noise, extra = None, [0.0] * len(losses)  # measured columns without noise worth counting
    values = [nf.floor + e if nf.floor - nf.sigma2_acceleration > 0 else max(nf.floor + e, REL_FLOOR * s)
              for nf, e, s in zip(floors, extra, scales)]
    source = floors[0].source
    if state_noise is not None:
        source += (f"; plus the state's noise (variance {state_noise[1]:.3g}, Savitzky-Golay residual) through "
                   f"{state_noise_via}")
    ee: dict[str, Any] = {"loss_over_floor": [loss / f if f > 0 else float("inf") for loss, f in zip(losses, values)],
          "loss_value": losses, "noise_floor": values, "floor_source": source,
          "loss": "equation-error loss of the final curves on the prepared record (sticking samples left out)"}
    oe = _output_error_check(model, raw)
    used: dict[str, Any] = oe if oe is not None else ee
    ratios: list[float] = list(used["loss_over_floor"])
    check = {**used, "threshold": SELF_CHECK_FACTOR, "passed": bool(all(r <= SELF_CHECK_FACTOR for r in ratios)),
             # the floor holds noise of the state (through derivatives or curves, or output error's own):
             # selection's inner loop then takes these figures rather than the forcing's floor alone
             "state_noise_counted": bool(oe is not None or state_noise is not None)}
    if oe is not None:
        check["equation_error"] = ee
    model.info["self_check"] = check
    if not check["passed"] and not model.info.get("interrupted"):
        k = int(np.argmax(ratios))
        label = f"{k + 1} of {len(ratios)}" if len(ratios) > 1 else ""
        model.info["warnings"] = list(model.info.get("warnings", [])) + [
            self_check_warning(ratios[k], used["noise_floor"][k], used["floor_source"], label,
                               output_error=oe is not None)]
    return check
