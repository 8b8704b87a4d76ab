"""Calibration of the posterior bands: does the 95 % band hold the true curve?

The paper's Duffing (charcurves.systems, 1000 samples over 40 s), R noise realisations in two settings:

* ``force``: 20 dB on F, the record's derivatives given;
* ``state``: 40 dB on x only, derivatives estimated by the default differentiator;
* ``state-oe``: the same records fitted by output error (its posterior has the segments' initial
  states marginalised).

Each realisation is fitted by equation error (``objective="equation-error"``) with each method and a
free gain (so that the gain's interval is checked too: its truth is 1); sindy-cc and sindy-cc+sym fix
the gain (their constrained SR3); their bands are the least-squares posterior on the active terms their
sparse regression chose, with the lack-of-fit term of a sparse fit (charcurves.fitting.SPARSE_LACK_OF_FIT)
by equation error; by output error (state-oe) the Gauss-Newton posterior of the refined coefficients. Reported per method, setting
and band: the share of the curve grid (200 points over each curve's training range, f1 and f2
pooled, then the mean over realisations) inside the band, the share of realisations whose gain and
free constant (truth 0) lie inside their intervals, the mean band half-width, and the seconds of the
posterior beside those of the fit. Bands: the posterior with the HAC covariance (the default; seconds: the covariance and the bands on the grid), the
plain Gaussian one (``gauss``), and (``--bootstrap N``, the first ``--bootstrap-records`` realisations)
the wild-bootstrap bands of charcurves.selection with N refits.

Results: benchmarks/results/coverage/coverage.json (rows) and coverage.md (the table of
docs/uncertainty-coverage.md). Run: ``python benchmarks/bench_coverage.py --realisations 100``; ``--render`` only
rewrites the table of docs/uncertainty-coverage.md from the committed results.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from statistics import NormalDist

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "results", "coverage")
METHODS = {"poly-cc": {}, "parametric": {"basis": "f1=z; f2=z, z**3"}, "sindy-cc": {"free_gain": False},
           "sindy-cc+sym": {"free_gain": False}, "nn-cc": {}, "nn-cc+sym": {}}
#: methods whose realisations train as one batch (``fit_many``); their fit seconds are the batch's per record
BATCHED = ("nn-cc", "nn-cc+sym")
SETTINGS = {"force": (20.0, "force"), "state": (40.0, "state"), "state-oe": (40.0, "state")}
#: the objective of each setting (state-oe: 40 dB on x only through output error)
OBJECTIVE = {"force": "equation-error", "state": "equation-error", "state-oe": "output-error"}
LEVEL = 0.95
#: factors on the band's half-width whose coverage each row records too (a scaled posterior's calibration)
SCALES = (0.75, 1.0, 1.25, 1.5, 2.0, 2.5, 3.0, 4.0)


def _covers(model, truth):
    """Per curve: share of the grid inside the band; the gain's and offset's (value, lo, hi)."""
    zq = NormalDist().inv_cdf(0.5 + LEVEL / 2)
    inside, width, ratio = [], [], []
    for name, curve in model.curves.items():
        z = np.linspace(curve.domain[0], curve.domain[1], 200)
        value, sd = model.posterior.curve_sd(name, z)
        t = np.asarray(truth[name](z), dtype=float)
        inside.append(np.abs(t - value) <= zq * sd)
        with np.errstate(all="ignore"):
            ratio.append(np.where(np.abs(t - value) == 0, 0.0, np.abs(t - value) / (zq * sd)))
        width.append(np.mean(zq * sd) / (np.std(t) + 1e-300))
    stats = model.posterior.scalar_stats()
    # the truth inside the whole band; and the grid share and that flag for the band scaled by each of SCALES
    r = np.concatenate(ratio)
    scal = {"everywhere": bool(np.all(np.concatenate(inside))),
            "scaled": {f"{c:g}": [float(np.mean(r <= c)), bool(np.all(r <= c))] for c in SCALES}}
    if hasattr(model.posterior, "simultaneous_factor"):  # the sup-t band over both curves' grids at once
        c = model.posterior.simultaneous_factor({n: np.linspace(cv.domain[0], cv.domain[1], 200)
                                                 for n, cv in model.curves.items()}, level=LEVEL)
        scal["simultaneous"] = {"factor": c, "grid": float(np.mean(r * zq <= c)), "everywhere": bool(np.all(r * zq <= c))}
    for k, true in (("gain", 1.0), ("offset", 0.0)):
        if k in stats["mean"]:
            scal[k] = bool(abs(stats["mean"][k] - true) <= zq * stats["sd"][k])
            scal[f"{k}_error"], scal[f"{k}_sd"] = stats["mean"][k] - true, stats["sd"][k]
    return float(np.mean(np.concatenate(inside))), float(np.mean(width)), scal


def _bootstrap(est, record, model, truth, n):
    import charcurves as cc
    from charcurves.selection import band_coverage, curve_bands

    t0 = time.perf_counter()
    ens = cc.fitting.fit_ensemble(est, record, n, random_state=0)
    seconds = time.perf_counter() - t0
    bands = curve_bands(ens, level=LEVEL)
    cov = band_coverage(bands, truth)
    width = np.mean([np.mean((np.asarray(b["hi"]) - np.asarray(b["lo"])) / 2) / (np.std(truth[k](np.asarray(b["z"]))))
                     for k, b in bands.items()])
    return float(np.mean(list(cov.values()))), float(width), seconds


def run(realisations: int, bootstrap: int, bootstrap_records: int, methods, settings, first: int = 0):
    import charcurves as cc
    from charcurves.fitting import posterior_bands
    from charcurves.systems import get_system

    system = get_system("duffing")
    clean = system.simulate()
    truth = system.true_curves()
    rows = []
    for setting in settings:
        snr, on = SETTINGS[setting]
        for method in methods:
            batch = {}
            if method in BATCHED:  # one batched training for every realisation (what fit_many is for)
                est = cc.CharacteristicCurves.from_method(method=method, objective=OBJECTIVE[setting], threads=1,
                                                          **{"free_gain": True, **METHODS[method]})
                t0 = time.perf_counter()
                seeds = list(range(first, first + realisations))
                fitted = est.fit_many([cc.corrupt(clean, snr, on=on, seed=r) for r in seeds], seeds=seeds)
                per = (time.perf_counter() - t0) / realisations
                batch = dict(zip(seeds, fitted))
            for r in range(first, first + realisations):
                record = cc.corrupt(clean, snr, on=on, seed=r)
                est = cc.CharacteristicCurves.from_method(method=method, objective=OBJECTIVE[setting], random_state=r, threads=1,
                                              **{"free_gain": True, **METHODS[method]})
                t0 = time.perf_counter()
                model = batch[r] if batch else est.fit(record).model_
                fit_s = per if batch else time.perf_counter() - t0
                if model.posterior is None:
                    print(json.dumps({"setting": setting, "method": method, "realisation": r, "no_posterior": True}))
                    continue
                t1 = time.perf_counter()
                posterior_bands(model, level=LEVEL)  # what --bands computes: the bands on 200 points per curve
                band_s = time.perf_counter() - t1
                row = {"setting": setting, "method": method, "realisation": r, "fit_seconds": fit_s,
                       "posterior_seconds": model.info.get("posterior_seconds", 0.0) + band_s}
                for kind in ("hac", "gauss"):
                    if kind != "hac":
                        model.posterior = _with_kind(model.posterior, kind)
                    grid, width, scal = _covers(model, truth)
                    row[kind] = {"grid": grid, "width": width, **scal}
                if bootstrap and r < bootstrap_records:
                    grid, width, secs = _bootstrap(est, record, model, truth, bootstrap)
                    row["bootstrap"] = {"grid": grid, "width": width, "seconds": secs, "members": bootstrap}
                rows.append(row)
                print(json.dumps(row), flush=True)
    return rows


def rows_json(rows) -> str:
    """``rows`` as a JSON list with one compact row per line (1.4 MB for 1 700 rows, where an indented
    file took 2.3 MB), so that a diff shows the realisations that changed."""
    return "[\n" + ",\n".join(json.dumps(r, separators=(",", ":")) for r in rows) + "\n]\n"


def _with_kind(post, kind):
    """The same fit's posterior with another covariance."""
    return post.with_kind(kind)


