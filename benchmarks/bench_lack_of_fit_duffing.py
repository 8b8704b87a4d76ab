"""The lack-of-fit term on the paper's Duffing (a quick check beside benchmarks/bench_coverage.py):
for R noise realisations per setting and method, the share of the 200-point grid (f1 and f2 pooled)
inside the 95 % band with the term (the default posterior) and without it (the wrapped Laplace
posterior), and how many fits got the term.

``--previous`` adds, on the same fits, the band of the estimate before issue 48's level fix
(``benchmarks/_lof_previous.py``, gated at the same level) and each band's mean half-width over sd(truth).

Run: ``python benchmarks/bench_lack_of_fit_duffing.py --realisations 30 [--methods poly-cc,parametric]``.
"""

from __future__ import annotations

import argparse
import json
from statistics import NormalDist

import numpy as np

SETTINGS = {"force": (20.0, "force", "equation-error"), "state": (40.0, "state", "equation-error"),
            "state-oe": (40.0, "state", "output-error")}
EXTRA = {"poly-cc": {}, "parametric": {"basis": "f1=z; f2=z, z**3"}, "sindy-cc": {"free_gain": False},
         "sindy-cc+sym": {"free_gain": False}, "nn-cc": {}, "nn-cc+sym": {}}


def main(argv=None) -> int:
    import charcurves as cc
    from charcurves.systems import get_system

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--realisations", type=int, default=30)
    p.add_argument("--methods", default="poly-cc,parametric,sindy-cc")
    p.add_argument("--settings", default="force,state,state-oe")
    p.add_argument("--previous", action="store_true", help="also the estimate before issue 48's level fix")
    a = p.parse_args(argv)
    if a.previous:
        import os
        import sys

        sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
        from _lof_previous import record_previous

        record_previous()
    from charcurves.fitting import LACK_OF_FIT_LEVEL
    system = get_system("duffing")
    clean, truth = system.simulate(), system.true_curves()
    zq = NormalDist().inv_cdf(0.975)
    for setting in a.settings.split(","):
        snr, on, objective = SETTINGS[setting]
        for method in a.methods.split(","):
            wide, plain, wrapped = [], [], 0
            prev, wrapped_prev, width = [], 0, {"with_term": [], "plain": [], "previous": []}
            for r in range(a.realisations):
                record = cc.corrupt(clean, snr, on=on, seed=r)
                model = cc.CharacteristicCurves.from_method(method=method, objective=objective, random_state=r, threads=1,
                                                            **{"free_gain": True, **EXTRA[method]}).fit(record).model_
                post = model.posterior
                if post is None:
                    continue
                inner = getattr(post, "inner", post)
                wrapped += inner is not post
                old = {c: (zc, b) for c, (zc, b, pv) in model.info.pop("_lack_of_fit_previous", {}).items()
                       if pv < LACK_OF_FIT_LEVEL}
                old_post = cc.model.LackOfFitPosterior(inner, old) if old else inner
                wrapped_prev += bool(old)
                for name, curve in model.curves.items():
                    z = np.linspace(curve.domain[0], curve.domain[1], 200)
                    t = np.asarray(truth[name](z), dtype=float)
                    for p_, out, key in ((post, wide, "with_term"), (inner, plain, "plain"), (old_post, prev, "previous")):
                        v, sd = p_.curve_sd(name, z)
                        out.append(np.mean(np.abs(t - v) <= zq * sd))
                        width[key].append(float(np.mean(zq * sd) / np.std(t)))
            row = {"setting": setting, "method": method, "realisations": a.realisations,
                   "with_term": round(float(np.mean(wide)), 4), "plain": round(float(np.mean(plain)), 4),
                   "fits_with_term": wrapped}
            if a.previous:
                row.update({"previous": round(float(np.mean(prev)), 4), "fits_with_term_previous": wrapped_prev,
                            **{f"half_width_{k}": round(float(np.mean(v)), 5) for k, v in width.items()}})
            print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
