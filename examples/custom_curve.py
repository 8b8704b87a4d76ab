"""A user-written curve representation: Gaussian radial basis functions, plugged into charcurves.

A representation that is linear in its parameters only says what its feature functions are
(torch, elementwise in the scaled argument ``u = z / max|z|``); every template, fitter and
objective then works with it: least squares when all curves are linear, the batched gradient
trainer beside neural curves, output error on measured records, saving and loading.

Run: ``python examples/custom_curve.py`` (about 10 s).
"""

import torch

import charcurves as cc
from charcurves.curves import LinearCurve, register_curve


@register_curve  # lets load_model rebuild it from the model file (no code is read from the file)
class RadialBasis(LinearCurve):
    """``f(u) = sum_k c_k exp(-((u - m_k) / w)^2 / 2)``, centres ``m_k`` evenly over ``[-1, 1]``."""

    def __init__(self, n_centres: int = 9, width: float = 0.3):
        self.n_centres = n_centres
        self.width = width

    def features(self, u):
        centres = torch.linspace(-1.0, 1.0, self.n_centres, dtype=u.dtype)
        return torch.exp(-0.5 * ((u.unsqueeze(-1) - centres) / self.width) ** 2)


def main(out_dir: str = "custom-curve-model"):
    from charcurves.data import corrupt
    from charcurves.metrics import curve_errors
    from charcurves.systems import get_system

    system = get_system("duffing")
    record = corrupt(system.simulate(), 30, seed=0)  # 30 dB noise on the forcing, derivatives given
    template = cc.Separable(f1=cc.Polynomial(degree=1, symmetry="odd"), f2=RadialBasis(n_centres=11))
    model = cc.CharacteristicCurves(template=template).fit(record).model_
    model.save(out_dir)
    again = cc.load_model(out_dir)
    errors = curve_errors(again, system.true_curves())
    print(f"f1 = {again.curves['f1'].expression()}; RMSE of f1 {errors['f1']:.2e}, of f2 {errors['f2']:.2e}")
    return errors


if __name__ == "__main__":
    main()