def table(rows) -> str:
    """The Markdown table of docs/uncertainty-coverage.md."""
    out = ["| setting | method | band | grid inside 95 % band | inside everywhere | gain inside | constant inside | "
           "half-width / sd(truth) | realisations | seconds (band / fit) |",
           "|---|---|---|---|---|---|---|---|---|---|"]
    keys = sorted({(r["setting"], r["method"]) for r in rows}, key=lambda k: (list(SETTINGS).index(k[0]), k[1]))
    for setting, method in keys:
        sel = [r for r in rows if r["setting"] == setting and r["method"] == method]
        fit_s = float(np.mean([r["fit_seconds"] for r in sel]))
        post_s = float(np.mean([r["posterior_seconds"] or 0.0 for r in sel]))
        for band in ("hac", "gauss", "bootstrap"):
            got = [r[band] for r in sel if band in r]
            if not got:
                continue
            g = [x for x in (d.get("gain") for d in got) if x is not None]
            o = [x for x in (d.get("offset") for d in got) if x is not None]
            secs = (f"{np.mean([d['seconds'] for d in got]):.3f} / {fit_s:.3f}" if band == "bootstrap"
                    else f"{post_s:.4f} / {fit_s:.3f}")
            label = {"hac": "posterior (HAC, default)", "gauss": "posterior (iid noise)",
                     "bootstrap": f"bootstrap, {got[0].get('members')} refits"}[band]
            share = lambda xs: f"{np.mean(xs):.2f}" if xs else "–"  # noqa: E731
            every = [d["everywhere"] for d in got if "everywhere" in d]
            out.append(f"| {setting} | {method} | {label} | {np.mean([d['grid'] for d in got]):.3f} | "
                       f"{share(every)} | {share(g)} | {share(o)} | {np.mean([d['width'] for d in got]):.4f} | "
                       f"{len(got)} | {secs} |")
    return "\n".join(out) + "\n"


