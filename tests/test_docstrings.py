"""Every public name of the API reference has a rendered docstring with an example, and the
examples run (doctests), so that none can rot.

The public names are found the way the documentation site finds them (docs/api/*.md,
mkdocs.yml): each ``::: module`` directive of an API page renders that module's public names, which
are its ``__all__`` when it has one, else the names it defines and the names it imports as
``from ._x import Name as Name`` (the griffe_public_redundant_aliases extension). The top-level
names (``charcurves._LAZY``) are documented on their subpackages' pages. The sources are read
statically, as griffe reads them, so the docstring checked is the one the site shows, also for a
module attribute (the string literal after the assignment).

The examples run in an empty namespace, in a temporary working directory (``tempfile`` writes
there too): each one imports what it uses, as a reader who copies it must. They are kept cheap
(short records, tiny training and search budgets), so that this file runs in about 20 s of one core.
An example that is too expensive to run carries ``# doctest: +SKIP`` and its docstring says why
("not run"); there are at most ``MAX_SKIPS`` such lines.
"""

from __future__ import annotations

import ast
import dataclasses
import doctest
import functools
import importlib
import inspect
import re
import sys
import tempfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src"
PACKAGE = "charcurves"
MAX_SKIPS = 5
# examples that need an optional dependency (an extra of pyproject.toml) run where it is installed
OPTIONAL = {
    "charcurves.data._diff_tv.TotalVariation": ("cvxpy",),
    "charcurves.symbolic": ("pyoperon",),
    "charcurves.symbolic._engine.OperonEngine": ("pyoperon",),
    "charcurves.symbolic._engine.SymbolicRegressionEngine": ("pyoperon",),
    "charcurves.symbolic._selection.SRResult": ("pyoperon",),
    "charcurves.symbolic._distill.distill_curve": ("pyoperon",),
    "charcurves.symbolic._distill.distill_curve_front": ("pyoperon",),
    "charcurves.fitting._symbolic_fit.fit_sr": ("pyoperon",),
    "charcurves.fitting._symbolic_fit.fit_sr_cc": ("pyoperon",),
    "charcurves.fitting._symbolic_fit.fit_symbolic": ("pyoperon",),
    "charcurves.fitting._post_sr.distill_model": ("pyoperon",),
}

# `::: module` and its indented options, at the start of a line of an API page
_DIRECTIVE = re.compile(r"^::: ([\w.]+)[ \t]*\n((?:[ \t]+\S.*\n)*)", re.MULTILINE)
_SECTION = re.compile(r"^(\w[\w ]*)\n-{3,}[ \t]*$", re.MULTILINE)


@dataclasses.dataclass(frozen=True)
class Documented:
    """A rendered docstring: the object it belongs to and where it is written."""

    module: str  # the module that defines the object (for a module docstring: the module itself)
    name: str  # its name there ("" for a module docstring)
    kind: str  # "class", "function", "attribute" or "module"
    raw: str | None  # the docstring as written (None: none)
    lineno: int  # line of the docstring in the module's file

    @property
    def path(self) -> str:
        return f"{self.module}.{self.name}" if self.name else self.module

    @property
    def text(self) -> str:
        return inspect.cleandoc(self.raw) if self.raw else ""


def _module_file(module: str) -> Path:
    path = SRC.joinpath(*module.split("."))
    return path / "__init__.py" if path.is_dir() else path.with_suffix(".py")


@functools.lru_cache(maxsize=None)
def _tree(module: str) -> ast.Module:
    return ast.parse(_module_file(module).read_text(encoding="utf-8"))


def _absolute(module: str, node: ast.ImportFrom) -> str:
    if not node.level:
        return node.module or ""
    base = module.split(".")
    if _module_file(module).name != "__init__.py":
        base = base[:-1]
    base = base[: len(base) - node.level + 1]
    return ".".join(base + ([node.module] if node.module else []))


