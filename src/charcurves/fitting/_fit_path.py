"""The one fitting path: prepared records + a template with a representation per curve -> fitted models.

Which fitter runs depends only on the representations: every curve Symbolic -> symbolic regression
(SR or SR-CC); every curve linear in its parameters -> one least-squares (or pysindy sparse)
solve; otherwise -> the batched gradient trainer, where linear curves train beside neural ones.
The same fitters serve every template (the separable family is a template like the others).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .._errors import ConfigError
from ..curves import neural_input_map
from ..templates import ESTIMATED_STICK_TOL, EquationTemplate, sticking_mask
from ..train import TrainingPreset, fit_gradient, fit_linear
from ._harmonics import harmonic_test
from ._sticking import sticking_masks
from ._symbolic_fit import fit_symbolic, unfitted_symbolic

__all__ = ["fit_records", "dry_friction_test", "JUMP_F_THRESHOLD", "fitter_kind", "sticking_masks"]

#: F statistic above which a jump at zero velocity is significant (chi2(1) quantile, p = 0.001)
JUMP_F_THRESHOLD = 10.83


def fitter_kind(reps: dict) -> str:
    """"symbolic", "linear" or "gradient" for a mapping of curve name -> representation."""
    kinds = {r.kind for r in reps.values()}
    if "symbolic" in kinds:
        if kinds != {"symbolic"}:
            raise ConfigError("Symbolic curves are found by symbolic regression and cannot be mixed with trained "
                              "curves in one fit; use Symbolic for every curve (SR-CC) or distil trained curves "
                              "with post_sr")
        return "symbolic"
    return "linear" if kinds == {"linear"} else "gradient"


def dry_friction_test(traj, template: EquationTemplate) -> tuple[float, float]:
    """F statistic and height of a jump at zero velocity, by least squares.

    The target g F - x'' is regressed on smooth odd and even powers of every curve's argument
    (degree 5), with and without sign(x'); the F statistic of the added column measures how much a
    jump explains beyond smooth curves. Smooth systems give F of order 1 whatever the noise level
    (their curves lie in the span), dry friction gives tens to thousands.

    Examples
    --------
    >>> from charcurves.fitting import dry_friction_test
    >>> from charcurves.systems import get_system
    >>> from charcurves.templates import get_template
    >>> F_smooth, _ = dry_friction_test(get_system("duffing").simulate(), get_template())
    >>> F_dry, height = dry_friction_test(get_system("stick-slip").simulate(), get_template())
    >>> F_smooth < 10 < F_dry, round(height, 2)
    (True, 0.79)
    """
    velocity = template.velocity_curves
    if not velocity or template.n_equations != 1:
        return 0.0, 0.0
    D = template.design(traj)
    cols = [np.ones(D["n"])]
    for z in D["args"].values():
        u = z / max(float(np.max(np.abs(z))), 1e-300)
        cols += [u, u**2, u**3, u**5]
    base = np.column_stack(cols)
    X = np.column_stack([base, np.sign(D["args"][velocity[0]])])
    y = template.gain * D["F"] - D["y"]
    c0, *_ = np.linalg.lstsq(base, y, rcond=None)
    c1, *_ = np.linalg.lstsq(X, y, rcond=None)
    sse0 = float(np.sum((y - base @ c0) ** 2))
    sse1 = float(np.sum((y - X @ c1) ** 2))
    dof = D["n"] - X.shape[1]
    if sse1 <= 0 or dof <= 0:
        return 0.0, 0.0
    return (sse0 - sse1) / (sse1 / dof), float(c1[-1])


#: F above which an unconstrained curve gets a quadratic term. Stricter than the 0.1 % point of the
#: other tests: on a measured record the derivatives are estimated, their errors are correlated and
#: F's null distribution is wider (Duffing's odd f2 reached 28 at 20 dB noise on x), while a real
#: quadratic stands far above it (the first-order f2 = 0.5 + x^2: 2300-3400 at 30-40 dB).
QUADRATIC_F_THRESHOLD = 100.0


def resolve_jumps(reps: dict, records, template: EquationTemplate, estimated: list[bool], preset: TrainingPreset,
                  automatic: bool = True):
    """Per record, the layout of the neural curves: ``(jumps, powers, harmonics)`` -- the curves that get
    a learned jump (``jump="auto"`` decided per record), the polynomial terms of each (``powers="auto"``:
    :func:`nonlinearity_test`) and their harmonic frequencies in the scaled argument (``harmonics="auto"``:
    :func:`harmonic_test`). ``automatic=False`` (or ``preset.auto_terms`` off): no term that a test
    would add, only those the curves or the preset name."""
    automatic = automatic and preset.auto_terms
    out = []
    for rec, est in zip(records, estimated):
        layout = []
        for name, rep in reps.items():
            jump = getattr(rep, "jump", False)
            if rep.kind != "neural" or jump is False:
                continue
            if jump is True:
                layout.append(name)
            elif automatic and preset.auto_jump and name in template.velocity_curves and (
                    sticking_mask(rec, rel_tol=ESTIMATED_STICK_TOL if est else None).any()
                    or dry_friction_test(rec, template)[0] > JUMP_F_THRESHOLD):
                layout.append(name)
        powers = []
        for name, rep in reps.items():
            if rep.kind != "neural":
                continue
            setting = rep.powers_setting(preset)
            if setting != "auto":
                powers.append((name, tuple(setting)))
            elif automatic and name not in layout:
                # even curves may get a quadratic, odd ones a cubic, unconstrained ones either or both
                # (a convex curve such as 0.5 + x^2 is then carried by its term up to the range's ends,
                # where a network alone is flattened by its weight decay if the record says little there)
                sym = rep.symmetry_name
                ks = (2,) if sym == "even" else (3,) if sym == "odd" else (2, 3)
                chosen = tuple(k for k in ks if nonlinearity_test(rec, template, reps, name, k, layout)
                               > (QUADRATIC_F_THRESHOLD if sym == "none" and k == 2 else JUMP_F_THRESHOLD))
                if chosen:
                    powers.append((name, chosen))
        out.append((tuple(layout), tuple(powers), _harmonics(reps, rec, template, preset, layout, automatic)))
    return out


def _harmonics(reps: dict, rec, template: EquationTemplate, preset: TrainingPreset, jumps,
               automatic: bool = True) -> tuple:
    """``((name, frequencies in u), ...)`` for the neural curves of one record."""
    neural = {n: r for n, r in reps.items() if r.kind == "neural"}
    fixed, auto = {}, []
    for name, rep in neural.items():
        setting = rep.harmonics_setting(preset)
        if setting == "auto":
            if automatic:
                auto.append(name)
        elif setting:
            fixed[name] = setting
    D = template.design(rec) if fixed else None
    out = {}
    for name, ws in fixed.items():
        assert D is not None  # built above whenever there are fixed frequencies
        scale = rep_scale(neural[name], D["args"][name], preset, jump=name in jumps)
        out[name] = tuple(float(w) * scale for w in ws)
    if auto:
        syms = {n: getattr(r, "symmetry_name", "none") for n, r in reps.items()}
        if preset.symmetry_mode != "exact":
            syms = {n: "none" for n in syms}
        found = harmonic_test(rec, template, syms, auto, jumps)
        if found and not preset.scale_inputs:  # the test works on the network's u of a scaled input; the network on z
            D = template.design(rec)
            found = {n: tuple(w / neural_input_map(D["args"][n], syms[n] != "none" or n in jumps)[1] for w in ws)
                     for n, ws in found.items()}
        out.update(found)
    return tuple((n, out[n]) for n in reps if n in out)


def rep_scale(rep, z, preset: TrainingPreset, jump: bool | None = None) -> float:
    """The input scale of a curve's argument (``u = (z - center) / scale``)."""
    return float(rep.scaling(z, preset, jump=jump)[1])


def _unit(z, anchored: bool):
    """A curve's argument as its network sees it (:func:`~charcurves.curves.neural_input_map`)."""
    center, half = neural_input_map(z, anchored)
    return (z - center) / half if center else z / half


def nonlinearity_test(traj, template: EquationTemplate, reps: dict, name: str, power: int, jumps) -> float:
    """F statistic of ``m z^power`` for curve ``name`` in a least-squares fit of the equation whose
    curves are otherwise linear (odd curves), constant-plus-quadratic (even) or linear-plus-quadratic
    (unconstrained; a quadratic of an unconstrained curve is tested beside its cubic, so that an odd
    cubic such as Duffing's is not mistaken for one), with a sign column for each learned jump: large
    when the curve is clearly nonlinear (Duffing's x^3), of order 1 when it is linear (damping, a
    linear spring)."""
    D = template.design(traj)
    E = D["E"]
    cols = [np.ones(E * D["n"])] if E == 1 else []
    for cname in template.curve_names:
        sym = reps[cname].symmetry_name
        z = np.tile(_unit(D["args"][cname], sym != "none" or cname in jumps), E)
        m = D["mult"][cname]
        if sym != "even":
            cols.append(m * z)
        if sym != "odd":
            cols += [m, m * z**2] if cname != name or power != 2 else [m]
        if cname == name and sym not in ("odd", "even") and power == 2:
            cols.append(m * z**3)  # unconstrained: the quadratic is tested beside the cubic (Duffing's x^3)
        if cname in jumps:
            cols.append(m * np.sign(z))
    cols += list(D["scalars"].values())
    base = np.column_stack(cols)
    z = np.tile(_unit(D["args"][name], reps[name].symmetry_name != "none" or name in jumps), E)
    X = np.column_stack([base, D["mult"][name] * z**power])
    y = template.gain * D["F"] - D["y"]
    if template.free_gain:
        base, X = np.column_stack([base, D["F"]]), np.column_stack([X, D["F"]])
        y = -D["y"]
    c0, *_ = np.linalg.lstsq(base, y, rcond=None)
    c1, *_ = np.linalg.lstsq(X, y, rcond=None)
    sse0 = float(np.sum((y - base @ c0) ** 2))
    sse1 = float(np.sum((y - X @ c1) ** 2))
    dof = y.size - X.shape[1]
    if sse1 <= 0 or dof <= 0:
        return 0.0
    return (sse0 - sse1) / (sse1 / dof)


def fit_records(records, template: EquationTemplate, reps: dict, preset: TrainingPreset, seeds, *, method: str,
                masks, jumps, options: dict, sr_options: dict | None, device: str = "cpu",
                threads: int | None = None, progress: Callable | None = None) -> list:
    """Fit every record with the fitter the representations call for (module docstring)."""
    kind = fitter_kind(reps)
    if kind == "symbolic":
        return _fit_symbolic_records(records, template, reps, seeds, method=method, masks=masks, options=options,
                                     sr_options=sr_options, progress=progress)
    if kind == "linear":
        constant = bool(options.get("constant", True))
        return [fit_linear(rec, template, reps, method=method, mask=m, constant=constant)
                for rec, m in zip(records, masks)]
    out: list = [None] * len(records)
    groups: dict[tuple, list[int]] = {}
    for i, rec in enumerate(records):
        groups.setdefault((rec.n_samples, jumps[i]), []).append(i)
    for (_, (layout, powers, harmonics)), idx in groups.items():
        models = fit_gradient([records[i] for i in idx], template, reps, preset, [int(seeds[i]) for i in idx],
                              method=method, masks=[masks[i] for i in idx], jumps=layout, powers=dict(powers),
                              harmonics=dict(harmonics),
                              device=device, threads=threads, progress=progress)
        for i, m in zip(idx, models):
            out[i] = m
    return out


def _fit_symbolic_records(records, template, reps, seeds, *, method, masks, options, sr_options, progress=None) -> list:
    """One symbolic fit per record, in turn. Ctrl-C or SIGTERM stops at once: the record being fitted
    keeps what its searches found (or, when none returned, gets no curves), and the records after it
    are not searched (no curves, ``stopped_by="not fitted: interrupted"``); interrupted before any
    record was fitted, the KeyboardInterrupt goes on (there is nothing to keep)."""
    sr_keys = ("outer_iterations", "inner_generations", "tol")
    opts = {k: v for k, v in options.items() if k in sr_keys}
    out: list = []
    for rec, s, m in zip(records, seeds, masks):
        if out and out[-1].info.get("interrupted"):
            out.append(unfitted_symbolic(rec, template, method=method, mask=m))
            continue
        try:
            out.append(fit_symbolic(rec, template, reps, method=method, mask=m, options=opts, sr_options=sr_options,
                                    random_state=int(s), progress=progress))
        except KeyboardInterrupt:
            if not out:
                raise
            out.append(unfitted_symbolic(rec, template, method=method, mask=m))
    return out
