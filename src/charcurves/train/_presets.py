"""Training presets: frozen settings objects handed to the one training loop.

``default`` was chosen by measurement (see docs/training-defaults.md); ``paper`` is the exact
protocol of the paper and its authors' scripts, kept for faithful reproduction.
"""

from __future__ import annotations

import dataclasses

from .._errors import ConfigError

__all__ = ["TrainingPreset", "PRESETS", "get_preset"]


@dataclasses.dataclass(frozen=True)
class TrainingPreset:
    """How neural curves are built and trained.

    Parameters
    ----------
    name : str
    hidden, activation, linear_term, powers : network shape of every curve (see NeuralCurve)
    harmonics : tuple of float or "auto"
        Harmonic terms of every neural curve (see Neural); "auto": where a periodogram of the
        equation error finds a curve oscillating over many periods of its argument.
    symmetry_mode : {"exact", "penalty"}
    lambda_sym, n_sym : weight and number of points of the symmetry penalty (paper: 10, 1000)
    dtype : {"float64", "float32"}
    scale_inputs : bool
        Divide each curve's argument by its largest magnitude (keeps parity, conditions the fit).
    scale_output : bool
        Divide the regression target by its standard deviation.
    warm_start : bool
        Start linear parts, the gain, the constant and jump heights from a least-squares fit.
    adam_steps, adam_lr : first-order phase (full batch)
    lm_max_iter, lm_tol : Levenberg-Marquardt refinement; stops when the relative decrease of
        the loss stays below ``lm_tol`` (a stall) or after ``lm_max_iter`` iterations
    stop_loss : float
        Stop when the loss falls below this (the paper: 1e-7).
    n_starts : int
        Random initialisations per model, trained together.
    combine : {"mean", "best"}
        "best" keeps the start with the lowest loss; "mean" averages the starts whose loss is
        within ``combine_tol`` (relative) of the lowest (starts stuck in a worse local minimum
        are dropped), which cancels much of the initialisation-dependent error.
    combine_tol : float
    bayesian : bool
        Bayesian regularisation (MacKay; Foresee & Hagan): the weight decay of the network
        weights is re-estimated from the evidence at every Levenberg-Marquardt step.
    decay_groups : {"shared", "per-curve", "per-layer"}
        With Bayesian regularisation: one weight decay for all networks of a model, one per
        curve (each curve's smoothness set by the evidence separately), or one per layer's
        weights and per layer's biases of each curve (MacKay's groups; the default).
    auto_jump : bool
        Whether ``jump="auto"`` may add a learned jump to the velocity curve of records with
        sticking phases (off in the paper preset: the paper's networks have none).
    auto_terms : bool
        Whether tests may add terms beside the neural curves (``powers="auto"``,
        ``harmonics="auto"``, ``jump="auto"``). False: only the terms a curve or the preset names,
        e.g. to measure a fit without the automatic terms.
    check_auto_terms : bool
        Keep a term the tests add only where it helps, by ``auto_terms_rule`` (docs/automatic-terms.md).
    auto_terms_rule : {"held-out", "aic"}
        How ``check_auto_terms`` judges the terms. ``"held-out"``: sets of the added terms (every
        subset of up to two; of more, none, each alone and all) are fitted on the record less the
        ends of every curve's range (5 % of each curve's weight in the equation at each end), and the
        smallest set whose error on those ends is within 5 % of the lowest is kept
        (``charcurves.fitting._heldout_terms``; 2 to n + 2 fits of the reduced record for n terms, one
        more of the whole record where the choice differs from the tests'). ``"aic"``: all terms or none,
        by the Akaike criterion of two fits of the whole record (``charcurves.fitting._auto_terms``).

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.systems import get_system
    >>> system = get_system("duffing")
    >>> quick = cc.PRESETS["default"].replace(n_starts=1, adam_steps=20, lm_max_iter=5)
    >>> isinstance(quick, cc.TrainingPreset), quick.hidden, quick.activation
    (True, (8,), 'softplus')
    >>> model = cc.fit(cc.corrupt(system.simulate(), 20, seed=0), method="nn-cc+sym", preset=quick)
    >>> max(cc.curve_errors(model, system.true_curves()).values()) < 0.01
    True
    """

    name: str
    hidden: tuple[int, ...] = (8,)
    activation: str = "softplus"
    linear_term: bool = True
    powers: tuple[int, ...] | str = "auto"
    harmonics: tuple[float, ...] | str = "auto"
    symmetry_mode: str = "exact"
    lambda_sym: float = 10.0
    n_sym: int = 1000
    dtype: str = "float64"
    scale_inputs: bool = True
    scale_output: bool = True
    warm_start: bool = True
    adam_steps: int = 150
    adam_lr: float = 1e-2
    lm_max_iter: int = 80
    lm_tol: float = 1e-7
    stop_loss: float = 1e-7
    n_starts: int = 6
    combine: str = "mean"
    combine_tol: float = 0.02
    auto_jump: bool = True
    auto_terms: bool = True
    check_auto_terms: bool = False
    auto_terms_rule: str = "held-out"
    bayesian: bool = True
    decay_groups: str = "per-layer"

    def __post_init__(self) -> None:
        if self.dtype not in ("float64", "float32"):
            raise ConfigError(f"dtype must be 'float64' or 'float32', got {self.dtype!r}")
        for key in ("adam_steps", "lm_max_iter", "n_sym", "n_starts"):
            if int(getattr(self, key)) < 0:
                raise ConfigError(f"{key} must be >= 0, got {getattr(self, key)}")
        if self.decay_groups not in ("shared", "per-curve", "per-layer"):
            raise ConfigError(
                f"decay_groups must be 'shared', 'per-curve' or 'per-layer', got {self.decay_groups!r}")
        if self.auto_terms_rule not in ("held-out", "aic"):
            raise ConfigError(f"auto_terms_rule must be 'held-out' or 'aic', got {self.auto_terms_rule!r}")
        if self.combine not in ("mean", "best"):
            raise ConfigError(f"combine must be 'mean' or 'best', got {self.combine!r}")
        if self.n_starts < 1:
            raise ConfigError("n_starts must be at least 1")
        if self.adam_steps == 0 and self.lm_max_iter == 0:
            raise ConfigError("a preset needs adam_steps > 0 or lm_max_iter > 0, otherwise nothing is trained")
        object.__setattr__(self, "hidden", tuple(int(h) for h in self.hidden))
        if self.powers != "auto":
            object.__setattr__(self, "powers", tuple(int(k) for k in self.powers))
        if self.harmonics != "auto":
            object.__setattr__(self, "harmonics", tuple(float(w) for w in self.harmonics))

    def replace(self, **changes) -> TrainingPreset:
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict:
        d = dataclasses.asdict(self)
        d["hidden"] = list(self.hidden)
        d["powers"] = self.powers if self.powers == "auto" else list(self.powers)
        d["harmonics"] = self.harmonics if self.harmonics == "auto" else list(self.harmonics)
        return d


