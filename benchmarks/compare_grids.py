"""Per (method, SNR level): the curve RMSE of two benchmark runs on the same records, side by side.

Usage: ``python benchmarks/compare_grids.py BEFORE/results.csv AFTER/results.csv``. Jobs are matched by
(method, SNR, realisation), which fixes the record (the dataset seed derives from them and the base
seed); the statistic is the geometric mean over the matched realisations. Used for the core refactor
(benchmarks/results/core-check/PROVENANCE.md).
"""
import csv, sys, collections, math
def load(p):
    out = {}
    for r in csv.DictReader(open(p)):
        if r["status"] != "ok": continue
        out[(r["method"], float(r["snr_db"]), int(r["realization"]))] = (float(r["rmse_f1"]), float(r["rmse_f2"]))
    return out
full = load(sys.argv[1]); new = load(sys.argv[2])
by = collections.defaultdict(list)
for k, v in new.items():
    if k in full:
        by[(k[0], k[1])].append((full[k], v))
print(f"{'method':<22} {'SNR':>4} {'n':>2}  {'RMSE f1 before':>14} {'after':>10}  {'RMSE f2 before':>14} {'after':>10}")
for (m, snr), pairs in sorted(by.items(), key=lambda kv: (kv[0][0], -kv[0][1])):
    g = lambda i, j: math.exp(sum(math.log(max(p[i][j], 1e-300)) for p in pairs) / len(pairs))
    print(f"{m:<22} {snr:>4g} {len(pairs):>2}  {g(0,0):>14.3g} {g(1,0):>10.3g}  {g(0,1):>14.3g} {g(1,1):>10.3g}")