@functools.lru_cache(maxsize=None)
def _bindings(module: str) -> dict[str, tuple]:
    """Module-level names: ("def", node), ("attribute", node, docstring node or None),
    ("from", source module, name there, redundant alias?) or ("import",)."""
    out: dict[str, tuple] = {}
    body = _tree(module).body
    for i, node in enumerate(body):
        if isinstance(node, (ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            out[node.name] = ("def", node)
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            nxt = body[i + 1] if i + 1 < len(body) else None
            doc = nxt if isinstance(nxt, ast.Expr) and isinstance(nxt.value, ast.Constant) and isinstance(
                nxt.value.value, str) else None
            for target in node.targets if isinstance(node, ast.Assign) else [node.target]:
                if isinstance(target, ast.Name):
                    out[target.id] = ("attribute", node, doc)
        elif isinstance(node, ast.ImportFrom):
            for alias in node.names:
                out[alias.asname or alias.name] = ("from", _absolute(module, node), alias.name,
                                                   alias.asname == alias.name)
        elif isinstance(node, ast.Import):
            for alias in node.names:
                out[alias.asname or alias.name.split(".")[0]] = ("import",)
    return out


def _exports(module: str) -> list[str] | None:
    for node in _tree(module).body:
        if isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            if any(isinstance(t, ast.Name) and t.id == "__all__" for t in targets) and node.value is not None:
                return list(ast.literal_eval(node.value))
    return None


def public_names(module: str) -> list[str]:
    """The names the API page of ``module`` lists (griffe's rule, with redundant aliases public)."""
    exports = _exports(module)
    if exports is not None:
        return exports
    return [name for name, b in _bindings(module).items() if not name.startswith("_")
            and (b[0] in ("def", "attribute") or (b[0] == "from" and b[3]))]


def resolve(module: str, name: str) -> Documented:
    """The definition behind ``module.name``, following imports to the module that writes it."""
    b = _bindings(module).get(name)
    if b is None:
        raise LookupError(f"{module} does not bind {name}")
    if b[0] == "from":
        return resolve(b[1], b[2])
    if b[0] == "def":
        node = b[1]
        doc = node.body[0] if ast.get_docstring(node, clean=False) is not None else None
        kind = "class" if isinstance(node, ast.ClassDef) else "function"
    elif b[0] == "attribute":
        node, doc, kind = b[1], b[2], "attribute"
    else:
        raise LookupError(f"{module}.{name} is a plain import")
    return Documented(module, name, kind, doc.value.value if doc else None, (doc or node).lineno)


def _module_docstring(module: str) -> Documented:
    body = _tree(module).body
    first = body[0] if body else None
    raw = first.value.value if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) else None
    return Documented(module, "", "module", raw if isinstance(raw, str) else None, first.lineno if first else 1)


def rendered_modules() -> dict[str, bool]:
    """``{module: whether its members are rendered}`` for every ``:::`` directive of docs/api/."""
    out: dict[str, bool] = {}
    for page in sorted((ROOT / "docs" / "api").glob("*.md")):
        for module, options in _DIRECTIVE.findall(page.read_text(encoding="utf-8")):
            if not _module_file(module).is_file():  # an object's own page (api/estimator.md): its module lists it
                continue
            out[module] = not re.search(r"^\s*members:\s*false\s*$", options, re.MULTILINE)
    return out


def public_objects() -> dict[str, Documented]:
    """``{documented path (page module.name): definition}`` for every name the API pages list."""
    out = {}
    for module, members in rendered_modules().items():
        if members:
            for name in public_names(module):
                out[f"{module}.{name}"] = resolve(module, name)
    return out


def rendered_docstrings() -> list[Documented]:
    """Each rendered docstring once: the public objects' (several names may share one
    definition) and the pages' module docstrings."""
    unique = {(d.module, d.name): d for d in public_objects().values()}
    unique.update({(m, ""): _module_docstring(m) for m in rendered_modules()})
    return sorted(unique.values(), key=lambda d: d.path)


def _top_level_names() -> dict[str, str]:
    """``charcurves._LAZY`` read statically: top-level name -> the module documenting it."""
    for node in _tree(PACKAGE).body:
        if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name) and node.target.id == "_LAZY":
            return ast.literal_eval(node.value)
    raise AssertionError("charcurves/__init__.py has no _LAZY table")


def examples_section(text: str) -> str | None:
    """The body of the numpydoc ``Examples`` section of a cleaned docstring, or None."""
    match = re.search(r"^Examples\n-{3,}[ \t]*$", text, re.MULTILINE)
    if match is None:
        return None
    rest = text[match.end():].lstrip("\n")
    following = _SECTION.search(rest)
    return rest[: following.start()] if following else rest


def _is_callable_api(module: str, name: str) -> bool:
    obj = getattr(importlib.import_module(module), name)
    return inspect.isclass(obj) or inspect.isroutine(obj)


def _example_problem(doc: Documented) -> str | None:
    section = examples_section(doc.text)
    if section is None:
        return "no Examples section" if doc.raw else "no docstring"
    examples = doctest.DocTestParser().get_examples(section)
    if not examples:
        return "an Examples section without a >>> line"
    if all(re.match(r"(from \S+ )?import ", e.source) for e in examples):
        return "an Examples section that only imports"
    if not any(e.want.strip() for e in examples):
        return "an Examples section that shows no output"
    return None


# --- the rule that selects the names -------------------------------------------------------------

def test_every_subpackage_page_is_read():
    modules = rendered_modules()
    assert modules[PACKAGE] is False, "the top-level directive of docs/api/index.md renders no members"
    assert modules[f"{PACKAGE}._errors"] is True
    for init in sorted((SRC / PACKAGE).glob("*/__init__.py")):
        if init.parent.name != "cli":
            assert modules.get(f"{PACKAGE}.{init.parent.name}") is True, f"no API page renders {init.parent.name}"


