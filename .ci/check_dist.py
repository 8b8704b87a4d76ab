"""Check the release files that `python -m build` wrote: python .ci/check_dist.py DIST_DIR.

The sdist must hold what a build from it needs (pyproject.toml, README.md, LICENSE, the package
with py.typed) and no junk (virtual environments, results, caches, the docs build); the wheel must
ship py.typed and the LICENSE, and both must carry the version of src/charcurves/_version.py.
"""

from __future__ import annotations

import re
import sys
import tarfile
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
VERSION = re.search(r'^__version__ = "([^"]+)"$', (ROOT / "src/charcurves/_version.py").read_text(), re.M).group(1)
JUNK = re.compile(r"(^|/)(\.venv|venv|site|dist|build|results|runs|out|charcurves-demo|__pycache__|\.pytest_cache|"
                  r"\.hypothesis|\.git|\.ci|benchmarks|tests|docs)(/|$)|\.py[cod]$")


def main(dist: Path) -> list[str]:
    errors = []
    sdists = list(dist.glob("charcurves-*.tar.gz"))
    wheels = list(dist.glob("charcurves-*.whl"))
    if len(sdists) != 1 or len(wheels) != 1:
        return [f"expected one sdist and one wheel in {dist}, found {sdists + wheels}"]
    sdist, wheel = sdists[0], wheels[0]
    for path, expected in ((sdist, f"charcurves-{VERSION}.tar.gz"), (wheel, f"charcurves-{VERSION}-py3-none-any.whl")):
        if path.name != expected:
            errors.append(f"{path.name}: expected {expected} (version {VERSION} from _version.py)")

    top = f"charcurves-{VERSION}/"
    with tarfile.open(sdist) as tar:
        names = [n[len(top):] for n in tar.getnames() if n.startswith(top)]
    needed = ["pyproject.toml", "README.md", "LICENSE", "CHANGELOG.md", "CITATION.cff", "PKG-INFO",
              "src/charcurves/__init__.py", "src/charcurves/_version.py", "src/charcurves/py.typed"]
    errors += [f"sdist lacks {n}" for n in needed if n not in names]
    errors += [f"sdist holds a path it should not: {n}" for n in names if JUNK.search(n)]

    with zipfile.ZipFile(wheel) as whl:
        wnames = whl.namelist()
        meta = whl.read(f"charcurves-{VERSION}.dist-info/METADATA").decode()
    needed = ["charcurves/__init__.py", "charcurves/py.typed", f"charcurves-{VERSION}.dist-info/licenses/LICENSE"]
    errors += [f"wheel lacks {n}" for n in needed if n not in wnames]
    errors += [f"wheel holds a file outside the package: {n}" for n in wnames
               if not n.startswith(("charcurves/", f"charcurves-{VERSION}.dist-info/"))]
    errors += [f"wheel holds a path it should not: {n}" for n in wnames if JUNK.search(n)]
    if f"\nVersion: {VERSION}\n" not in meta:
        errors.append(f"wheel METADATA does not say Version: {VERSION}")
    if "\nLicense-Expression: MIT\n" not in meta:
        errors.append("wheel METADATA does not say License-Expression: MIT")
    print(f"{sdist.name}: {len(names)} entries; {wheel.name}: {len(wnames)} files")
    return errors


if __name__ == "__main__":
    problems = main(Path(sys.argv[1] if len(sys.argv) > 1 else "dist"))
    for problem in problems:
        print("check_dist:", problem, file=sys.stderr)
    sys.exit(1 if problems else 0)
