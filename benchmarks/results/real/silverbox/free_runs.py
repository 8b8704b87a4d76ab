"""The free runs of real.json, redone from the saved model with a longer time budget:

    python benchmarks/results/real/silverbox/free_runs.py MODEL_DIR DATA_DIR OUT.json
"""

import json
import sys
import time

from charcurves.datasets import silverbox
from charcurves.fitting import load_model
from charcurves.simulate import free_run_error

model_dir, data_dir, out_path = sys.argv[1:4]
m = load_model(model_dir)
d = silverbox(data_dir)
oe = m.info.get("output_error") or {}
hold, sub = oe.get("hold", "linear"), int(oe.get("substeps", 4))
out = {}
for name, rec in d.tests.items():
    t = time.time()
    rmse, res = free_run_error(m, rec, hold=hold, substeps=sub, init_window=d.init_window, time_budget=1500)
    out[name] = {"rmse_mV": rmse * 1e3, "status": res.status, "seconds": time.time() - t}
    print(name, out[name], flush=True)
with open(out_path, "w", encoding="utf-8") as fh:
    json.dump(out, fh, indent=1)
