"""Post-SR closed forms beyond polynomials: the true form recovered, before and after (issue 46, item 4).

Each curve of :data:`CURVES` is sampled as a fitted curve would be: 1000 evenly spaced points over a
realistic argument range, plus an error of RMS 1e-3 of the curve's range (half of its variance a
smooth wiggle -- four random sines of 0.5 to 2 periods over the domain, as a network's systematic
error -- half independent per point; seeded per curve). The samples are distilled by post-SR's entry
point (``charcurves.symbolic.distill_curve_front`` with the post-SR engine, the library defaults)
twice in the same run:

* before: the old automatic rule -- one search with ``polynomial_operators`` (+ - *, tanh for a
  jump, sin and cos for a curve that turns 4 times or more) and the old knee (without
  ``KNEE_UNFINISHED``, switched off here for this run only);
* after: ``operators="auto"``, the library default (that search and one with
  ``CLOSED_FORM_OPERATORS``; the second is kept when its MSE is ``CLOSED_FORM_GAIN`` times smaller).

Recovered: the closed form's additive terms have the truth's shapes (every number replaced by its
sign, a step tanh(k z) -- k times the half-width of the domain at least 100 -- by sign(z); exponents kept,
sinh and cosh written with exp), and its RMSE against the true curve is at
most twice the added error's. The curves are split into a tuning half (the rule and its constants
were chosen on it) and a report half (run once the rule was fixed); ``in_set`` says whether the
truth can be written with the closed-form operator set (no division, no atan or log, no piecewise
forms); shares are over those.

    python benchmarks/bench_postsr_forms.py [--half tune|report|all] [--json PATH] [--seed 0]
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np

#: (name, truth in sympy syntax, domain, half, truth expressible with the closed-form set)
CURVES = [
    # tuning half
    ("linear", "1.3*z", (-2.0, 2.0), "tune", True),
    ("duffing", "z**3 - z", (-2.0, 2.0), "tune", True),
    ("drag", "0.2*z + 0.15*z*Abs(z)", (-3.0, 3.0), "tune", True),
    ("tanh saturation", "tanh(3*z)", (-2.0, 2.0), "tune", True),
    ("sine", "sin(z)", (-3.0, 3.0), "tune", True),
    ("exp hardening", "exp(0.5*z) - 1", (-2.0, 2.0), "tune", True),
    ("sqrt law", "sign(z)*sqrt(Abs(z))", (-2.0, 2.0), "tune", True),
    ("asymmetric spring", "4*z + 1.5*z**2", (-1.0, 1.0), "tune", True),
    ("offset parabola", "0.5 + z**2", (-2.0, 2.0), "tune", True),
    ("rational", "z/(1 + z**2)", (-3.0, 3.0), "tune", False),
    ("dead zone", "sign(z)*Max(Abs(z) - 0.5, 0)", (-2.0, 2.0), "tune", False),
    # report half
    ("quintic", "z**5", (-1.5, 1.5), "report", True),
    ("softening", "1.5*z - 0.2*z**3", (-2.0, 2.0), "report", True),
    ("pure drag", "0.5*z*Abs(z)", (-2.0, 2.0), "report", True),
    ("pendulum", "9.81*sin(z)", (-2.5, 2.5), "report", True),
    ("one minus cosine", "1 - cos(z)", (-3.0, 3.0), "report", True),
    ("coulomb + viscous", "0.3*z + 0.8*tanh(50*z)", (-1.0, 1.0), "report", True),
    ("sinh hardening", "sinh(z)", (-2.0, 2.0), "report", True),
    ("exp saturation", "sign(z)*(1 - exp(-Abs(z)))", (-3.0, 3.0), "report", True),
    ("hardening cubic", "2*z**3", (-1.0, 1.0), "report", True),
    ("arctangent", "2*atan(z)", (-3.0, 3.0), "report", False),
    ("softplus", "log(1 + exp(z))", (-3.0, 3.0), "report", False),
    ("clipped", "Min(Max(z, -1), 1)", (-2.0, 2.0), "report", False),
]
N_GRID = 1000
REL_ERROR = 1e-3  # RMS of the added error, times the curve's range
RMSE_FACTOR = 2.0  # recovered: RMSE against the truth at most this times the added error's RMS
STEP_SHARPNESS = 100.0  # tanh(k z) with k * half-width >= this is a step, sign(z), in the comparison


def sampled_curve(name: str, truth: str, domain, seed: int):
    """A FittedCurve holding noisy samples of ``truth`` (linear interpolation between them)."""
    import sympy as sp

    from charcurves.curves import FittedCurve

    z = np.linspace(*domain, N_GRID)
    f = sp.lambdify(sp.Symbol("z"), sp.sympify(truth), "numpy")
    y = np.asarray(f(z), dtype=float) * np.ones_like(z)
    rng = np.random.default_rng(seed)
    u = (z - domain[0]) / (domain[1] - domain[0])
    wiggle = sum(rng.normal() * np.sin(2 * np.pi * rng.uniform(0.5, 2.0) * u + rng.uniform(0, 2 * np.pi))
                 for _ in range(4))
    white = rng.standard_normal(z.size)
    sd = REL_ERROR * float(np.ptp(y))
    err = sd / np.sqrt(2) * (wiggle / np.std(wiggle) + white / np.std(white))

    class Sampled(FittedCurve):
        kind = "samples"

        def raw(self, zz):
            return np.interp(np.asarray(zz, dtype=float), z, y + err)

        @property
        def pinned_at_zero(self) -> bool:
            return False

        def to_spec(self):  # pragma: no cover - never saved
            raise NotImplementedError

    return Sampled(name, "z", tuple(domain)), z, y, sd


def shape(expr, half_width: float):
    """The set of additive term shapes: numbers -> their sign (exponents kept), a step tanh(k z) -> sign(z)
    (k times the domain's half-width at least :data:`STEP_SHARPNESS`: the step's width under 1 % of it)."""
    import sympy as sp

    zs = sp.Symbol("z")
    e = sp.sympify(expr).replace(sp.sinh, lambda a: (sp.exp(a) - sp.exp(-a)) / 2)
    e = e.replace(sp.cosh, lambda a: (sp.exp(a) + sp.exp(-a)) / 2)
    # a float exponent that is a simple fraction (0.5 from sqrt(|k z|) = |k|^0.5 |z|^0.5) is that fraction
    e = e.replace(lambda x: x.is_Pow and x.exp.is_Float,
                  lambda x: x.base ** sp.nsimplify(x.exp, tolerance=1e-9, rational=True)
                  if sp.nsimplify(x.exp, tolerance=1e-9, rational=True).q <= 4 else x)
    e = sp.nfloat(e, exponent=False)
    rep = {}
    for t in e.atoms(sp.tanh):
        c, s = t.args[0].as_coeff_Mul()
        if s == zs and c.is_Number and abs(float(c)) * half_width >= STEP_SHARPNESS:
            rep[t] = sp.sign(zs) * (1 if float(c) > 0 else -1)
    e = sp.expand(e.xreplace(rep))
    out = set()
    for term in sp.Add.make_args(e):
        _c, basis = term.as_coeff_Mul()
        basis = basis.xreplace({f: sp.Integer(1 if f > 0 else -1) for f in basis.atoms(sp.Float)})
        out.add(sp.srepr(sp.simplify(basis)))
    return frozenset(out)


def run_one(curve, engine, operators, seed, *, old_knee: bool):
    """One distillation; ``old_knee``: the knee as before issue 46 (no KNEE_UNFINISHED rule).

    The searches remembered per process are forgotten first: a search's memo does not know the rule."""
    import math

    from charcurves.symbolic import _engine, _selection, distill_curve_front

    _engine._MEMO.clear()
    saved = _selection.KNEE_UNFINISHED
    _selection.KNEE_UNFINISHED = math.inf if old_knee else saved
    try:
        t0, c0 = time.perf_counter(), time.process_time()
        closed, _front = distill_curve_front(curve, engine, n=N_GRID, random_state=seed, operators=operators)
        return closed, time.perf_counter() - t0, time.process_time() - c0
    finally:
        _selection.KNEE_UNFINISHED = saved


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--half", default="all", choices=["tune", "report", "all"])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", default=None, help="write the figures to this JSON file")
    args = ap.parse_args(argv)
    import sympy as sp

    import charcurves
    from charcurves.symbolic import (CLOSED_FORM_GAIN, CLOSED_FORM_OPERATORS, POST_SR_OPTIONS, has_jump,
                                     polynomial_operators, post_sr_engine)

    engine = post_sr_engine()
    rows = []
    print(f"{'curve':<19} {'half':<6} {'set':<3} | {'before: rec':>11} {'RMSE':>8} {'s':>5} | "
          f"{'after: rec':>10} {'RMSE':>8} {'s':>5} | closed form after   (s: CPU seconds, one thread)")
    for i, (name, truth, domain, half, in_set) in enumerate(CURVES):
        if args.half != "all" and half != args.half:
            continue
        curve, z, y_true, sd = sampled_curve(name, truth, domain, args.seed * 1000 + i)
        half_width = 0.5 * (domain[1] - domain[0])
        want = shape(truth, half_width)
        samples = curve(z)
        old_ops = polynomial_operators(has_jump(curve, z, samples), samples)
        row = {"curve": name, "truth": truth, "domain": list(domain), "half": half, "in_set": in_set,
               "error_rms": sd}
        for label, ops in (("before", old_ops), ("after", None)):
            closed, sec, cpu = run_one(curve, engine, ops, args.seed, old_knee=label == "before")
            expr = closed.expression()
            rmse = float(np.sqrt(np.mean((closed(z) - y_true) ** 2)))
            rec = bool(shape(expr, half_width) == want and rmse <= RMSE_FACTOR * sd)
            row[label] = {"expression": str(sp.N(expr, 4)), "recovered": rec, "rmse": rmse,
                          "rmse_over_error": rmse / sd, "seconds": sec, "cpu_seconds": cpu,
                          "operators": list(closed.meta["operators"]), "mode": closed.meta["mode"]}
        rows.append(row)
        b, a = row["before"], row["after"]
        print(f"{name:<19} {half:<6} {'yes' if in_set else 'no':<3} | {str(b['recovered']):>11} {b['rmse']:8.1e} "
              f"{b['cpu_seconds']:5.2f} | {str(a['recovered']):>10} {a['rmse']:8.1e} {a['cpu_seconds']:5.2f} | "
              f"{a['expression']}", flush=True)

    summary = {}
    print()
    for half in ("tune", "report"):
        sel = [r for r in rows if r["half"] == half and r["in_set"]]
        if not sel:
            continue
        entry = {"n_in_set": len(sel)}
        for label in ("before", "after"):
            k = sum(r[label]["recovered"] for r in sel)
            entry[f"recovered_{label}"] = k
            entry[f"share_{label}"] = k / len(sel)
            for key in ("seconds", "cpu_seconds"):
                entry[f"mean_{key}_{label}"] = float(np.mean([r[label][key] for r in rows if r["half"] == half]))
        summary[half] = entry
        print(f"{half} half: true form recovered on {entry['recovered_before']}/{len(sel)} before, "
              f"{entry['recovered_after']}/{len(sel)} after; mean CPU seconds per curve "
              f"{entry['mean_cpu_seconds_before']:.2f} before, {entry['mean_cpu_seconds_after']:.2f} after "
              f"(wall {entry['mean_seconds_before']:.2f}, {entry['mean_seconds_after']:.2f})")
    poly = [r for r in rows if r["in_set"] and not (set(sp.sympify(r["truth"]).atoms(sp.Function)))]
    kept = sum(1 for r in poly if not sp.sympify(r["after"]["expression"]).atoms(sp.Function))
    print(f"polynomial truths returned as polynomials after: {kept}/{len(poly)}")
    summary["polynomial_truths_kept_polynomial_after"] = [kept, len(poly)]
    if args.json:
        from importlib.metadata import version

        doc = {"benchmark": "bench_postsr_forms.py", "load_average_at_end": list(os.getloadavg()), "charcurves": charcurves.__version__,
               "pyoperon": version("pyoperon"), "seed": args.seed,
               "half": args.half, "n_grid": N_GRID, "rel_error": REL_ERROR, "rmse_factor": RMSE_FACTOR,
               "post_sr_options": POST_SR_OPTIONS, "closed_form_operators": list(CLOSED_FORM_OPERATORS),
               "closed_form_gain": CLOSED_FORM_GAIN, "summary": summary, "curves": rows}
        Path(args.json).write_text(json.dumps(doc, indent=1) + "\n")
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
