"""Figures of the paper's study (matplotlib, ``ax=`` convention, plain data in).

Each function draws on the given axes (a new figure when ``ax`` is None) and returns the axes;
the inputs are arrays and dicts, not stores, so the figures can be drawn from any source.

- :func:`plot_rmse_vs_noise`  ensemble RMSE vs noise fraction with A η (and bias) fits (Figs. 5, 11)
- :func:`plot_tsep_vs_noise`  ⟨t_sep⟩ vs noise fraction with the Lyapunov time (Fig. 8)
- :func:`plot_forward`        forward integrations of models against the truth (Fig. 6)
- :func:`plot_phase_space`    training trajectory, its box and validation trajectories (Fig. 7)
- :func:`plot_performance`    performance % bars, ours beside the paper's (Figs. 9, 13)
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

__all__ = ["plot_rmse_vs_noise", "plot_tsep_vs_noise", "plot_forward", "plot_phase_space", "plot_performance"]


def _axes(ax, figsize=(5.0, 3.8)):
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=figsize)
    return ax


def _log_axes(ax) -> None:
    """Log-log axes with labels on the decades only (minor labels collide on short ranges)."""
    from matplotlib.ticker import LogLocator, NullFormatter

    ax.set_xscale("log")
    ax.set_yscale("log")
    for axis in (ax.xaxis, ax.yaxis):
        axis.set_minor_formatter(NullFormatter())
        axis.set_major_locator(LogLocator(base=10, numticks=12))


def _widen_single_points(ax, xs: list, ys: list) -> None:
    """A log axis spanning one value has zero width; give it a decade around the value."""
    for values, setter in ((xs, ax.set_xlim), (ys, ax.set_ylim)):
        v = np.concatenate([np.asarray(a, float).ravel() for a in values]) if values else np.array([])
        v = v[np.isfinite(v) & (v > 0)]
        if v.size and np.isclose(v.min(), v.max()):
            setter(v.min() / 3.0, v.max() * 3.0)


def _empty(ax, text: str = "no method of this group in the run") -> None:
    ax.text(0.5, 0.5, text, transform=ax.transAxes, ha="center", va="center", color="0.4")


def plot_rmse_vs_noise(series: Mapping[str, tuple[Sequence[float] | np.ndarray, Sequence[float] | np.ndarray]], *,
                       ax=None,
                       fits: Mapping[str, float] | None = None,
                       bias_fits: Mapping[str, tuple[float, float]] | None = None,
                       ylabel: str = "RMSE", title: str | None = None):
    """Log-log ensemble RMSE per method against the noise fraction η = 10^(−SNR/20).

    Parameters
    ----------
    series : mapping
        ``{label: (eta, rmse)}``; η = 0 (noise-free) and non-finite points are not drawn.
    fits : mapping, optional
        ``{label: A}``: dashed lines ``A η`` in the method's colour.
    bias_fits : mapping, optional
        ``{label: (bias, A)}``: dotted curves ``sqrt(bias² + (A η)²)``.

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.report import plot_rmse_vs_noise
    >>> eta = 10 ** (-np.array([40.0, 20.0, 0.0]) / 20)
    >>> ax = plot_rmse_vs_noise({"parametric": (eta, 0.02 * eta)}, fits={"parametric": 0.02})
    >>> ax.get_xscale(), ax.get_yscale()
    ('log', 'log')
    """
    ax = _axes(ax)
    all_eta, all_r = [], []
    for i, (label, (eta, rmse)) in enumerate(series.items()):
        e, r = np.asarray(eta, float), np.asarray(rmse, float)
        keep = np.isfinite(e) & np.isfinite(r) & (e > 0) & (r > 0)
        if not keep.any():
            continue
        order = np.argsort(e[keep])
        color = f"C{i % 10}"
        ax.plot(e[keep][order], r[keep][order], "o-", ms=3.5, lw=1, color=color, label=label)
        all_eta.append(e[keep])
        all_r.append(r[keep])
        grid = np.geomspace(e[keep].min(), e[keep].max(), 50)
        if fits and np.isfinite(fits.get(label, np.nan)):
            ax.plot(grid, fits[label] * grid, "--", lw=1, color=color)
        if bias_fits and label in bias_fits and np.all(np.isfinite(bias_fits[label])):
            b, a = bias_fits[label]
            ax.plot(grid, np.sqrt(b * b + (a * grid) ** 2), ":", lw=1.2, color=color)
    _widen_single_points(ax, all_eta, all_r)
    _log_axes(ax)
    ax.set_xlabel("noise fraction η")
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3, which="both")
    if all_eta:
        ax.legend(fontsize=7, loc="best")
    else:
        _empty(ax, "no finite values" if series else "no method of this group in the run")
    return ax


def plot_tsep_vs_noise(series: Mapping[str, tuple[Sequence[float] | np.ndarray, Sequence[float] | np.ndarray]], *,
                       ax=None,
                       lyapunov_time: float | None = None, horizon: float | None = 80.0, title: str | None = None):
    """Mean separation time per method against η, with the Lyapunov time as a red dashed line.

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.report import plot_tsep_vs_noise
    >>> eta = 10 ** (-np.array([40.0, 20.0, 0.0]) / 20)
    >>> ax = plot_tsep_vs_noise({"parametric": (eta, [60.0, 35.0, 12.0])}, lyapunov_time=9.5)
    >>> [line.get_label() for line in ax.get_lines()]
    ['parametric', 'T_L = 9.50', 'horizon 80 s']
    """
    ax = _axes(ax)
    drawn, etas = 0, []
    for i, (label, (eta, tsep)) in enumerate(series.items()):
        e, t = np.asarray(eta, float), np.asarray(tsep, float)
        keep = np.isfinite(e) & np.isfinite(t) & (e > 0)
        if keep.any():
            order = np.argsort(e[keep])
            ax.plot(e[keep][order], t[keep][order], "o-", ms=3.5, lw=1, color=f"C{i % 10}", label=label)
            drawn += 1
            etas.append(e[keep])
    if not drawn:
        _empty(ax)
    if lyapunov_time is not None and np.isfinite(lyapunov_time):
        ax.axhline(lyapunov_time, color="red", ls="--", lw=1.2, label=f"T_L = {lyapunov_time:.2f}")
    if horizon is not None:
        ax.axhline(horizon, color="0.6", ls=":", lw=1, label=f"horizon {horizon:g} s")
    _widen_single_points(ax, etas, [])
    _log_axes(ax)
    ax.set_xlabel("noise fraction η")
    ax.set_ylabel("⟨t_sep⟩ (s)")
    if title:
        ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7, loc="best")
    return ax


def plot_forward(t: Sequence[float] | np.ndarray, x_true: Sequence[float] | np.ndarray,
                 models: Mapping[str, tuple[Sequence[float] | np.ndarray, Sequence[float] | np.ndarray]], *, ax=None,
                 eps: float | None = 0.2, title: str | None = None):
    """The true x(t) (black) and each model's forward integration (``{label: (t, x)}``; a model
    that failed early is drawn up to where it stopped).

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.report import plot_forward
    >>> t = np.linspace(0, 10, 201)
    >>> runs = {"model A": (t, np.sin(t) + 0.02 * t), "model B": (t[:100], np.sin(t[:100]))}  # B stopped at t = 5
    >>> ax = plot_forward(t, np.sin(t), runs)
    >>> [line.get_label() for line in ax.get_lines()]
    ['truth', 'model A', 'model B']
    """
    ax = _axes(ax, (7.0, 3.0))
    t = np.asarray(t, float)
    ax.plot(t, np.asarray(x_true, float), "k-", lw=1.6, label="truth")
    for i, (label, (tm, xm)) in enumerate(models.items()):
        ax.plot(np.asarray(tm, float), np.asarray(xm, float), "--", lw=1.1, color=f"C{i % 10}", label=label)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("x")
    if title:
        ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper right", ncol=2)
    return ax


def plot_phase_space(x: Sequence[float] | np.ndarray, v: Sequence[float] | np.ndarray, *, ax=None,
                     box: Mapping | None = None,
                     others: Sequence[tuple[Sequence[float] | np.ndarray, Sequence[float] | np.ndarray]] = (),
                     title: str | None = None):
    """Phase portrait: the training trajectory (or validation trajectories in ``others``), with
    the training box shaded grey as in the paper's Fig. 7.

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.report import plot_phase_space
    >>> t = np.linspace(0, 10, 201)
    >>> ax = plot_phase_space(np.sin(t), np.cos(t), box={"x": (-1.0, 1.0), "v": (-1.0, 1.0)})
    >>> ax.get_xlabel(), ax.get_ylabel()
    ('x', "x'")
    """
    ax = _axes(ax, (4.5, 4.0))
    if box is not None:
        from matplotlib.patches import Rectangle

        (xl, xh), (vl, vh) = box["x"], box["v"]
        ax.add_patch(Rectangle((xl, vl), xh - xl, vh - vl, color="0.9", zorder=0, label="training box"))
    if len(x):
        ax.plot(np.asarray(x, float), np.asarray(v, float), "k-", lw=0.7, label="training")
    for i, (xo, vo) in enumerate(others):
        ax.plot(np.asarray(xo, float), np.asarray(vo, float), "-", lw=0.7, color=f"C{i % 10}")
    ax.set_xlabel("x")
    ax.set_ylabel("x'")
    if title:
        ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    return ax


def plot_performance(series: Mapping[str, Mapping[str, float]], paper: Mapping[str, float] | None = None, *,
                     ax=None, title: str | None = None, ylim: float | None = None):
    """Performance % per method (paper Figs. 9, 13): one filled bar per series (e.g. per training
    preset, ``{label: {method: %}}``) and the paper's values as hatched bars beside; a method
    without a value gets no bar ("n/a" over the first series).

    Examples
    --------
    >>> from charcurves.report import plot_performance
    >>> ours = {"default": {"parametric": 100.0, "nn-cc": 62.0}}
    >>> ax = plot_performance(ours, paper={"parametric": 100.0, "nn-cc": 55.0})
    >>> [tick.get_text() for tick in ax.get_xticklabels()]
    ['parametric', 'nn-cc']
    """
    names: list[str] = []
    for values in list(series.values()) + [paper or {}]:
        for m in values:
            if m not in names and (values is not paper or any(m in v for v in series.values())):
                names.append(m)
    ax = _axes(ax, (max(5.0, 0.8 * len(names) + 2), 3.8))
    x = np.arange(len(names))
    n_bars = len(series) + (1 if paper else 0)
    w = 0.8 / max(n_bars, 1)
    tops = [100.0]
    for k, (label, values) in enumerate(series.items()):
        v = np.array([values.get(m, np.nan) for m in names], float)
        pos = x - 0.4 + w * (k + 0.5)
        ax.bar(pos, np.nan_to_num(v), w, color=f"C{0 if k == 0 else k + 1}", label=label)
        for xi, vi in zip(pos, v):
            if np.isfinite(vi) or k == 0:  # other series simply have no bar where they did not run
                ax.text(xi, (vi if np.isfinite(vi) else 0) + 1, f"{vi:.0f}" if np.isfinite(vi) else "n/a",
                        ha="center", va="bottom", fontsize=6.5)
        tops.extend(v[np.isfinite(v)].tolist())
    if paper:
        pv = np.array([paper.get(m, np.nan) for m in names], float)
        ax.bar(x - 0.4 + w * (n_bars - 0.5), np.nan_to_num(pv), w, color="white", edgecolor="C1", hatch="//",
               label="paper")
        tops.extend(pv[np.isfinite(pv)].tolist())
    ax.axhline(100, color="0.4", lw=0.8, ls="--")
    ax.set_xticks(x)
    ax.set_xticklabels(names, rotation=35, ha="right", fontsize=8)
    ax.set_ylabel("performance (%)")
    ax.set_ylim(0, ylim or max(tops) * 1.15)
    if title:
        ax.set_title(title, fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, axis="y")
    return ax
