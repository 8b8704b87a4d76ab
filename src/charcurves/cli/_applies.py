"""Options that do not apply to the rest of the command line are an error, not silently ignored.

Issue 50: ``fit --basis ... --method poly-cc`` fitted polynomials and dropped the basis without a
word, ``--bands-level`` without ``--bands`` computed no bands, ``--refine-substeps`` with
``--objective equation-error`` ran no output error. Each such combination is refused here, before
any work, with one line naming the option, why it does not apply and the fix (exit 2). Options
whose default is a value (``--bands-kind bootstrap``) are parsed with the default ``None``, so that
one given explicitly can be told from the default; :func:`check_options_apply` fills the defaults in.
"""

from __future__ import annotations

from typing import Any

from ._common import UsageError

__all__ = ["check_options_apply", "DEFAULTS"]

#: the defaults of the options parsed as None, by command and attribute
DEFAULTS: dict[str, dict[str, Any]] = {
    "fit": {"noisy_side": "force", "truth_variant": "paper", "bands_kind": "bootstrap", "bands_level": 0.95},
    "report": {"truth_variant": "paper"},
    "simulate": {"noise_on": "force", "seed": 0},
}

_SR_FLAGS = (("sr_engine", "--sr-engine"), ("sr_generations", "--sr-generations"),
             ("sr_populations", "--sr-populations"), ("sr_max_size", "--sr-max-size"),
             ("sr_operators", "--sr-operators"))
_OE_FLAGS = (("refine_hold", "--refine-hold"), ("refine_substeps", "--refine-substeps"),
             ("segment_length", "--segment-length"))


def _refuse(command: str, option: str, why: str, fix: str) -> None:
    raise UsageError(f"{option} does not apply here: {why}; {fix} (see 'charcurves {command} --help')")


#: what a hidden-state fit (``--measured``) does not use, with each option's value when not given
_NOT_HIDDEN = (("family", "--family", "separable"), ("sym", "--sym", None), ("gauge", "--gauge", None),
               ("noisy_side", "--noisy-side", None), ("preset", "--preset", "default"),
               ("derivatives", "--derivatives", "auto"), ("jump", "--jump", "auto"), ("basis", "--basis", None),
               ("keep_sticking", "--keep-sticking", False),
               ("x_col", "--x-col", "x"), ("force_col", "--force-col", "F"), ("sample_rate", "--sample-rate", None),
               ("long_record", "--long-record", False), ("truth", "--truth", None), ("threads", "--threads", None),
               ("device", "--device", "cpu"), ("objective", "--objective", None), ("refine", "--refine", None),
               *((key, flag, None) for key, flag in _OE_FLAGS), ("snr", "--snr", None), ("bands", "--bands", None),
               ("report", "--report", False))


#: the --method values of a hidden-state fit: polynomial (the default) or neural curves
HIDDEN_METHODS = ("poly-cc", "nn-cc")


def _check_hidden(a) -> None:
    """``--measured`` runs its own output-error fit of a state-space template: the options of the other
    fits do not reach it (before: ``--bands``, ``--method``, ``--sym`` ... were dropped without a word)."""
    if getattr(a, "measured", None) is None:
        if getattr(a, "start", "growing") != "growing":
            _refuse("fit", "--start", "it chooses the starts of a hidden-state fit, and --measured is not given",
                    "add --measured STATE=COLUMN (with --equation) or drop --start")
        if getattr(a, "post_sr", False):
            _refuse("fit", "--post-sr", "it distils the curves of a hidden-state fit, and --measured is not given",
                    "add --measured STATE=COLUMN or choose a +post-sr --method (e.g. nn-cc+post-sr)")
        return
    for key, flag, unset in _NOT_HIDDEN:
        if getattr(a, key, unset) != unset:
            _refuse("fit", flag, "a hidden-state fit (--measured) takes the record, --equation, --free-gain, --start, "
                                 "--method poly-cc or nn-cc, --post-sr, --seed, --time-col and --rows only",
                    f"drop {flag}")
    if getattr(a, "method", None) not in (None, *HIDDEN_METHODS):
        _refuse("fit", "--method", f"a hidden-state fit (--measured) learns its curves as {' or '.join(HIDDEN_METHODS)}, "
                                   f"not {a.method}", "give --method nn-cc or poly-cc (and --post-sr for closed forms)")
    if not getattr(a, "post_sr", False):
        given = [flag for key, flag in _SR_FLAGS if getattr(a, key, None) is not None]
        if given:
            _refuse("fit", given[0], "a hidden-state fit runs symbolic regression only with --post-sr",
                    f"add --post-sr or drop {given[0]}")


