"""Fits in other units and with an offset (docs/zoo.md, "Units and offsets of the measured signals").

The paper's Duffing record (seed 0) with 20 dB of noise on F (derivatives given) and with 40 dB on x
only, mapped into new units ``X = c (x + d)`` with F (per unit mass) in the same length unit, so the
template's gain stays 1: cases x, x + 10, 1e-3 x, 1e3 x, 1e3 (x + 10); and, with a learned gain, F
scaled by 1e3 beside its own baseline ("x|free"). Each method at its defaults; per fit the
normalised RMSE of f1 and f2 against the true curves in the new units (``c f1(V / c)``,
``c f2(X / c - d)``), up to a constant (the gauge), over the clean record's range, divided by the
std of the truth there. One JSON line per fit.

    python benchmarks/bench_units.py OUT.jsonl [--methods nn-cc,poly-cc] [--settings F20,X40]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

CASES = {  # name: (c, d, k, free gain): X = c (x + d), F -> k F
    "x": (1.0, 0.0, 1.0, False), "x+10": (1.0, 10.0, 1.0, False), "1e-3x": (1e-3, 0.0, 1e-3, False),
    "1e3x": (1e3, 0.0, 1e3, False), "1e3(x+10)": (1e3, 10.0, 1e3, False),
    "x|free": (1.0, 0.0, 1.0, True), "1e3F|free": (1.0, 0.0, 1e3, True),
}
METHODS = ("nn-cc", "nn-cc+sym", "poly-cc", "sindy-cc+sym", "parametric", "default")


def record(clean, setting: str, c: float, d: float, k: float):
    from charcurves.data import Trajectory, corrupt

    if setting == "F20":
        r = corrupt(clean, 20.0, on="force", seed=0)
        return Trajectory(t=r.t, x=c * (np.asarray(r.x) + d), v=c * np.asarray(r.v), a=c * np.asarray(r.a),
                          F=k * np.asarray(r.F))
    r = corrupt(clean, 40.0, on="state", seed=0)
    return Trajectory(t=r.t, x=c * (np.asarray(r.x) + d), F=k * np.asarray(r.F))


def score(model, system, clean, c: float, d: float) -> dict[str, float]:
    from charcurves.metrics import curve_rmse

    truth = {"f1": lambda V: c * system.f1(V / c), "f2": lambda X: c * system.f2(X / c - d)}
    spans = {"f1": c * np.asarray(clean.v), "f2": c * (np.asarray(clean.x) + d)}
    out = {}
    for name, f in truth.items():
        lo, hi = float(spans[name].min()), float(spans[name].max())
        out[name] = (curve_rmse(model.curves[name], f, domain=(lo, hi), align="mean")
                     / float(np.std(f(np.linspace(lo, hi, 1000)))))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--settings", default="F20,X40")
    a = ap.parse_args()
    from charcurves.fitting import CharacteristicCurves
    from charcurves.systems import get_system

    system = get_system("duffing")
    clean = system.simulate()
    for setting in a.settings.split(","):
        for method in a.methods.split(","):
            for case, (c, d, k, free) in CASES.items():
                kw = {"basis": "f1=z; f2=z, z**2, z**3"} if method == "parametric" else {}
                row: dict = {"setting": setting, "method": method, "case": case}
                t0 = time.perf_counter()
                try:
                    est = CharacteristicCurves.from_method(None if method == "default" else method, random_state=0,
                                                           threads=1, free_gain=free, **kw)
                    model = est.fit(record(clean, setting, c, d, k)).model_
                    row.update(nrmse=score(model, system, clean, c, d), priors=model.info["priors"]["summary"],
                               loss_over_floor=model.info.get("self_check", {}).get("loss_over_floor"))
                except Exception as exc:  # noqa: BLE001 - a refusal is a result here
                    row["error"] = f"{type(exc).__name__}: {str(exc)[:300]}"
                row["seconds"] = round(time.perf_counter() - t0, 1)
                print(json.dumps(row), flush=True)
                with open(a.out, "a") as fh:
                    fh.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
