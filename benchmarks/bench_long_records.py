"""Long records: time and peak memory of a whole `charcurves fit --method nn-cc+sym` process against
the record's length, the Silverbox command of docs/silverbox.md, and the paper's protocol, in one run.

Records: the paper's Duffing (noise on the forcing, 20 dB, its sampling step 0.04) with 1 000,
100 000 and 1 000 000 samples (t_end scaled with the length). Each fit is a separate process run as
a user runs it (figure included, one torch thread); its wall time and peak resident memory come
from the operating system (``os.wait4``); the shortest record's process runs ``--repeat`` times
(default 3) and its figure is the median. The paper's protocol (bench_nncc.paper_protocol: two
1-100-100-100-1 ReLU MLPs, Adam lr 1e-4, the symmetry penalty) runs with 2 torch threads on the
1 000-sample record, its 20 000 epochs timed on a prefix and scaled.

    python benchmarks/bench_long_records.py [--sizes 1000,100000,1000000] [--paper-epochs 2000]
                                            [--silverbox PATH] [--repeat 3] [--json benchmarks/results/long_records.json]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
#: $SILVERBOX_CSV, else silverbox/SNLS80mV.csv of $CHARCURVES_DATA_DIR or ../shared/real-data (docs/silverbox.md)
SILVERBOX = Path(os.environ.get("SILVERBOX_CSV") or Path(os.environ.get("CHARCURVES_DATA_DIR") or HERE.parent.parent
                 / "shared" / "real-data") / "silverbox" / "SNLS80mV.csv")
SILVERBOX_ARGS = ["--x-col", "V2", "--force-col", "V1", "--sample-rate", "610.3515625", "--rows", "40650:105712",
                  "--family", "separable", "--method", "nn-cc+sym+post-sr", "--sym", "f1=odd,f2=odd", "--free-gain"]


def run_process(args: list[str]) -> tuple[float, float, str]:
    """Run ``python -m charcurves ARGS``: (wall seconds, peak resident MiB, stderr)."""
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "charcurves", *args], env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    err = proc.stderr.read() if proc.stderr else ""
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise RuntimeError(f"charcurves {' '.join(args)} failed ({proc.returncode}): {err[-2000:]}")
    return wall, usage.ru_maxrss / 1024.0, err


def curve_rmse(out: str, truth) -> tuple[float, float]:
    res = json.load(open(os.path.join(out, "result.json")))
    errs = []
    for name in ("f1", "f2"):
        g = np.asarray(res["curves"][name]["grid"])
        errs.append(float(np.sqrt(np.mean((np.asarray(res["curves"][name]["values"]) - truth[name](g)) ** 2))))
    return errs[0], errs[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="1000,100000,1000000")
    ap.add_argument("--paper-epochs", type=int, default=2000)
    ap.add_argument("--silverbox", default=str(SILVERBOX), help="SNLS80mV.csv ('' to skip)")
    ap.add_argument("--json", default=None, help="write the figures to this JSON file")
    ap.add_argument("--repeat", type=int, default=3,
                    help="processes timed on the shortest record (the median is its figure: one process is "
                         "the noisiest figure here, and the first of a session pays a cold file cache)")
    args = ap.parse_args()
    from charcurves.data import corrupt
    from charcurves.systems import get_system

    system = get_system("duffing")
    truth = system.true_curves()
    sizes = [int(s) for s in args.sizes.split(",")]
    work = tempfile.mkdtemp(prefix="bench-long-")
    load_before = os.getloadavg()
    rows = []
    print(f"{'samples':>9} {'wall s':>8} {'x 1k':>6} {'peak MiB':>9} {'RMSE f1':>9} {'RMSE f2':>9}  long-record stages")
    for n in sizes:
        rec = corrupt(system.simulate(t_end=40.0 * n / 1000, n_points=n), 20.0, on="force", seed=0)
        csv = os.path.join(work, f"duffing_{n}.csv")
        rec.to_csv(csv)
        out = os.path.join(work, f"fit_{n}")
        walls = []
        for _ in range(max(1, args.repeat) if n == sizes[0] else 1):
            shutil.rmtree(out, ignore_errors=True)
            wall, peak, _ = run_process(["fit", csv, "--method", "nn-cc+sym", "--out", out, "--quiet"])
            walls.append(wall)
        wall = float(np.median(walls))
        f1, f2 = curve_rmse(out, truth)
        info = json.load(open(os.path.join(out, "result.json")))["info"]
        lr = info.get("long_record")
        rows.append({"samples": n, "wall_s": wall, "wall_s_runs": walls, "peak_mib": peak, "rmse_f1": f1, "rmse_f2": f2,
                     "long_record": lr, "lm_iterations": info.get("lm_iterations")})
        ratio = wall / rows[0]["wall_s"]
        stages = (f"subset {lr['subset_samples']}, {lr['refine_iterations']} LM iterations on all samples"
                  if lr else "one stage")
        print(f"{n:>9} {wall:8.1f} {ratio:6.1f} {peak:9.0f} {f1:9.2e} {f2:9.2e}  {stages}", flush=True)
    silverbox = None
    if args.silverbox and os.path.isfile(args.silverbox):
        out = os.path.join(work, "silverbox")
        wall, peak, _ = run_process(["fit", args.silverbox, *SILVERBOX_ARGS, "--out", out, "--quiet"])
        res = json.load(open(os.path.join(out, "result.json")))
        timing = json.load(open(os.path.join(out, "timing.json")))
        silverbox = {"wall_s": wall, "peak_mib": peak, "timing": timing,
                     "closed_form": res.get("info", {}).get("output_error", {}).get("closed_form")}
        print(f"Silverbox command (docs/silverbox.md, 65 062 samples): {wall:.1f} s wall, {peak:.0f} MiB; "
              f"train {timing.get('train_seconds', 0):.1f} s, output error of the networks "
              f"{timing.get('output_error_before_post_sr.seconds', 0):.1f} s, post-SR {timing.get('post_sr_seconds', 0):.1f} s, "
              f"output error of the closed forms {timing.get('output_error.seconds', 0):.1f} s", flush=True)
    sys.path.insert(0, str(HERE))
    import torch
    from bench_nncc import paper_protocol

    torch.set_num_threads(2)
    rec = corrupt(system.simulate(), 20.0, on="force", seed=0)
    sec, *_ = paper_protocol(rec, True, args.paper_epochs)
    paper = sec * 20000 / args.paper_epochs
    print(f"paper protocol (NN-CC+sym, 1 000 samples, 2 threads, {args.paper_epochs} epochs timed, scaled to "
          f"20 000): {paper:.1f} s; whole charcurves process on the same record {rows[0]['wall_s']:.2f} s "
          f"= 1/{paper / rows[0]['wall_s']:.0f}")
    load_after = os.getloadavg()
    print(f"load average before {load_before[0]:.2f}, after {load_after[0]:.2f} (2 cores)")
    if args.json:
        doc = {"records": rows, "silverbox": silverbox, "paper_protocol_seconds": paper,
               "paper_epochs_timed": args.paper_epochs, "load_average": [load_before[0], load_after[0]],
               "torch": torch.__version__}
        Path(args.json).write_text(json.dumps(doc, indent=1) + "\n")
        print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
