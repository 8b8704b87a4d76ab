"""The Silverbox Duffing coefficients with their posterior standard deviations (issue 48).

The equation-error parametric fit of ``examples/silverbox.py`` (the Duffing basis ``f1=z; f2=z,
z**3``, free gain, regressed on x'', spectral derivatives, the estimation split rows 40650:105712):
c, k1, k3, g and b with their 1-sd intervals under the HAC posterior (the default) and under
independent noise, beside the published Duffing fit (which gives no standard deviations).
Writes ``benchmarks/results/silverbox-sd/silverbox_sd.json`` and prints the Markdown table.

Run: ``python benchmarks/bench_silverbox_sd.py [--data SNLS80mV.csv]``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "examples"))

import silverbox as sb  # noqa: E402

OUT = os.path.join(HERE, "results", "silverbox-sd", "silverbox_sd.json")


def coefficient_stats(model) -> dict:
    """{name: (mean, sd)} of c, k1, k3 (the closed forms' constants) and g, b (scalars)."""
    import sympy as sp

    from charcurves.model import constant_sds_of

    z = sp.Symbol("z")
    out = {}
    for curve, names in (("f1", {1: "c"}), ("f2", {1: "k1", 3: "k3"})):
        sds = constant_sds_of(model, curve)
        for f, sd in sds.items():
            power = sp.Poly(model.curves[curve].expression(), z).as_dict()
            for (k,), coef in power.items():
                if float(coef) == float(f) and k in names:
                    out[names[k]] = (float(f), float(sd))
    stats = model.posterior.scalar_stats()
    for k, name in (("gain", "g"), ("offset", "b")):
        if k in stats["names"]:
            out[name] = (stats["mean"][k], stats["sd"][k])
    return out


def main(argv=None) -> int:
    import charcurves as cc
    from charcurves.data import estimate_derivatives

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", default=None)
    a = p.parse_args(argv)
    path = sb.find_data(a.data)
    _, est = sb.load(path, sb.EST_ROWS)
    d = estimate_derivatives(est, "spectral")
    t0 = time.perf_counter()
    model = cc.fit(d, method="parametric", basis=sb.DUFFING_BASIS, free_gain=True, **sb.fit_kwargs())
    fit_s = time.perf_counter() - t0
    rows = {"hac": coefficient_stats(model)}
    model.posterior = model.posterior.with_kind("gauss")
    rows["gauss"] = coefficient_stats(model)
    doc = {"record": os.path.basename(path), "rows": list(sb.EST_ROWS), "derivatives": "spectral",
           "fit": "parametric f1=z; f2=z, z**3, free gain, gain_on=acceleration", "fit_seconds": fit_s,
           "hac_bandwidth": model.posterior.bandwidth, "published": sb.PUBLISHED,
           "coefficients": {k: {n: {"mean": m, "sd": s} for n, (m, s) in v.items()} for k, v in rows.items()}}
    os.makedirs(os.path.dirname(OUT), exist_ok=True)
    with open(OUT, "w", encoding="utf-8") as fh:
        json.dump(doc, fh, indent=2)
    print(table(doc))
    return 0


def table(doc) -> str:
    names = ("c", "k1", "k3", "g", "b")
    out = ["| | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
    pub = doc["published"]
    out.append("| published Duffing fit | " + " | ".join(f"{pub[n]:.4g}" if n in pub else "–" for n in names) + " |")
    for kind, label in (("hac", "equation error, ± 1 sd (HAC posterior)"), ("gauss", "± 1 sd under independent noise")):
        co = doc["coefficients"][kind]
        out.append(f"| {label} | " + " | ".join(f"{co[n]['mean']:.5g} ± {co[n]['sd']:.2g}" for n in names) + " |")
    co = doc["coefficients"]["hac"]
    out.append("| (equation error − published) / sd | " + " | ".join(
        f"{(co[n]['mean'] - pub[n]) / co[n]['sd']:+.1f}" if n in pub else "–" for n in names) + " |")
    return "\n".join(out)


if __name__ == "__main__":
    raise SystemExit(main())