PRESETS: dict[str, TrainingPreset] = {
    "default": TrainingPreset(name="default"),
    # The paper's NN-CC protocol (Sec. 2.2, App. C) as its scripts run it: two 1-100-100-100-1 ReLU
    # MLPs on raw inputs, Adam lr 1e-4 (one per net: identical to one Adam, it acts elementwise),
    # full batch, up to 20 000 epochs or loss < 1e-7, last-epoch weights, symmetry as a penalty.
    "paper": TrainingPreset(
        name="paper",
        hidden=(100, 100, 100),
        activation="relu",
        linear_term=False,
        powers=(),
        harmonics=(),
        symmetry_mode="penalty",
        lambda_sym=10.0,
        n_sym=1000,
        dtype="float32",
        scale_inputs=False,
        scale_output=False,
        warm_start=False,
        adam_steps=20000,
        adam_lr=1e-4,
        lm_max_iter=0,
        stop_loss=1e-7,
        n_starts=1,
        combine="best",
        auto_jump=False,
        bayesian=False,
    ),
}


def get_preset(preset: str | TrainingPreset | None) -> TrainingPreset:
    """A preset by name (``"default"``, ``"paper"``) or the object itself.

    Examples
    --------
    >>> from charcurves.fitting import PRESETS, get_preset
    >>> get_preset(None) is PRESETS["default"], get_preset("paper").hidden, get_preset("paper").adam_steps
    (True, (100, 100, 100), 20000)
    """
    if preset is None:
        return PRESETS["default"]
    if isinstance(preset, TrainingPreset):
        return preset
    try:
        return PRESETS[str(preset)]
    except KeyError:
        raise ConfigError(
            f"unknown preset {preset!r}; choose one of {', '.join(PRESETS)}"
        ) from None