def _check_fit(a) -> None:
    from .._method_table import METHODS

    _check_hidden(a)
    # a hidden-state fit's --method names its curves, and its SR is --post-sr's (checked above)
    spec = METHODS.get(a.method) if a.method is not None and getattr(a, "measured", None) is None else None
    if a.basis is not None and a.method != "parametric":
        _refuse("fit", "--basis", f"it gives the functions of --method parametric, and the method is "
                                  f"{a.method or 'the default (nn-cc)'}", "add --method parametric or drop --basis")
    if spec is not None and not spec["post_sr"] and spec["representation"] not in ("sr", "sr-cc"):
        given = [flag for key, flag in _SR_FLAGS if getattr(a, key, None) is not None]
        if given:
            _refuse("fit", given[0], f"method {a.method} runs no symbolic regression (SR runs in sr, sr-cc, "
                                     "sr-cc+refit and the +post-sr methods)", f"drop {given[0]} or choose such a method")
    refine = (a.refine or "").strip().lower()
    if a.objective == "equation-error" or refine in ("none", "equation-error"):
        given = [flag for key, flag in _OE_FLAGS if getattr(a, key, None) is not None]
        if given:
            asked = "--objective equation-error" if a.objective == "equation-error" else f"--refine {a.refine}"
            _refuse("fit", given[0], f"it sets the output-error refit, which {asked} turns off",
                    f"drop {given[0]} or use --objective output-error (or auto)")
    if a.bands == "posterior" and a.bands_kind is not None:
        _refuse("fit", "--bands-kind", "it chooses the refits of --bands N, and --bands posterior refits nothing",
                "drop --bands-kind or give --bands 8")
    if a.bands is None:
        for key, flag in (("bands_kind", "--bands-kind"), ("bands_level", "--bands-level")):
            if getattr(a, key) is not None:
                _refuse("fit", flag, "no uncertainty bands are computed without --bands", f"add --bands (posterior) or --bands 8 (bootstrap), or drop {flag}")
    if a.truth is None and a.truth_variant is not None:
        _refuse("fit", "--truth-variant", "it chooses the parameters of --truth, which is not given",
                "add --truth SYSTEM or drop --truth-variant")
    if a.noisy_side is not None and not a.free_gain and a.equation is None and not (spec is not None and
                                                                                    spec.get("free_gain")):
        _refuse("fit", "--noisy-side", "it chooses the side regressed on when the gain is learned, and the gain is "
                                       "fixed", "add --free-gain or drop --noisy-side")


def _check_report(a) -> None:
    if a.truth is None and a.truth_variant is not None:
        _refuse("report", "--truth-variant", "it chooses the parameters of --truth, which is not given",
                "add --truth SYSTEM or drop --truth-variant")


def _check_simulate(a) -> None:
    if a.snr is None:
        for key, flag in (("noise_on", "--noise-on"), ("noise_reference", "--noise-reference"), ("seed", "--seed")):
            if getattr(a, key, None) is not None:
                _refuse("simulate", flag, "no noise is added without --snr", f"add --snr 20 or drop {flag}")


def check_options_apply(a) -> None:
    """Refuse an option that does not apply to the rest of ``a`` (parsed arguments); then fill in
    the defaults of :data:`DEFAULTS`."""
    check = {"fit": _check_fit, "report": _check_report, "simulate": _check_simulate}.get(a.command)
    if check is not None:
        check(a)
    for key, value in DEFAULTS.get(a.command, {}).items():
        if getattr(a, key, None) is None:
            setattr(a, key, value)
