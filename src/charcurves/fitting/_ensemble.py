"""Ensembles of fitted models (the uncertainty bands of :mod:`charcurves.selection` are drawn from them).

An ensemble is a set of fits that differ only by what is random or uncertain in the
identification: the training seed (``kind="seeds"``), or the noise realisation, drawn by a wild
residual bootstrap around a first fit (``kind="bootstrap"``, the default). Bands are computed
on a grid over each curve's training range from the spread of the members.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from .._errors import ConfigError

if TYPE_CHECKING:
    from ..model import FittedModel

__all__ = ["Ensemble", "fit_ensemble", "fit_ensembles", "bootstrap_records", "residual_block", "ENSEMBLE_KINDS", "MIN_MEMBERS",
           "check_band_options"]

#: Ways to draw an ensemble: training seeds only, or a wild residual bootstrap (new seeds too).
ENSEMBLE_KINDS = ("bootstrap", "seeds")
#: Fewest members from which a spread (standard deviation) means anything.
MIN_MEMBERS = 3


@dataclasses.dataclass
class Ensemble:
    """A point fit and the members drawn around it.

    Attributes
    ----------
    point : FittedModel
        The fit of the record itself (what ``CharacteristicCurves.fit`` returns).
    members : list of FittedModel
        Refits on bootstrap records (or with other seeds); before any post-SR distillation.
    record : Trajectory
        The record with the derivatives the fits used.
    kind : str

    Examples
    --------
    >>> from charcurves.data import corrupt
    >>> from charcurves.fitting import CharacteristicCurves, Ensemble, fit_ensemble
    >>> from charcurves.systems import get_system
    >>> record = corrupt(get_system("duffing").simulate(t_end=20.0, n_points=500), 20, seed=0)
    >>> ens = fit_ensemble(CharacteristicCurves.from_method(method="poly-cc"), record, 4)
    >>> isinstance(ens, Ensemble), ens.kind, ens.curve_values("f2", [0.0, 1.0]).shape
    (True, 'bootstrap', (4, 2))
    """

    point: FittedModel
    members: list[FittedModel]
    record: object
    kind: str

    def curve_values(self, name: str, z: np.ndarray) -> np.ndarray:
        """Values of curve ``name`` of every member at ``z``, shape (members, len(z))."""
        return np.stack([np.asarray(m.curves[name](z), dtype=float) for m in self.members])


def _check_members(n: int) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < MIN_MEMBERS:
        raise ConfigError(f"an ensemble needs at least {MIN_MEMBERS} members to measure a spread, got {n!r}; "
                          f"use e.g. --bands 8")
    return int(n)


def check_band_options(n, level: float) -> None:
    """Refuse an ensemble size or band level that cannot work (ConfigError naming the fix).

    Examples
    --------
    >>> from charcurves.fitting import check_band_options
    >>> check_band_options(8, 0.95)
    >>> try:
    ...     check_band_options(2, 0.95)
    ... except ValueError as exc:
    ...     print(str(exc)[:55])
    an ensemble needs at least 3 members to measure a sprea
    """
    from .._bounds import check_number

    _check_members(n)
    check_number("bands", n, label="the ensemble size (--bands)")
    if not isinstance(level, (int, float)) or not (0.0 < float(level) < 1.0):
        raise ConfigError(f"band level must be between 0 and 1 (e.g. 0.95), got {level!r}")
    check_number("bands_level", level, label="the band level (--bands-level)")


def bootstrap_records(record, model, n: int, *, random_state: int = 0, block: int | None = None) -> list:
    """Wild residual bootstrap: records whose forcing is the fitted one plus sign-flipped residuals.

    The state and its derivatives stay as they are (they define where the curves are sampled);
    the forcing becomes ``F_hat + w * e`` with ``e = F - F_hat`` the model's residual in force
    units and ``w = ±1`` at random per block of ``block`` samples. Sign flips, rather than
    resampling residuals, keep each sample's own residual size (heteroscedastic noise, sticking
    phases). Several equations (two-dof) flip each equation's forcing column with the same sign.

    ``block`` (default :func:`residual_block`: the residual's correlation length, 1 for white
    noise): a residual whose samples are correlated (noise on x, differentiated: the smoother's
    kernel spreads each sample's error over its neighbours) keeps that correlation in the copies,
    so their spread is the spread of the fit. With one sign per sample such a residual's copies
    vary 2-4 times too little (Duffing, 30 dB on x: the parity test rejected the true odd f1 in
    13 of 20 noise seeds, 1 of 20 with blocks; the zoo: ``benchmarks/bench_parity.py``).

    Examples
    --------
    >>> import numpy as np
    >>> import charcurves as cc
    >>> from charcurves.fitting import bootstrap_records
    >>> from charcurves.systems import get_system
    >>> record = cc.corrupt(get_system("duffing").simulate(t_end=20.0, n_points=500), 20, seed=0)
    >>> copies = bootstrap_records(record, cc.fit(record, method="poly-cc"), 3, random_state=0)
    >>> len(copies), bool(np.array_equal(copies[0].x, record.x)), bool(np.array_equal(copies[0].F, record.F))
    (3, True, False)
    """
    if not hasattr(model, "force_residual"):
        raise ConfigError(f"a bootstrap needs the model's residual, which a {type(model).__name__} does not give; "
                          "use kind='seeds'")
    resid = np.asarray(model.force_residual(record), dtype=float) / float(model.gain)
    names = _input_columns(record, model, resid)
    resid = resid.reshape(resid.shape[0], len(names))
    signals = getattr(record, "forces", None) or {"F": record.F}
    # the residual is x'' + ... - g F, so F - F_hat = -resid / g
    fitted = {nm: np.asarray(signals[nm], dtype=float) + resid[:, e] for e, nm in enumerate(names)}
    m = resid.shape[0]
    L = residual_block(resid) if block is None else int(block)
    if L < 1:
        raise ConfigError(f"block must be a positive number of samples, got {block!r}")
    rng = np.random.default_rng(random_state)
    out = []
    for _ in range(n):
        # one sign per block, shared by the equations: keeps the noise's correlation between them
        signs = np.repeat(rng.choice([-1.0, 1.0], size=-(-m // L)), L)[:m]
        new = {nm: fitted[nm] - signs * resid[:, e] for e, nm in enumerate(names)}
        out.append(record.replace(forces={**record.forces, **new}) if names != ["F"] else record.replace(F=new["F"]))
    return out


def residual_block(resid) -> int:
    """The block of a wild bootstrap of ``resid`` (samples, or samples x equations): the first lag
    at which every column's autocorrelation falls inside the white-noise band ``2 / sqrt(n)``, at
    most ``n // 20`` (20 blocks); 1 for white noise (95 % of white records, the sign per sample).

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.fitting import residual_block
    >>> e = np.random.default_rng(0).standard_normal(1000)
    >>> residual_block(e), residual_block(np.convolve(e, np.ones(8) / 8, mode="same"))
    (1, 8)
    """
    r = np.asarray(resid, dtype=float)
    r = r.reshape(r.shape[0], -1)
    n = r.shape[0]
    cap = max(1, n // 20)
    if n < 40:
        return 1
    from scipy.signal import correlate

    block = 1
    for col in r.T:
        u = col - col.mean()
        if not np.any(u):
            continue
        ac = correlate(u, u, mode="full", method="fft")[n - 1:n + cap]
        inside = np.nonzero(ac[1:] / ac[0] < 2.0 / np.sqrt(n))[0]
        block = max(block, int(inside[0]) + 1 if inside.size else cap)
    return int(min(block, cap))


def _input_columns(record, model, resid) -> list[str]:
    """The forcing column of each equation: ["F"] for one equation on a Trajectory, the symbols of
    the equations' inputs for several (each must be a forcing column of its own, as two-dof's)."""
    if resid.ndim == 1:
        if not hasattr(record, "F"):
            raise ConfigError("the residual bootstrap handles one-equation templates on one forcing column; "
                              "use kind='seeds' for this template")
        return ["F"]
    import sympy

    forces = getattr(record, "forces", None)
    inputs = [eq.input for eq in getattr(model.template, "equations", ())]
    names = [str(e) for e in inputs if isinstance(e, sympy.Symbol)]
    if forces is None or len(names) != len(inputs) or len(set(names)) != len(names) or \
            any(nm not in forces for nm in names) or resid.shape[1] != len(names):
        raise ConfigError("the residual bootstrap needs every equation to have one forcing column of its own "
                          "(as two-dof: F1, F2); use kind='seeds' for this template")
    return names


def fit_ensemble(estimator, record, n: int = 8, *, kind: str = "bootstrap", random_state: int | None = None,
                 block: int | None = None) -> Ensemble:
    """Fit ``record`` with ``estimator`` and draw an ensemble of ``n`` refits around it.

    Parameters
    ----------
    estimator : CharacteristicCurves
        Its settings (family, method, symmetry...) are used for every fit; it is not modified.
    record : Trajectory
    n : int
        Members (at least 3; 8 gives bands whose level is about right, see docs/selection.md).
    kind : {"bootstrap", "seeds"}
        "bootstrap": wild residual bootstrap of the forcing, each member with its own seed;
        "seeds": the same record with other training seeds (optimisation spread only).
    random_state : int, optional
        Seeds the bootstrap and the members' training; default: the estimator's.
    block : int, optional
        Samples per sign of the bootstrap (:func:`bootstrap_records`); default: the residual's
        correlation length (:func:`residual_block`).

    Returns
    -------
    Ensemble

    Examples
    --------
    >>> from charcurves.data import corrupt
    >>> from charcurves.fitting import CharacteristicCurves, fit_ensemble
    >>> from charcurves.systems import get_system
    >>> record = corrupt(get_system("duffing").simulate(t_end=20.0, n_points=500), 20, seed=0)
    >>> ens = fit_ensemble(CharacteristicCurves.from_method(method="poly-cc"), record, 4)
    >>> len(ens.members)
    4
    """
    return fit_ensembles(estimator, [record], n, kind=kind, random_state=random_state, block=block)[0]


def fit_ensembles(estimator, records, n: int = 8, *, kind: str = "bootstrap",
                  random_state: int | None = None, points: Sequence | None = None,
                  block: int | None = None) -> list[Ensemble]:
    """:func:`fit_ensemble` for several records, batched: all point fits in one training pass,
    then all members in another (neural curves of equally long records train together).
    Ctrl-C raises KeyboardInterrupt (no ensemble is made of interrupted refits).

    ``points``: models already fitted on ``records`` by ``estimator`` (e.g. a long post-SR
    fit), used as they are instead of fitting again.

    Examples
    --------
    >>> from charcurves.data import corrupt
    >>> from charcurves.fitting import CharacteristicCurves, fit_ensembles
    >>> from charcurves.systems import get_system
    >>> clean = get_system("duffing").simulate()
    >>> records = [corrupt(clean, 20, seed=s) for s in (0, 1)]
    >>> ensembles = fit_ensembles(CharacteristicCurves.from_method(method="poly-cc"), records, 3, kind="seeds")
    >>> [len(e.members) for e in ensembles]
    [3, 3]
    """
    n = _check_members(n)
    if kind not in ENSEMBLE_KINDS:
        raise ConfigError(f"unknown ensemble kind {kind!r}; choose one of {', '.join(ENSEMBLE_KINDS)}")
    seed = int(estimator.random_state if random_state is None else random_state)
    records = list(records)
    point_seeds = [seed + 1000 * k for k in range(len(records))]
    from ._pipeline import raw_fit

    if points is not None:
        points = list(points)
        prepared = [_prepared(estimator, rec) for rec in records]
        raw_points = points
    else:
        # point fits through the estimator's own path (post-SR, output error included); members are raw refits
        raw_points, prepared = raw_fit(estimator, records, point_seeds)
        points = estimator.fit_many(records, seeds=point_seeds) if _beyond_raw(estimator, records) else raw_points
    member_records, member_seeds = [], []
    for k, (rec, raw) in enumerate(zip(prepared, raw_points)):
        if kind == "seeds":
            member_records += [rec] * n
        else:
            member_records += bootstrap_records(rec, raw, n, random_state=point_seeds[k] + 7919, block=block)
        member_seeds += [point_seeds[k] + 1 + i for i in range(n)]
    # one layout for every member (the jump decision of the first point fit)
    members, _ = raw_fit(_member_estimator(estimator, raw_points[0]), member_records, member_seeds)
    if any(m.info.get("interrupted") for m in [*raw_points, *members]):
        # neural training answers Ctrl-C by returning its best weights so far; bands from
        # half-trained refits would be wrong, so the interrupt goes on to the caller instead
        raise KeyboardInterrupt
    return [Ensemble(point=points[k], members=list(members[k * n:(k + 1) * n]), record=prepared[k], kind=kind)
            for k in range(len(records))]


def _prepared(estimator, record):
    """The record with the derivatives the estimator's fit used (given ones, or estimated)."""
    from ._records import prepare_any

    _, structure, sym, method = estimator.resolve()
    return prepare_any(record, structure, sym, estimator.differentiator_value(), f"method {method}")[0]


def _beyond_raw(estimator, records) -> bool:
    """Whether the estimator's models go beyond the raw fit (post-SR, output error)."""
    from ..templates import derivatives_given
    from ..objectives import resolve_objective

    objective = resolve_objective(estimator.objective, estimator.refine, estimator.refine_options)
    if estimator.wants_post_sr():
        return True
    preset = estimator.preset_object()
    structure = estimator.resolve()[1]
    return any(objective.refines(not derivatives_given(r, structure, estimator.differentiator_value()), preset)
               for r in records)


def _member_estimator(estimator, point):
    """The estimator for members: same settings, the point fit's jump decision, given derivatives."""
    params = estimator.flat_params()
    if params.get("jump") == "auto":
        # members keep the point fit's curve layout (a jump decided on the record, not per member)
        jumps = [name for name, c in point.curves.items() if getattr(getattr(c, "spec", None), "jump", False)]
        params["jump"] = jumps or "none"
    params["differentiator"] = "auto"  # the prepared record carries the derivatives the point fit used
    params["progress"] = None
    if isinstance(params.get("symmetry"), str) and params["symmetry"].strip().lower() == "auto":
        params["symmetry"] = None  # members of an auto fit are drawn by the caller with resolved priors
    return type(estimator).from_method(**params)
