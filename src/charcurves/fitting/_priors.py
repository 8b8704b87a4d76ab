"""What parity prior each curve of a fit carries and where it came from (``info["priors"]``), and
the self-check warning that names it first among the causes. Pure functions of the estimator and the
fitted model, below the estimator, the pipeline and the symmetry tests that all use them."""

from __future__ import annotations

import re

__all__ = ["priors_record", "name_prior_in_warnings"]

_SHORT_REASONS = (("contradict both", "asymmetric"), ("both parities fit", "nearly constant"),
                  ("one-sided", "one-sided range"), ("not tested", "not tested"))


def priors_record(estimator, model) -> dict:
    """The parity prior imposed on each curve of ``model`` and where it came from, with the line
    the CLI prints first (``info["priors"]`` in result.json).

    Examples
    --------
    >>> from charcurves.data import corrupt
    >>> from charcurves.fitting import CharacteristicCurves
    >>> from charcurves.systems import get_system
    >>> record = corrupt(get_system("duffing").simulate(t_end=20.0, n_points=500), 20, seed=0)
    >>> estimator = CharacteristicCurves.from_method(method="poly-cc", symmetry="f1=odd")
    >>> estimator.fit(record).model_.info["priors"]["summary"]
    'f1=odd, f2=none (asked: symmetry f1=odd)'
    """
    settings = model.info.get("settings") or {}
    imposed = {str(k): str(v) for k, v in (settings.get("symmetry") or {}).items()}
    if not imposed:
        imposed = {n: getattr(c, "symmetry_name", "none") or "none" for n, c in model.curves.items()}
    auto = model.info.get("symmetry_auto")
    notes: dict[str, str] = {}
    if auto:
        tests = auto["tests"] if isinstance(auto["tests"], dict) else auto["tests"][0]
        tag = "tested" if str(auto.get("mode", "")).startswith("default") else "tested, --sym auto"
        for name in imposed:
            reason = str((tests.get(name) or {}).get("reason", ""))
            short = next((s for key, s in _SHORT_REASONS if key in reason), "")
            notes[name] = tag + (f": {short}" if imposed[name] == "none" and short else "")
        source = "tested" if tag == "tested" else "--sym auto"
    elif estimator.template is not None:
        source = "the template's curves"
    elif estimator.symmetry not in (None, "", {}):
        text = estimator.symmetry if isinstance(estimator.symmetry, str) else \
            ",".join(f"{k}={v}" for k, v in dict(estimator.symmetry).items())
        source = f"asked: symmetry {text}"
    elif any(v != "none" for v in imposed.values()):
        source = f"from method {model.method}"
    else:
        source = f"none asked, method {model.method}"
    if notes and len(set(notes.values())) > 1:
        summary = ", ".join(f"{n}={v} ({notes[n]})" for n, v in imposed.items())
    else:
        note = next(iter(notes.values())) if notes else source
        summary = ", ".join(f"{n}={v}" for n, v in imposed.items()) + f" ({note})"
    return {"imposed": imposed, "source": source, "summary": summary}


def name_prior_in_warnings(model) -> None:
    """Put an imposed parity prior first among the likely causes of the self-check's warning."""
    priors = model.info.get("priors") or {}
    imposed = {n: v for n, v in (priors.get("imposed") or {}).items() if v != "none"}
    warnings = model.info.get("warnings")
    if not imposed or not warnings:
        return
    cause = (f"(0) the parity prior imposed ({', '.join(f'{n}={v}' for n, v in imposed.items())}; "
             f"{priors.get('source', '')}) -- refit without it (--sym none, --method nn-cc) or test it (--sym auto); ")
    marker = "Likely causes, most likely first: "
    out = []
    for w in warnings:
        if isinstance(w, str) and w.startswith("self-check:") and "--sym none or --sym auto" not in w:
            # (a residual test that blamed the prior names it already)
            # a fit inside a fit (symmetry="auto") named the prior already, in its own terms
            w = re.sub(r"(; also )?\(0\) the parity prior imposed \(.*?\(--sym auto\)(; )?", "", w)
            w = w.replace(marker, marker + cause, 1) if marker in w else f"{w}; also {cause.rstrip('; ')}"
        out.append(w)
    model.info["warnings"] = out
