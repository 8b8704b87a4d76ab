"""Figures: identified curves with the training range shaded and the truth overlaid."""

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402

import charcurves as cc  # noqa: E402
from charcurves.report import plot_curves  # noqa: E402


def test_curve_figure_shades_the_training_range_and_overlays_the_truth(duffing, duffing_20db):
    system, _ = duffing
    model = cc.fit(duffing_20db, method="parametric", basis="f1=z; f2=z, z**3")
    fig = plot_curves(model, system.true_curves())
    axes = fig.axes
    assert len(axes) == 2
    for ax, name in zip(axes, ("f1", "f2")):
        curve = model.curves[name]
        spans = [p for p in ax.patches]
        assert len(spans) == 1
        x0, x1 = spans[0].get_x(), spans[0].get_x() + spans[0].get_width()
        assert np.allclose([x0, x1], curve.domain)
        labels = [line.get_label() for line in ax.get_lines()]
        assert "truth" in labels and "parametric" in labels
        fitted = ax.get_lines()[0]
        xd, yd = fitted.get_data()
        assert np.allclose(yd, curve(xd))
        assert xd.min() < curve.domain[0] and xd.max() > curve.domain[1]  # extrapolation visible
        assert ax.get_xlabel() == curve.argument
        assert "=" in ax.get_title()  # closed forms are printed in the title
    import matplotlib.pyplot as plt

    plt.close(fig)


def test_curve_figure_draws_into_given_axes(duffing_20db):
    import matplotlib.pyplot as plt

    model = cc.fit(duffing_20db, method="parametric", basis="f1=z; f2=z, z**3")
    fig, axes = plt.subplots(1, 2)
    out = plot_curves(model, axes=axes, label="mine")
    assert out is fig
    assert [ln.get_label() for ln in axes[0].get_lines()] == ["mine"]
    plt.close(fig)
