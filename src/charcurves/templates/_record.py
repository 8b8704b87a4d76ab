"""Records in the shape a template needs: validated, with the derivatives it reads, sticking phases."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .._errors import ConfigError, DataError, IdentifiabilityError
from ._structure import EquationTemplate

__all__ = ["prepare_record", "sticking_mask", "read_record", "derivatives_given", "ESTIMATED_STICK_TOL", "REST_TOL"]


def derivatives_given(record, template: EquationTemplate, differentiator) -> bool:
    """Whether the record's own derivative columns are used (``differentiator`` "auto"/"given").

    Examples
    --------
    >>> from charcurves.templates import derivatives_given, get_template
    >>> from charcurves.systems import get_system
    >>> record = get_system("duffing").simulate()
    >>> derivatives_given(record, get_template(), "auto"), derivatives_given(record, get_template(), "spline")
    (True, False)
    >>> derivatives_given(record.replace(v=None, a=None), get_template(), "auto")
    False
    """
    from ..data import Given, MultiTrajectory, Trajectory

    wants_given = differentiator is None or isinstance(differentiator, Given) or (
        isinstance(differentiator, str) and differentiator.strip().lower() in ("auto", "given"))
    if not wants_given:
        return False
    if isinstance(record, Trajectory):
        velocities = record.v is not None
    elif isinstance(record, MultiTrajectory):
        velocities = record.velocities is not None
    else:
        return False
    return bool(record.has_derivatives or (template.order == 1 and velocities))


def prepare_record(record, template: EquationTemplate, sym: dict, differentiator, what: str,
                   without_prior: Callable | None = None):
    """Validate a record for a template and fill in the derivatives it needs.

    Parameters
    ----------
    record : Trajectory or MultiTrajectory
    template : EquationTemplate
    sym : dict
        Parity prior per curve ("none", "odd", "even"): a prior needs its argument on both sides of 0.
    differentiator : str or Differentiator
        "auto" (the record's derivative columns when present, else estimated), "given", a
        differentiator name or instance.
    what : str
        Names the fit in error messages ("method nn-cc").
    without_prior : callable, optional
        ``without_prior(name, sym)`` says how to drop the prior on ``name`` (the estimator knows its options).

    Returns
    -------
    (record, estimated)
        The record with derivatives, and whether they were estimated (a measured record).

    Examples
    --------
    >>> from charcurves.templates import get_template, prepare_record
    >>> from charcurves.systems import get_system
    >>> measured = get_system("duffing").simulate().replace(v=None, a=None)
    >>> record, estimated = prepare_record(measured, get_template(), {}, "spectral", "method poly-cc")
    >>> estimated, record.has_derivatives
    (True, True)
    """
    from ..data import MIN_SAMPLES, Given, MultiTrajectory, Trajectory, estimate_derivatives

    if not isinstance(record, (Trajectory, MultiTrajectory)):
        raise DataError(f"fit expects a Trajectory or MultiTrajectory, got {type(record).__name__}; build one with "
                        "Trajectory.from_csv or MultiTrajectory.from_csv")
    if template.multi_dof and isinstance(record, Trajectory):
        raise DataError(f"the {template.family} template uses {', '.join(template.states + template.forces)}; give a "
                        "multi-DOF record (MultiTrajectory, CSV columns t,x1,x2,F1,F2)")
    if isinstance(record, MultiTrajectory):
        missing = [s for s in template.states if s not in record.states]
        missing += [f for f in template.forces if f not in record.forces]
        if missing:
            raise DataError(f"the template uses {', '.join(missing)}, which the record lacks; the record has "
                            f"{', '.join(list(record.states) + list(record.forces))}")
    record.require_samples(MIN_SAMPLES, what)
    name = differentiator if differentiator is not None else "auto"
    given_asked = isinstance(name, Given) or (isinstance(name, str) and name.strip().lower() == "given")
    have = derivatives_given(record, template, "given")
    if given_asked and not have and template.order > 0:
        if template.family == "separable":
            raise DataError("--derivatives given needs v and a columns in the data; "
                            "use --derivatives spline|spectral|savgol to estimate them")
        raise DataError("--derivatives given needs the derivative columns (v, a or v1, a1, ...) in the data; "
                        "use --derivatives spline|spectral|savgol to estimate them")
    estimated = False
    if template.order > 0 and not derivatives_given(record, template, name):
        method = "auto" if given_asked else name
        estimated = True
        if isinstance(record, Trajectory):
            record = estimate_derivatives(record.replace(v=None, a=None), method)
        else:
            xs, vs, as_ = {}, {}, {}
            for s in record.states:
                one = estimate_derivatives(record.dof(s).replace(v=None, a=None), method)
                xs[s], vs[s], as_[s] = one.x, one.v, one.a
            record = record.replace(states=xs, velocities=vs, accelerations=as_)
    try:
        template.check_excitation(record)
    except DataError as exc:  # no excitation: the data cannot determine the curves at all
        raise IdentifiabilityError(f"no excitation: {exc}") from None
    if template.free_gain:
        design = template.design(record)
        inputs = design["F"].reshape(design["E"], design["n"])
        # g is shared by the equations: one equation with a varying input is enough to fix it
        if all(np.ptp(row) == 0 for row in inputs):
            forces = ", ".join(template.forces) or "input"
            noun = "forcings" if len(template.forces) > 1 else "forcing"
            raise IdentifiabilityError(
                f"the {noun} {forces} {'are' if len(template.forces) > 1 else 'is'} constant over the record, so the "
                "gain g cannot be told apart from a constant offset (not identifiable); drop --free-gain "
                "(free_gain=False) or give a record with varying forcing"
            )
    for cname, z in template.arguments_of(record).items():
        if sym.get(cname, "none") != "none" and (z.min() >= 0 or z.max() <= 0):
            fix = without_prior(cname, sym) if without_prior is not None else "drop it"
            where = "the record as the differentiator smoothed it" if estimated else "the record"
            raise IdentifiabilityError(
                f"an {sym[cname]} prior on {cname} needs its argument {template.arguments[cname]} on both "
                f"sides of 0, but {where} covers only [{z.min():.3g}, {z.max():.3g}], so the prior can be "
                f"neither checked nor used; {fix} or give a record that crosses 0"
                + (" (a record whose noise swamps the signal smooths to its slow part)" if estimated else "")
            )
    return record, estimated


#: |x'| threshold of the sticking test on estimated derivatives, relative to max|x'| (given
#: derivatives: exact zeros, 1e-12)
ESTIMATED_STICK_TOL = 0.05
#: a sticking run rests: its median |x''| is at most this fraction of max|x''|
REST_TOL = 0.1


def sticking_mask(traj, *, rel_tol: float | None = None, min_run: int = 3, rest_tol: float = REST_TOL) -> np.ndarray:
    """Samples where the mass sticks (dry friction): x' = 0 over a run of samples.

    There the friction force is set-valued (any value with |f| <= mu*N), so these samples only
    bound f1 and must not be fitted as points of the curve. A run counts when (1) |x'| stays
    within ``rel_tol`` of max|x'| for at least ``min_run`` samples: exact zeros (1e-12) for given
    derivatives, :data:`ESTIMATED_STICK_TOL` (5 %) for estimated ones; (2) the velocity does not
    sweep that band (the least-squares trend of x' over the run changes by at most the band's
    half-width, where a smooth turning point of a moving mass crosses it whole); (3) the mass
    rests (the median |x''| over the run is at most ``rest_tol`` of max|x''|); and (4), for a
    tolerance above exact zeros, x'' does not follow the forcing over the run (its trend is at most
    half the forcing's: a mass held by friction does not respond, one that merely slows down
    does). Records without x'' skip (3) and (4).

    Examples
    --------
    >>> from charcurves.systems import get_system
    >>> from charcurves.templates import sticking_mask
    >>> record = get_system("stick-slip").simulate()
    >>> mask = sticking_mask(record)
    >>> mask.shape, round(float(mask.mean()), 2)
    ((1000,), 0.37)
    >>> int(sticking_mask(get_system("duffing").simulate(), rel_tol=0.05).sum())
    0
    """
    if getattr(traj, "v", None) is None:  # multi-DOF records: sticking is not detected (see docs/families.md)
        return np.zeros(traj.n_samples, dtype=bool)
    v = np.asarray(traj.v, dtype=float)
    if rel_tol is None:
        rel_tol = 1e-12
    thresh = rel_tol * max(float(np.max(np.abs(v))), 1e-300)
    small = np.abs(v) <= thresh
    if not small.any():
        return small
    t = np.asarray(traj.t, dtype=float)
    a = getattr(traj, "a", None)
    a = None if a is None else np.asarray(a, dtype=float)
    a_max = 0.0 if a is None else float(np.max(np.abs(a)))
    forcing = getattr(traj, "F", None)
    forcing = None if forcing is None or rel_tol <= 1e-9 else np.asarray(forcing, dtype=float)
    mask = np.zeros_like(small)
    idx = np.flatnonzero(np.diff(np.concatenate([[0], small.astype(int), [0]])))
    for start, stop in zip(idx[::2], idx[1::2]):
        if stop - start < min_run:  # a single crossing of zero is not sticking
            continue
        tt, vv = t[start:stop], v[start:stop]
        span = float(tt[-1] - tt[0])
        trend = np.polyfit(tt - tt.mean(), vv, 1)[0] * span if span > 0 else 0.0
        if abs(trend) > thresh:  # the velocity sweeps the band: a turning point, not a stop
            continue
        if a is not None and a_max > 0 and float(np.median(np.abs(a[start:stop]))) > rest_tol * a_max:
            continue  # accelerating through x' = 0: the mass does not rest
        if a is not None and forcing is not None and span > 0:
            # held by friction, x'' stays put while the forcing moves; a mass that merely slows down
            # follows the forcing (x, x' frozen: x'' changes as F does)
            trend_a = np.polyfit(tt - tt.mean(), a[start:stop], 1)[0] * span
            trend_f = np.polyfit(tt - tt.mean(), forcing[start:stop], 1)[0] * span
            if abs(trend_a) > 0.5 * abs(trend_f):
                continue
        mask[start:stop] = True
    return mask


def read_record(path, *, family: str = "separable", equation: str | None = None, time_col: str | None = "t",
                x_col: str = "x", force_col: str = "F", sample_rate=None, rows=None):
    """Read a CSV record in the shape the template needs: a Trajectory (t,x,F[,v,a]) or, for
    multi-DOF templates, a MultiTrajectory (t,x1,x2,F1,F2[,v1,a1,v2,a2]).

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from charcurves.systems import get_system
    >>> from charcurves.templates import read_record
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "duffing.csv"
    >>> get_system("duffing").simulate().to_csv(path)
    >>> record = read_record(path)
    >>> type(record).__name__, record.n_samples
    ('Trajectory', 1000)
    """
    from ..data import MultiTrajectory, Trajectory
    from ._families import get_template

    template = get_template(family, equation=equation)
    if template.multi_dof:
        if sample_rate is not None:
            raise ConfigError("--sample-rate is not supported for multi-DOF records; give a time column t")
        return MultiTrajectory.from_csv(path, states=template.states, forces=template.forces, time_col=time_col,
                                        rows=rows)
    return Trajectory.from_csv(path, time_col=time_col, x_col=x_col, force_col=force_col, sample_rate=sample_rate,
                               rows=rows)
