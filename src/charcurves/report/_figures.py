"""Figures of one fit (matplotlib, ``ax=`` convention) beside the curves (``plot_curves`` lives in
:mod:`charcurves.fitting`): the free-run diagnostics of output error."""

from __future__ import annotations

import numpy as np

__all__ = ["plot_free_run"]


def plot_free_run(t, measured, simulated, *, axes=None, title: str | None = None):
    """Diagnostics of a model refitted by output error: the measured x against one free run of the
    model over the whole record (top), and their difference (bottom). ``axes``: two axes, or None
    for a new figure. Returns the figure.

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.report import plot_free_run
    >>> t = np.linspace(0, 10, 201)
    >>> fig = plot_free_run(t, np.sin(t), np.sin(t) + 0.01 * t, title="free run")
    >>> [ax.get_ylabel() for ax in fig.axes]
    ['x', 'free run - measured']
    """
    t, measured, simulated = (np.asarray(a, dtype=float) for a in (t, measured, simulated))
    if axes is None:
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(2, 1, figsize=(10.0, 4.6), sharex=True)
    fig = axes[0].figure
    ok = np.isfinite(simulated)
    rmse = float(np.sqrt(np.mean((simulated[ok] - measured[ok]) ** 2))) if ok.any() else float("nan")
    axes[0].plot(t, measured, color="0.55", lw=0.8, label="measured x")
    axes[0].plot(t, simulated, color="C0", lw=1.0, label=f"free run of the model (RMSE {rmse:.3g})")
    axes[0].set_ylabel("x")
    axes[0].legend(loc="upper right", fontsize=8)
    if title:
        axes[0].set_title(title, fontsize=10)
    axes[1].plot(t, simulated - measured, color="C3", lw=0.8)
    axes[1].axhline(0.0, color="0.3", lw=0.6)
    axes[1].set_ylabel("free run - measured")
    axes[1].set_xlabel("t")
    if not ok.all():
        axes[1].text(0.01, 0.9, f"the free run stopped at t = {t[~ok][0]:.4g}", transform=axes[1].transAxes,
                     fontsize=8, color="C3")
    return fig
