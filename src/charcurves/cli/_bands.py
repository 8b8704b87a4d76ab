"""``charcurves fit --bands`` (posterior): the fit's own posterior bands, or a line saying why there are none."""

from __future__ import annotations

from ._common import say


def attach_posterior_bands(model, level: float, quiet: bool) -> None:
    """Attach the posterior bands (result.json ``bands``, curves.png); a fit without a posterior gets
    a warning naming the alternative instead of a silent omission."""
    from ..fitting import posterior_bands
    from ..selection import attach_bands

    bands = posterior_bands(model, level=level)
    if bands:
        say(f"uncertainty bands: {next(iter(bands.values()))['kind']}, level {level:g}", quiet)
        attach_bands(model, bands)
        return
    model.info.setdefault("warnings", []).append(
        f"bands: this {model.method} fit has no posterior (today poly-cc, parametric, sindy-cc, nn-cc and "
        "nn-cc+sym fits have one, by equation or output error, and post-SR closed forms); use --bands N for N bootstrap refits")