PAGE = os.path.join(os.path.dirname(HERE), "docs", "uncertainty-coverage.md")


def render(results_dir: str = OUT, page: str = PAGE, check: bool = False) -> bool:
    """Write the table of ``coverage.json`` between the page's ``<!-- table:coverage -->`` markers;
    ``check``: write nothing, return whether the page already shows it."""
    from charcurves.experiments import fill_table_markers

    with open(os.path.join(results_dir, "coverage.json"), encoding="utf-8") as fh:
        rows = json.load(fh)
    with open(page, encoding="utf-8") as fh:
        text = fh.read()
    new = fill_table_markers(text, {"coverage": table(rows)})
    if not check and new != text:
        with open(page, "w", encoding="utf-8") as fh:
            fh.write(new)
    return new == text


def bias_lines(rows) -> list[str]:
    """Per setting and method: the gain's mean error, the spread of its errors and its mean posterior
    sd over the realisations (a bias shows as a mean error beside a right spread)."""
    out = []
    for setting, method in sorted({(r["setting"], r["method"]) for r in rows}):
        d = [r["hac"] for r in rows if r["setting"] == setting and r["method"] == method and "gain_error" in r["hac"]]
        if d:
            e = np.array([x["gain_error"] for x in d])
            out.append(f"{setting} {method}: gain error mean {e.mean():+.4f}, spread {e.std(ddof=1):.4f}, "
                       f"posterior sd {np.mean([x['gain_sd'] for x in d]):.4f} ({len(d)} realisations)")
    return out


def simultaneous_lines(rows) -> list[str]:
    """Per setting, method and band of the network posteriors: the sup-t band's mean factor (range),
    its grid share and share of realisations inside everywhere, beside the pointwise band's."""
    out = []
    for setting, method in sorted({(r["setting"], r["method"]) for r in rows}):
        sel = [r for r in rows if r["setting"] == setting and r["method"] == method and "simultaneous" in r["hac"]]
        for band in ("hac", "gauss") if sel else ():
            d = [r[band]["simultaneous"] for r in sel]
            f = [x["factor"] for x in d]
            out.append(f"{setting} {method} {band}: sup-t factor mean {np.mean(f):.3f} [{min(f):.3f}, {max(f):.3f}], "
                       f"grid {np.mean([x['grid'] for x in d]):.3f}, inside everywhere "
                       f"{np.mean([x['everywhere'] for x in d]):.2f}; pointwise band: grid "
                       f"{np.mean([r[band]['grid'] for r in sel]):.3f}, inside everywhere "
                       f"{np.mean([r[band]['everywhere'] for r in sel]):.2f} ({len(d)} realisations)")
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--render", action="store_true",
                    help="only rewrite the table of docs/uncertainty-coverage.md from the committed coverage.json")
    ap.add_argument("--realisations", type=int, default=100)
    ap.add_argument("--first", type=int, default=0,
                    help="the first noise seed (a chunk of seeds first..first+realisations-1, to merge afterwards)")
    ap.add_argument("--bootstrap", type=int, default=20, help="refits per bootstrap band (0: none)")
    ap.add_argument("--bootstrap-records", type=int, default=20)
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--settings", default=",".join(SETTINGS))
    ap.add_argument("--out", default=OUT)
    ap.add_argument("--merge", action="store_true",
                    help="keep the rows of --out's coverage.json for the settings and methods not run now")
    a = ap.parse_args(argv)
    if a.render:
        render(a.out)
        return
    rows = run(a.realisations, a.bootstrap, a.bootstrap_records, a.methods.split(","), a.settings.split(","), a.first)
    os.makedirs(a.out, exist_ok=True)
    if a.merge and os.path.exists(os.path.join(a.out, "coverage.json")):
        with open(os.path.join(a.out, "coverage.json"), encoding="utf-8") as fh:
            ran = {(r["setting"], r["method"]) for r in rows}
            rows = [r for r in json.load(fh) if (r["setting"], r["method"]) not in ran] + rows
    with open(os.path.join(a.out, "coverage.json"), "w", encoding="utf-8") as fh:
        fh.write(rows_json(rows))
    text = table(rows)
    print("\n".join(bias_lines(rows) + simultaneous_lines(rows)))
    with open(os.path.join(a.out, "coverage.md"), "w", encoding="utf-8") as fh:
        fh.write(text)
    print(text)


if __name__ == "__main__":
    main()
