"""Your own equation: ``x'' + f1(x)*x' + f2(x) = F`` on a forced Van der Pol oscillator.

    python examples/user_equation.py [--out DIR] [--snr 25] [--samples 1000] [--seed 0]

When the built-in families do not fit your physics, write the equation. ``cc.Equation`` parses it
(unknown functions ``f1(.)``, ``f2(.)`` of any state, scalars ``a1``, ``a2``...) and each unknown
function takes the representation you give it: here a neural damping curve ``f1(x)`` (position-
dependent damping) and an odd polynomial stiffness ``f2(x)`` of degree 5. The record is the forced Van der
Pol oscillator ``x'' + (x^2 - 1) x' + x + 0.5 x^3 = 1.2 cos(1.3 t)`` with 25 dB of noise on the
forcing. The script prints the curves' RMSE against the truth and writes ``user_equation.png``.
About 5 s on one thread.
"""

import argparse
import os

import matplotlib

matplotlib.use("Agg")

import charcurves as cc  # noqa: E402
from charcurves.data import corrupt  # noqa: E402
from charcurves.metrics import curve_errors  # noqa: E402
from charcurves.systems import get_system  # noqa: E402


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=".", help="folder for user_equation.png (default: .)")
    parser.add_argument("--snr", type=float, default=25.0, help="noise on the forcing, dB")
    parser.add_argument("--samples", type=int, default=1000,
                        help="record length; the sampling step stays 40.0/999 (the tests: 500)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)

    system = get_system("van-der-pol")
    record = corrupt(system.simulate(t_end=40.0 * (args.samples - 1) / 999, n_points=args.samples), args.snr, on="force", seed=args.seed)
    # a restoring force is odd about equilibrium: say so (odd powers only, no constant)
    template = cc.Equation("x'' + f1(x)*x' + f2(x) = F",
                           f1=cc.Neural(), f2=cc.Polynomial(degree=5, symmetry="odd"))
    model = cc.CharacteristicCurves(template=template, random_state=args.seed).fit(record).model_

    print(f"equation: {model.template.equation}")
    print(f"f2 = {model.curves['f2'].expression()}")
    truth = system.true_curves()
    errors = curve_errors(model, truth)
    for name, err in errors.items():
        print(f"RMSE {name} {err:.4g}")

    os.makedirs(args.out, exist_ok=True)
    axes = model.plot(truth=truth)
    fig = axes[0].figure
    fig.suptitle(f"user equation on Van der Pol, {args.snr:g} dB on F (dashed: truth)")
    fig.tight_layout()
    path = os.path.join(args.out, "user_equation.png")
    fig.savefig(path, dpi=80)
    print(f"wrote {path}")
    return errors


if __name__ == "__main__":
    main()
