"""A measured record: only the position, with sensor noise; equation error, then output error.

    python examples/measured_record.py [--out DIR] [--snr 40] [--samples 1000] [--seed 0]

A real record holds ``t, x, F``: the position from a sensor, with its noise, and no velocity or
acceleration. The script makes one from the paper's Duffing oscillator (40 dB of noise on x,
derivatives dropped: ``corrupt(..., on="state")``), keeps just the three columns, and fits
NN-CC+sym twice: with the equation-error objective alone (x' and x'' estimated by the spectral
differentiator, curves regressed on them; biased, since the curves' arguments are noisy) and with
the default objective, which refits that start so that the model's free runs follow the measured x
(output error). It prints both fits' curve RMSE against the truth and writes
``measured_record.png`` (each fit's curve errors over the training range). ``--samples 500`` keeps the sampling step and
halves the record (the test's setting, about 10 s on one thread; 1000 samples: about 20 s).
"""

import argparse
import os

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402

import charcurves as cc  # noqa: E402
from charcurves.data import corrupt  # noqa: E402
from charcurves.metrics import curve_errors  # noqa: E402
from charcurves.systems import get_system  # noqa: E402


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=".", help="folder for measured_record.png (default: .)")
    parser.add_argument("--snr", type=float, default=40.0, help="noise on x, dB")
    parser.add_argument("--samples", type=int, default=1000, help="samples, 40/999 time units apart")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)

    system = get_system("duffing")
    clean = system.simulate(t_end=40.0 * (args.samples - 1) / 999, n_points=args.samples)
    noisy = corrupt(clean, args.snr, on="state", seed=args.seed)  # noise on x; v and a dropped
    record = cc.Trajectory(t=noisy.t, x=noisy.x, F=noisy.F)      # what a measurement holds: t, x, F

    truth = system.true_curves()
    fits = {}
    for objective in ("equation-error", "auto"):  # "auto", the default: equation then output error
        estimator = cc.CharacteristicCurves.from_method(method="nn-cc+sym", objective=objective, random_state=args.seed)
        fits[objective] = estimator.fit(record).model_
        errors = curve_errors(fits[objective], truth)
        print(f"{objective}: ran {fits[objective].info.get('objective', objective)}; "
              + ", ".join(f"RMSE {name} {err:.4g}" for name, err in errors.items()))

    # the curves are within a line width of the truth at this scale: draw their errors instead
    os.makedirs(args.out, exist_ok=True)
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    labels = {"equation-error": "equation error", "auto": "default: then output error"}
    for ax, name in zip(axes, ("f1", "f2")):
        for objective, model in fits.items():
            curve = model.curves[name]
            z = curve.grid(400)  # the curve's training range
            ax.plot(z, curve(z) - truth[name](z), label=labels[objective])
        ax.axhline(0.0, color="k", lw=0.8, ls="--")
        arg = "x'" if name == "f1" else "x"
        ax.set(xlabel=arg, ylabel=f"{name}({arg}) - truth", title=f"error of {name}")
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
    fig.suptitle(f"Duffing, {args.snr:g} dB noise on x only (t, x, F): NN-CC+sym, curve errors")
    fig.tight_layout()
    path = os.path.join(args.out, "measured_record.png")
    fig.savefig(path, dpi=80)
    print(f"wrote {path}")
    return fits


if __name__ == "__main__":
    main()
