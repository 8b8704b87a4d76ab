"""Coverage of the posterior bands on the curve zoo's report half (issue 46 item 6, issue 48).

For every system of the report half of ``benchmarks/zoo.py`` (``SYSTEM_HALF``), the noise settings
F25 (noise on F, derivatives given) and x30 (noise on x only, derivatives estimated by the default
differentiator) and each seed, fits poly-cc, parametric on the true closed form's terms (the zoo's
limit) and, where every curve is odd, sindy-cc+sym, all by equation error (``objective=
"equation-error"``: the fits that have a posterior; the default objective refines x30 fits by output
error, whose posterior is not in this benchmark). Each scored curve's 95 % band
(``model.curve_band``) is evaluated on 200 points over the argument range of the clean record and
the share of points where the truth lies inside it is recorded, with the band's mean half-width
relative to the true curve's sd. Rows are appended to ``benchmarks/results/zoo-coverage/results.jsonl``
as they end; a rerun skips the jobs already there.

``--previous`` also scores, on the same fits, the band of the lack-of-fit estimate before issue 48's
level fix (``benchmarks/_lof_previous.py``): ``inside_prev``, ``half_width_prev``, ``binned_p_prev``.
``--before`` scores the band of the rule before issue 48's sparse rule (the term only where the test
rejects at ``LACK_OF_FIT_LEVEL``, ``LACK_OF_FIT_BINS`` bins, no shrinkage, for every method):
``inside_before``, ``half_width_before``. Rows of sparse fits (``charcurves.fitting.sparse_fit``) say
``lof_every_curve``: their default band has the term on every curve, whatever the test's p.

Run: ``python benchmarks/bench_zoo_coverage.py --seeds 0-9 [--report-only] [--markdown FILE]``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
if HERE not in sys.path:
    sys.path.insert(0, HERE)

import zoo  # noqa: E402
from bench_zoo import _all_arguments, noisy_record  # noqa: E402

from charcurves.experiments import coverage_table, gated_rows, per_curve_table  # noqa: E402

RESULTS = os.path.join(HERE, "results", "zoo-coverage", "results.jsonl")
SETTINGS = ("F25", "x30")
METHODS = ("poly-cc", "sindy-cc+sym", "parametric")
ALL_METHODS = ("poly-cc", "sindy-cc+sym", "parametric", "nn-cc", "nn-cc+sym")
LEVEL = 0.95


def jobs(seeds, half="report", methods=METHODS, settings=SETTINGS, systems=None) -> list[tuple[str, str, str, int]]:
    out = []
    for seed in seeds:
        for setting in settings:
            for name, h in zoo.SYSTEM_HALF.items():
                if h != half or (systems and name not in systems):
                    continue
                for method in methods:
                    if method == "sindy-cc+sym" and not zoo.SYSTEMS[name].all_odd():
                        continue
                    out.append((name, method, setting, seed))
    return out


def run_job(job, clean_cache) -> dict:
    import charcurves as cc

    name, method, setting, seed = job
    system = zoo.SYSTEMS[name]
    clean = clean_cache.setdefault(name, system.simulate())
    record = noisy_record(system, setting, seed, clean)
    kw = {"method": "parametric", "basis": zoo.basis_option(system)} if method == "parametric" else {"method": method}
    row = {"key": "|".join(map(str, job)), "system": name, "method": method, "setting": setting, "seed": seed}
    t0 = time.perf_counter()
    try:
        model = cc.CharacteristicCurves.from_method(family=system.family, random_state=seed, threads=1,
                                                    objective="equation-error", **kw).fit(record).model_
    except Exception as exc:  # a failure of the library is a result too
        row["error"] = f"{type(exc).__name__}: {str(exc)[:200]}"
        return row
    row["fit_seconds"] = time.perf_counter() - t0
    truth, args = system.truth(), _all_arguments(system, clean)
    row["posterior"] = str(model.info.get("posterior", ""))
    row["binned_p"] = dict(model.info.get("lack_of_fit_p", {}))  # the bias test of each curve
    row["inside"], row["half_width"], row["inside_plain"], row["half_width_plain"] = {}, {}, {}, {}
    row["error_over_half_width"] = {}
    prev = model.info.pop("_lack_of_fit_previous", None)  # --previous: the old estimate on the same fit
    before = model.info.pop("_lack_of_fit_before", None)  # --before: the rule before the sparse rule, same fit
    if cc.fitting.sparse_fit(model):
        row["lof_every_curve"] = True
        row["n_active_terms"] = model.info.get("n_active_terms")
        row["library_size"] = model.info.get("library_size")
    if before is not None:
        row["inside_before"], row["half_width_before"] = {}, {}
    if prev is not None:
        row["binned_p_prev"] = {c: p for c, (_, _, p) in prev.items()}
        row["inside_prev"], row["half_width_prev"] = {}, {}
    from statistics import NormalDist

    zq = NormalDist().inv_cdf(0.5 + LEVEL / 2)
    post = cc.model.model_posterior(model)
    plain = getattr(post, "inner", post)  # the Laplace posterior without the lack-of-fit term
    for slot in system.scored:
        lo, hi = float(args[slot].min()), float(args[slot].max())
        z = np.linspace(lo, hi, 200)
        try:
            _, blo, bhi = model.curve_band(slot, z, level=LEVEL)
        except cc.ConfigError as exc:
            row["error"] = f"ConfigError: {str(exc)[:200]}"
            return row
        f = truth[slot](z)
        row["inside"][slot] = float(np.mean((f >= blo) & (f <= bhi)))
        row["half_width"][slot] = float(np.mean((bhi - blo) / 2) / np.std(f))
        value, sd = plain.curve_sd(slot, z)
        hw = zq * np.asarray(sd)
        row["inside_plain"][slot] = float(np.mean(np.abs(f - value) <= hw))
        row["half_width_plain"][slot] = float(np.mean(hw) / np.std(f))
        if prev is not None:
            pv, psd = cc.model.LackOfFitPosterior(plain, {c: (zc, b) for c, (zc, b, _) in prev.items()}).curve_sd(slot, z)
            row["inside_prev"][slot] = float(np.mean(np.abs(f - pv) <= zq * psd))
            row["half_width_prev"][slot] = float(np.mean(zq * psd) / np.std(f))
        if before is not None:
            bv, bsd = (cc.model.LackOfFitPosterior(plain, before).curve_sd(slot, z) if before
                       else plain.curve_sd(slot, z))
            row["inside_before"][slot] = float(np.mean(np.abs(f - bv) <= zq * bsd))
            row["half_width_before"][slot] = float(np.mean(zq * bsd) / np.std(f))
        ok = hw > 0
        row["error_over_half_width"][slot] = float(np.mean(np.abs(f - value)[ok] / hw[ok])) if np.any(ok) else 0.0
    return row


def record_before() -> None:
    """Make every fit also keep the lack-of-fit term of the rule before issue 48's sparse rule (on the same
    prepared record and mask): ``info["_lack_of_fit_before"]``, ``{curve: (centres, bias)}`` of the curves
    whose test rejects at ``LACK_OF_FIT_LEVEL`` (20 bins, no shrinkage; what every method had)."""
    import charcurves.fitting._lack_of_fit as lof

    new = lof.apply_lack_of_fit

    def both(model, record, mask=None, **kw):
        out = new(model, record, mask, **kw)
        if getattr(model, "posterior", None) is not None and model.info.get("objective") != "output-error":
            est = lof.lack_of_fit_bias(model, record, mask, bins=lof.LACK_OF_FIT_BINS)
            model.info["_lack_of_fit_before"] = {c: (zc, b) for c, (zc, b, p) in est.items()
                                                 if p < lof.LACK_OF_FIT_LEVEL}
        return out

    lof.apply_lack_of_fit = both


def before_rows(rows: list[dict]) -> list[dict]:
    """The rows with the band of the rule before the sparse rule in ``inside`` (``--before``); others dropped."""
    # lof_every_curve: the band is the rule's as recorded, not to be gated again (gated_rows)
    return [{**r, "inside": r["inside_before"], "half_width": r["half_width_before"], "lof_every_curve": True}
            for r in rows if "inside_before" in r]


def previous_rows(rows: list[dict]) -> list[dict]:
    """The rows with the previous estimate's band in ``inside`` (for the same tables); rows without it dropped."""
    out = []
    for r in rows:
        if "inside_prev" in r:
            out.append({**r, "inside": r["inside_prev"], "half_width": r["half_width_prev"],
                        "binned_p": r["binned_p_prev"], "lof_every_curve": False})  # gated at the old level
    return out


