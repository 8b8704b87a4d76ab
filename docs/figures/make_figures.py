"""The figures of docs/tutorial.md, made by the tutorial's own commands.

    python docs/figures/make_figures.py        (from the repository root; about 2-4 minutes on one core)

Runs the tutorial's steps 1, 4 and 5 in a temporary folder (simulate the Duffing record with 30 dB of
noise on x, keep t, x, F; ``charcurves fit own.csv --method nn-cc --sym auto --out fit --report``;
``charcurves validate`` on rows 0:300 and 500:800) and copies the two figures they write next to this script:
tutorial-curves.png (the fit's curves.png) and tutorial-validation.png (validate's validation.png),
each with a 64-colour palette so that it stays under 150 KB.
The fit is seeded and runs on one thread, so a rerun on the same versions writes the same files.
"""

from __future__ import annotations

import csv
import os
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent


def _charcurves(*args: str, cwd: Path) -> None:
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MPLBACKEND": "Agg"}
    subprocess.run([sys.executable, "-m", "charcurves", *args], cwd=cwd, env=env, check=True)


def _small_png(src: Path, dst: Path) -> None:
    """``src`` written to ``dst`` with a 64-colour palette (median cut, no dithering: the same bytes
    each time), which keeps a line figure sharp at about half the size."""
    from PIL import Image  # installed with matplotlib

    with Image.open(src) as image:
        small = image.convert("RGB").quantize(colors=64, method=Image.Quantize.MEDIANCUT,
                                              dither=Image.Dither.NONE)
    small.save(dst, format="PNG", optimize=True)


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        _charcurves("simulate", "duffing", "--out", "sim.csv", "--snr", "30", "--noise-on", "state", "--seed", "1",
                    cwd=work)
        with open(work / "sim.csv", newline="") as src, open(work / "own.csv", "w", newline="") as dst:
            rows = csv.DictReader(src)
            out = csv.writer(dst, lineterminator="\n")
            out.writerow(["t", "x", "F"])
            for row in rows:  # the tutorial's `cut -d, -f1,2,5`: the columns a measurement has
                out.writerow([row["t"], row["x"], row["F"]])
        _charcurves("fit", "own.csv", "--method", "nn-cc", "--sym", "auto", "--out", "fit", "--report", cwd=work)
        _charcurves("validate", "fit/model", "own.csv", "--rows", "0:300", "--rows", "500:800", "--out", "val",
                    cwd=work)
        _small_png(work / "fit" / "curves.png", HERE / "tutorial-curves.png")
        _small_png(work / "val" / "validation.png", HERE / "tutorial-validation.png")
    for name in ("tutorial-curves.png", "tutorial-validation.png"):
        print(f"wrote docs/figures/{name} ({(HERE / name).stat().st_size // 1024} KiB)")


if __name__ == "__main__":
    main()
