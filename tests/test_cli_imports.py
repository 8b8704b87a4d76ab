"""The command line's cheap paths do not load torch or the fitting stack (issue 49): ``--version``,
``--help``, ``simulate`` and a usage error that exits 2 before any fit start in a fraction of the
1-2 s that importing torch costs, which the many CLI subprocess tests pay otherwise."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

_PROBE = """
import json, sys
from charcurves.cli import main
try:
    code = main(sys.argv[1:])
except SystemExit as e:
    code = e.code
print(json.dumps([code, [m for m in ("torch", "scipy.stats", "sympy", "charcurves.fitting") if m in sys.modules]]))
"""


@pytest.mark.parametrize(("argv", "expected"), [(["--version"], 0), (["--help"], 0),
                                              (["simulate", "duffing", "--out", "{tmp}/x.csv"], 0),
                                              (["simulate", "duffing", "--out", "{tmp}/x.csv", "--snr", "nan"], 2)])
def test_a_cheap_command_does_not_import_torch(argv, expected, tmp_path):
    argv = [a.format(tmp=tmp_path) for a in argv]
    out = subprocess.run([sys.executable, "-c", _PROBE, *argv], capture_output=True, text=True, check=False)
    code, loaded = json.loads(out.stdout.strip().splitlines()[-1])
    assert (code or 0) == expected, out.stderr
    assert loaded == []
    if argv[0] == "simulate":
        assert (tmp_path / "x.csv").exists() == (expected == 0)
