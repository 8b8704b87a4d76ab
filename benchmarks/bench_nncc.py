"""NN-CC speed and accuracy: charcurves' defaults against the paper's protocol, in one run.

The paper's protocol is written out plainly here (two 1-100-100-100-1 ReLU MLPs on raw inputs,
one Adam per network at lr 1e-4, full batch, symmetry as a penalty lambda = 10 on 1000 fixed
points, f2(0) = 0 by a post-hoc shift) so that the baseline does not depend on charcurves' code.
Its 20 000 epochs are timed on a prefix (--paper-epochs, default 2000) and scaled; the accuracy
it reaches after 20 000 epochs is quoted from a full run when --paper-full is given.

Each of our fits is timed as a whole process (`charcurves fit ...`), imports included.

    python benchmarks/bench_nncc.py [--seeds 5] [--paper-epochs 2000] [--paper-full]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np


def paper_protocol(traj, sym: bool, epochs: int, seed: int = 10):
    import torch

    torch.manual_seed(seed)

    def mlp():
        return torch.nn.Sequential(torch.nn.Linear(1, 100), torch.nn.ReLU(), torch.nn.Linear(100, 100),
                                   torch.nn.ReLU(), torch.nn.Linear(100, 100), torch.nn.ReLU(),
                                   torch.nn.Linear(100, 1))

    nn1, nn2 = mlp(), mlp()
    opt1 = torch.optim.Adam(nn1.parameters(), lr=1e-4)
    opt2 = torch.optim.Adam(nn2.parameters(), lr=1e-4)
    col = lambda a: torch.tensor(np.asarray(a), dtype=torch.float32).reshape(-1, 1)  # noqa: E731
    v, x, a, F = col(traj.v), col(traj.x), col(traj.a), col(traj.F)
    zv = col(np.linspace(traj.v.min(), traj.v.max(), 1000))
    zx = col(np.linspace(traj.x.min(), traj.x.max(), 1000))
    t0 = time.perf_counter()
    for _ in range(epochs):
        opt1.zero_grad()
        opt2.zero_grad()
        loss = torch.mean((a + nn1(v) + nn2(x) - F) ** 2)
        if sym:
            loss = loss + 10 * torch.mean((nn1(zv) + nn1(-zv)) ** 2) + 10 * torch.mean((nn2(zx) + nn2(-zx)) ** 2)
        loss.backward()
        opt1.step()
        opt2.step()
    seconds = time.perf_counter() - t0
    with torch.no_grad():
        c = float(nn2(torch.zeros(1, 1)))
        f1 = lambda z: nn1(col(z)).numpy().ravel() + c  # noqa: E731
        f2 = lambda z: nn2(col(z)).numpy().ravel() - c  # noqa: E731
        gv = np.linspace(traj.v.min(), traj.v.max(), 1000)
        gx = np.linspace(traj.x.min(), traj.x.max(), 1000)
        return seconds, f1(gv), f2(gx), gv, gx


def our_fit(csv: str, method: str, seed: int, extra=()):
    out = tempfile.mkdtemp(prefix="bench-")
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "charcurves", "fit", csv, "--method", method, "--out", out,
                        "--seed", str(seed), "--no-figure", "--quiet", *extra],
                       capture_output=True, text=True, env={**os.environ, "OMP_NUM_THREADS": "1"})
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        raise RuntimeError(r.stderr)
    res = json.load(open(os.path.join(out, "result.json")))
    return wall, res


def rmse_of(res, name, truth):
    g = np.asarray(res["curves"][name]["grid"])
    return float(np.sqrt(np.mean((np.asarray(res["curves"][name]["values"]) - truth(g)) ** 2)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--paper-epochs", type=int, default=2000)
    ap.add_argument("--paper-full", action="store_true", help="run the paper protocol's full 20 000 epochs")
    ap.add_argument("--systems", default="duffing,stick-slip")
    args = ap.parse_args()
    import torch

    torch.set_num_threads(1)
    from charcurves.data import corrupt
    from charcurves.systems import get_system

    print(f"{'system':<11} {'method':<10} {'who':<22} {'RMSE f1':>9} {'RMSE f2':>9} {'seconds/fit':>12}")
    for sysname in args.systems.split(","):
        system = get_system(sysname)
        truth = system.true_curves()
        clean = system.simulate()
        for method, sym in (("nn-cc", False), ("nn-cc+sym", True)):
            ours, theirs = [], []
            for seed in range(args.seeds):
                noisy = corrupt(clean, 20.0, seed=seed)
                with tempfile.NamedTemporaryFile(suffix=".csv", delete=False) as fh:
                    csv = fh.name
                noisy.to_csv(csv)
                wall, res = our_fit(csv, method, seed)
                ours.append((rmse_of(res, "f1", truth["f1"]), rmse_of(res, "f2", truth["f2"]), wall))
                if seed == 0:
                    epochs = 20000 if args.paper_full else args.paper_epochs
                    sec, p1, p2, gv, gx = paper_protocol(noisy, sym, epochs)
                    scaled = sec * 20000 / epochs
                    theirs.append((float(np.sqrt(np.mean((p1 - truth["f1"](gv)) ** 2))),
                                   float(np.sqrt(np.mean((p2 - truth["f2"](gx)) ** 2))), scaled))
            o = np.mean(ours, axis=0)
            p = theirs[0]
            print(f"{sysname:<11} {method:<10} {'charcurves default':<22} {o[0]:9.2e} {o[1]:9.2e} {o[2]:12.2f}")
            label = "paper protocol" + ("" if args.paper_full else f" ({args.paper_epochs} ep.)")
            print(f"{sysname:<11} {method:<10} {label:<22} {p[0]:9.2e} {p[1]:9.2e} {p[2]:12.2f}"
                  + ("" if args.paper_full else "  (time scaled to 20 000 epochs)"))
            print(f"{'':<11} {'':<10} {'ratio paper/ours':<22} {p[0] / o[0]:9.1f} {p[1] / o[1]:9.1f} {p[2] / o[2]:12.1f}")


if __name__ == "__main__":
    main()
