"""Figures of one fitted model (matplotlib, ``ax=`` convention): its curves over the training range,
with the truth and uncertainty bands where known. matplotlib is imported only when a figure is drawn.
"""

from __future__ import annotations

import io
from collections.abc import Callable, Mapping

import numpy as np

from .._errors import ConfigError
from ._display import format_closed_form

__all__ = ["plot_curves", "plot_model", "figure_png", "resolve_truth"]


def plot_curves(model, truth: dict[str, Callable] | None = None, *, axes=None, n: int = 1000,
                margin: float = 0.15, label: str | None = None, title: str | None = None, bands: dict | None = None):
    """Plot each identified curve with its training range shaded (the paper's Fig. 3).

    The curves are drawn a little beyond the training range (``margin``, as a fraction of it) so
    that extrapolation is visible; the shaded band marks where data constrained the curve.
    ``truth`` (name -> callable) is overlaid dashed when known. ``bands`` (name -> dict with
    ``z``, ``lo``, ``hi``, ``level``, as :func:`charcurves.selection.curve_bands` returns; default:
    the model's own ``bands`` when it has them) are drawn as a filled uncertainty band. Closed forms
    are written in the panel titles to 4 significant digits. Returns the figure.

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.fitting import plot_curves
    >>> from charcurves.systems import get_system
    >>> system = get_system("duffing")
    >>> model = cc.fit(system.simulate(), method="parametric", basis="f1=z; f2=z, z**3")
    >>> fig = plot_curves(model, system.true_curves())
    >>> [ax.get_xlabel() for ax in fig.axes]
    ["x'", 'x']
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
                            label=f"{b.get('level', 0.95):.0%} band ("
                                  + (f"{b.get('members', '?')} " if b.get("members") != 0 else "")  # 0: a posterior
                                  + f"{b.get('kind', 'members')})")
        ax.plot(z, curve(z), color="C0", lw=2, label=label or model.method)
        if truth and name in truth:
            ax.plot(z, truth[name](z), "k--", lw=1.2, label="truth")
        expr = curve.expression()
        ax.set_xlabel(curve.argument)
        ax.set_ylabel(f"{name}({curve.argument})")
        text = "" if expr is None else " = " + format_closed_form(expr, curve.domain, argument=curve.argument)
        ax.set_title(f"{name}({curve.argument})" + (text if len(text) <= 60 else text[:57] + "..."), fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="best")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig


def resolve_truth(truth) -> dict[str, Callable] | None:
    """Truth curves from None, a mapping name -> callable, or a benchmark system's name (``"duffing"``).

    Examples
    --------
    >>> from charcurves.fitting import resolve_truth
    >>> truth = resolve_truth("duffing")
    >>> sorted(truth), float(truth["f2"](2.0)), resolve_truth(None)
    (['f1', 'f2'], 6.0, None)
    """
    if truth is None:
        return None
    if isinstance(truth, Mapping):
        return dict(truth)
    if isinstance(truth, str):
        from ..systems import get_system

        return get_system(truth).true_curves()
    raise ConfigError(f"truth must be a mapping of curve name to callable or a benchmark system's name such as "
                      f"'duffing', got {type(truth).__name__}")


def plot_model(model, ax=None, truth=None, *, bands: dict | None = None, label: str | None = None,
               margin: float = 0.15):
    """Draw the model's curves on matplotlib axes and return the axes (``FittedModel.plot``).

    Parameters
    ----------
    model : FittedModel
    ax : matplotlib Axes or sequence of Axes, optional
        One Axes per curve (in the model's curve order); a single Axes for a model with one curve,
        or for all curves together (each labelled with its name); None: a new figure with one panel
        per curve.
    truth : mapping or str, optional
        True curves (name -> callable), or a benchmark system's name (``"duffing"``), drawn dashed.
    bands : dict, optional
        Uncertainty bands (default: the model's own, when it has them).
    label : str, optional
        Legend label of the fitted curves (default: the method).
    margin : float
        How far beyond the training range (shaded) to draw, as a fraction of it.

    Returns
    -------
    Axes or numpy array of Axes
        ``ax`` itself when one Axes was given, else one Axes per curve.

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.fitting import plot_model
    >>> from charcurves.systems import get_system
    >>> axes = plot_model(cc.fit(get_system("duffing").simulate(), method="parametric", basis="f1=z; f2=z, z**3"), truth="duffing")
    >>> [ax.get_title() for ax in axes]
    ["f1(x') = 0.3*x'", 'f2(x) = x**3 - x']
    """
    truth = resolve_truth(truth)
    n = len(model.curves)
    if ax is None:
        fig = plot_curves(model, truth, margin=margin, label=label, bands=bands)
        return np.asarray(fig.axes[:n], dtype=object)
    if isinstance(ax, (list, tuple, np.ndarray)):
        axes = np.atleast_1d(np.asarray(ax, dtype=object)).ravel()
        if axes.size != n:
            raise ConfigError(f"ax has {axes.size} axes but the model has {n} curves ({', '.join(model.curves)}); "
                              "give one Axes per curve, or a single Axes")
        plot_curves(model, truth, axes=axes, margin=margin, label=label, bands=bands)
        return axes
    if n == 1:
        plot_curves(model, truth, axes=[ax], margin=margin, label=label, bands=bands)
        return ax
    for i, (name, c) in enumerate(model.curves.items()):  # every curve on one Axes
        lo, hi = c.domain
        pad = margin * (hi - lo)
        z = np.linspace(lo - pad, hi + pad, 600)
        ax.plot(z, c(z), color=f"C{i}", lw=2, label=f"{name}({c.argument})")
        if truth and name in truth:
            ax.plot(z, truth[name](z), "--", color=f"C{i}", lw=1.1, label=f"{name} truth")
    ax.set_xlabel("argument")
    ax.set_ylabel("curve value")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    return ax


def figure_png(model, truth=None, *, width: float = 3.3, height: float = 2.5, dpi: int = 80) -> bytes:
    """The curves as PNG bytes (one panel per curve, ``width`` x ``height`` inches each).

    pyplot is not used, so a notebook does not show the figure a second time and no figure stays open.

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.fitting import figure_png
    >>> from charcurves.systems import get_system
    >>> model = cc.fit(get_system("duffing").simulate(), method="parametric", basis="f1=z; f2=z, z**3")
    >>> png = figure_png(model, truth="duffing", width=2.0, height=1.5, dpi=40)
    >>> png[1:4], len(png) > 1000  # a PNG file
    (b'PNG', True)
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    n = len(model.curves)
    fig = Figure(figsize=(width * n, height))
    FigureCanvasAgg(fig)
    axes = [fig.add_subplot(1, n, i + 1) for i in range(n)]
    plot_curves(model, resolve_truth(truth), axes=axes)
    for a in axes:
        a.title.set_fontsize(8)
        a.tick_params(labelsize=7)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()