def test_the_static_rule_finds_the_names_an_import_finds():
    """Cross-check of the static reading: every listed name exists at run time, and where a module
    has ``__all__`` its public names are exactly the names it exports."""
    for path in public_objects():
        module, name = path.rsplit(".", 1)
        assert hasattr(importlib.import_module(module), name), f"{path} is listed but does not exist"
    for module, members in rendered_modules().items():
        exported = getattr(importlib.import_module(module), "__all__", None)
        if members and exported is not None:
            assert public_names(module) == list(exported), module
    data = public_names("charcurves.data")
    assert {"Trajectory", "SavitzkyGolay", "Spline"} <= set(data)
    assert "annotations" not in public_names("charcurves.systems")


def test_the_static_rule_agrees_with_griffe():
    """The site's own reader (griffe with the redundant-aliases extension, as in mkdocs.yml)
    selects the same names from each page's module; run where the docs extra is installed."""
    griffe = pytest.importorskip("griffe")
    extension = pytest.importorskip("griffe_public_redundant_aliases")
    extensions = griffe.load_extensions(extension.PublicRedundantAliasesExtension)
    ours = public_objects()
    for module, members in rendered_modules().items():
        if not members:
            continue
        path = _module_file(module)
        visited = griffe.visit(module, path, path.read_text(encoding="utf-8"), extensions=extensions)
        theirs = sorted(n for n, m in visited.members.items() if m.is_public and not n.startswith("__"))
        assert theirs == sorted(p.rsplit(".", 1)[1] for p in ours if p.rsplit(".", 1)[0] == module), module


def test_every_top_level_name_is_documented_on_a_page():
    documented = public_objects()
    for name, module in _top_level_names().items():
        assert isinstance(module, str) and f"{module}.{name}" in documented, f"charcurves.{name} has no API entry"


# --- the docstrings ------------------------------------------------------------------------------

def test_every_public_class_and_function_has_an_example():
    objects = public_objects()
    assert len(objects) > 200
    missing = []
    for path, doc in sorted(objects.items()):
        if doc.kind == "attribute" and not _is_callable_api(*path.rsplit(".", 1)):
            continue  # a constant: its value is shown
        problem = _example_problem(doc)
        if problem:
            missing.append(f"{path} ({doc.module}.{doc.name}): {problem}")
    assert not missing, f"{len(missing)} public names lack an example:\n" + "\n".join(missing)


def test_skipped_examples_are_few_and_say_why():
    skipping = [d for d in rendered_docstrings() if "+SKIP" in d.text]
    total = sum(d.text.count("+SKIP") for d in skipping)
    assert total <= MAX_SKIPS, f"{total} skipped examples: " + ", ".join(d.path for d in skipping)
    for d in skipping:
        assert "not run" in d.text, f"{d.path} skips an example without saying why it is not run"


def test_optional_dependencies_name_documented_examples():
    with_examples = {d.path for d in rendered_docstrings() if d.raw and ">>>" in d.raw}
    assert set(OPTIONAL) <= with_examples


def test_the_example_checks_can_fail():
    assert examples_section("Summary.\n\nExamples\n--------\n>>> 1 + 1\n2\n") == ">>> 1 + 1\n2\n"
    assert examples_section("Summary.\n\nNotes\n-----\n>>> 1\n1\n") is None
    for text in ("A.\n\nExamples\n--------\n>>> import math\n", "A.\n\nExamples\n--------\n>>> x = 1\n",
                 "A.\n\nExamples\n--------\nNone.\n\nNotes\n-----\n>>> 1\n1\n"):
        assert _example_problem(Documented("m", "n", "function", text, 1)) is not None
    assert _example_problem(Documented("m", "n", "function", "A.\n\nExamples\n--------\n>>> 2\n2\n", 1)) is None
    failed, report = _run_examples(Documented("m", "n", "function", "A.\n\n>>> 1 + 1\n3\n", 1))
    assert failed == 1 and "Expected:" in report
    assert _run_examples(Documented("m", "n", "function", "A.\n\n>>> import math\n>>> math.pi > 3\nTrue\n", 1))[0] == 0
    assert _run_examples(Documented("m", "n", "function", "A.\n\n>>> np.pi\n3.14\n", 1))[0] == 1  # nothing pre-imported


# --- the examples run ----------------------------------------------------------------------------

_WITH_EXAMPLES = [d for d in rendered_docstrings() if d.raw and ">>>" in d.raw]


def _run_examples(doc: Documented) -> tuple[int, str]:
    """Run the examples of ``doc`` in an empty namespace: ``(failures, doctest's report)``."""
    test = doctest.DocTestParser().get_doctest(doc.raw or "", {"__name__": "__doctest__"}, doc.path,
                                               str(_module_file(doc.module)), doc.lineno - 1)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    report: list[str] = []
    try:
        result = runner.run(test, out=report.append)
    finally:
        if "matplotlib.pyplot" in sys.modules:
            sys.modules["matplotlib.pyplot"].close("all")
    return result.failed, "".join(report)


@pytest.mark.parametrize("doc", _WITH_EXAMPLES, ids=[d.path for d in _WITH_EXAMPLES])
def test_examples_run(doc, tmp_path, monkeypatch):
    for module in OPTIONAL.get(doc.path, ()):
        pytest.importorskip(module)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))  # the examples' temporary files
    failed, report = _run_examples(doc)
    assert failed == 0, report
