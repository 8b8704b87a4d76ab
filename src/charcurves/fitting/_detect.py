"""``detect_symmetry``: the parity tests of :mod:`._symmetry` for a record, with a new estimator's
settings when none is given."""

from __future__ import annotations

from ._estimator import CharacteristicCurves
from ._legacy import legacy_options
from ._symmetry import AUTO_MEMBERS, PARITY_THRESHOLD, detect_parity

__all__ = ["detect_symmetry"]


def detect_symmetry(record, *, estimator=None, n_members: int = AUTO_MEMBERS, threshold: float = PARITY_THRESHOLD,
                    random_state: int = 0, method: str = "nn-cc", objective=None, block: int | None = None,
                    **estimator_params) -> dict[str, dict]:
    """Fit unconstrained NN-CC curves with a bootstrap ensemble and test their parity.

    Parameters
    ----------
    record : Trajectory
    estimator : CharacteristicCurves, optional
        Settings to copy (family, gauge, gain, preset, derivatives...); its method and
        symmetry are replaced by unconstrained NN-CC.
    n_members : int
        Bootstrap members.
    threshold : float
        See :func:`parity_tests`.
    method : str
        An unconstrained method for the curves tested ("nn-cc"; "poly-cc" is faster).
    objective : optional
        The objective of the tested fits (default: the estimator's; "equation-error" skips the
        output-error refit of a measured record).
    block : int, optional
        Samples per sign of the residual bootstrap (default: the residual's correlation length,
        :func:`~charcurves.fitting.residual_block`; 1: a sign per sample).
    **estimator_params
        Settings for a new estimator when none is given (e.g. ``family="separable"``).

    Returns
    -------
    dict
        As :func:`parity_tests`.

    Examples
    --------
    >>> from charcurves.data import corrupt
    >>> from charcurves.fitting import detect_symmetry
    >>> from charcurves.systems import get_system
    >>> record = corrupt(get_system("duffing").simulate(t_end=20.0, n_points=500), 20, seed=0)
    >>> tests = detect_symmetry(record, method="poly-cc")  # the default, "nn-cc", takes longer
    >>> tests["f1"]["proposal"], tests["f2"]["proposal"]
    ('odd', 'odd')
    """
    if estimator is None:
        estimator = CharacteristicCurves.from_method(**legacy_options(estimator_params))
    return detect_parity(record, estimator, n_members=n_members, threshold=threshold, random_state=random_state,
                         method=method, objective=objective, block=block)
