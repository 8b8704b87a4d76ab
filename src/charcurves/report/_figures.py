"""Figures (matplotlib, ``ax=`` convention): the identified curves over their training range."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = ["plot_curves"]


def plot_curves(model, truth: dict[str, Callable] | None = None, *, axes=None, n: int = 1000,
                margin: float = 0.15, label: str | None = None, title: str | None = None, bands: dict | None = None):
    """Plot each identified curve with its training range shaded (the paper's Fig. 3).

    The curves are drawn a little beyond the training range (``margin``, as a fraction of it) so
    that extrapolation is visible; the shaded band marks where data constrained the curve.
    ``truth`` (name -> callable) is overlaid dashed when known. ``bands`` (name -> dict with
    ``z``, ``lo``, ``hi``, ``level``, as :func:`charcurves.selection.curve_bands` returns; default:
    the model's own ``bands`` when it has them) are drawn as a filled uncertainty band.
    Returns the figure.
    """
    if bands is None:
        bands = getattr(model, "bands", None) or {}
    if axes is None:
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(1, len(model.curves), figsize=(5.0 * len(model.curves), 3.8), squeeze=False)
        axes = axes[0]
    else:
        axes = np.atleast_1d(axes)
        fig = axes[0].figure
    for ax, (name, curve) in zip(axes, model.curves.items()):
        lo, hi = curve.domain
        pad = margin * (hi - lo)
        z = np.linspace(lo - pad, hi + pad, n)
        ax.axvspan(lo, hi, color="0.92", zorder=0, label="training range")
        if name in bands:
            b = bands[name]
            ax.fill_between(b["z"], b["lo"], b["hi"], color="C0", alpha=0.25, lw=0, zorder=1,
                            label=f"{b.get('level', 0.95):.0%} band ({b.get('members', '?')} {b.get('kind', 'members')})")
        ax.plot(z, curve(z), color="C0", lw=2, label=label or model.method)
        if truth and name in truth:
            ax.plot(z, truth[name](z), "k--", lw=1.2, label="truth")
        expr = curve.expression()
        ax.set_xlabel(curve.argument)
        ax.set_ylabel(f"{name}({curve.argument})")
        ax.set_title(f"{name}({curve.argument})" + (f" = {_short(expr)}" if expr is not None else ""), fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="best")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig


def _short(expr, digits: int = 4) -> str:
    import sympy as sp

    text = str(sp.N(expr, digits))
    return text if len(text) <= 60 else text[:57] + "..."


def plot_free_run(t, measured, simulated, *, axes=None, title: str | None = None):
    """Diagnostics of a model refitted by output error: the measured x against one free run of the
    model over the whole record (top), and their difference (bottom). ``axes``: two axes, or None
    for a new figure. Returns the figure."""
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