def load_rows(path=RESULTS) -> list[dict]:
    if not os.path.exists(path):
        return []
    with open(path, encoding="utf-8") as fh:
        return [json.loads(line) for line in fh if line.strip()]


# the tables are the library's (charcurves.experiments), which docs/uncertainty-zoo.md is rendered with
gated = gated_rows
table = coverage_table
per_curve = per_curve_table


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", default="0-4", help="e.g. 0-9")
    p.add_argument("--report-only", action="store_true")
    p.add_argument("--per-curve", action="store_true")
    p.add_argument("--half", default="report", choices=("report", "tuning"))
    p.add_argument("--methods", default=",".join(METHODS), help=f"comma-separated, of {', '.join(ALL_METHODS)}")
    p.add_argument("--settings", default=",".join(SETTINGS))
    p.add_argument("--systems", default="", help="comma-separated zoo systems (default: all of the half)")
    p.add_argument("--out", default=RESULTS, help="results file (JSON lines)")
    p.add_argument("--lof-level", type=float, default=None, help="tuning: the lack-of-fit term's test level")
    p.add_argument("--lof-bins", type=int, default=None, help="tuning: the lack-of-fit term's bins")
    p.add_argument("--gate", type=float, default=None,
                   help="tables: the term only where the binned test's p is below this (default: the library's "
                        "LACK_OF_FIT_LEVEL; exact for rows run at that level or a laxer one)")
    p.add_argument("--previous", action="store_true",
                   help="also score the lack-of-fit estimate before issue 48's level fix on the same fits")
    p.add_argument("--before", action="store_true",
                   help="also score the band of the rule before issue 48's sparse rule on the same fits")
    a = p.parse_args(argv)
    if a.lof_level is not None or a.lof_bins is not None:  # tuning runs (the tuning half only)
        import charcurves.fitting._lack_of_fit as lof

        lof.LACK_OF_FIT_LEVEL = lof.LACK_OF_FIT_LEVEL if a.lof_level is None else a.lof_level
        lof.LACK_OF_FIT_BINS = lof.LACK_OF_FIT_BINS if a.lof_bins is None else a.lof_bins
    lo, _, hi = a.seeds.partition("-")
    seeds = range(int(lo), int(hi or lo) + 1)
    methods = tuple(a.methods.split(","))
    out = a.out
    if not a.report_only:
        import torch

        torch.set_num_threads(1)
        if a.previous:
            from _lof_previous import record_previous

            record_previous()
        if a.before:
            record_before()
        os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
        done = {r["key"] for r in load_rows(out)}
        cache: dict = {}
        for job in jobs(seeds, a.half, methods, tuple(a.settings.split(",")), [s for s in a.systems.split(",") if s]):
            if "|".join(map(str, job)) in done:
                continue
            row = run_job(job, cache)
            with open(out, "a", encoding="utf-8") as fh:
                fh.write(json.dumps(row) + "\n")
            print(json.dumps(row), flush=True)
    rows = load_rows(out)
    from charcurves.fitting import LACK_OF_FIT_LEVEL

    # the term where the library's default adds it (rows run at a laxer level are exact at a stricter one)
    rows = gated(rows, LACK_OF_FIT_LEVEL if a.gate is None else a.gate)
    print(table(rows, methods))
    if any("inside_plain" in r for r in rows):
        print("\nThe plain Laplace band (no lack-of-fit term) of the same fits:\n")
        print(table(rows, methods, key="inside_plain"))
    prev = gated(previous_rows(load_rows(out)), LACK_OF_FIT_LEVEL if a.gate is None else a.gate)
    if prev:
        print("\nThe previous lack-of-fit estimate (before issue 48's level fix) on the same fits:\n")
        print(table(prev, methods))
    before = before_rows(load_rows(out))
    if before:
        print("\nThe rule before issue 48's sparse rule (the term where the test rejects) on the same fits:\n")
        print(table(before, methods))
    if a.per_curve:
        print(per_curve(rows))
        if before:
            print("\nPer curve, the rule before the sparse rule:\n")
            print(per_curve(before))
        if prev:
            print("\nPer curve, the previous estimate:\n")
            print(per_curve(prev))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
