"""The package's layers import only downward, so a lower layer never needs a higher one; and its modules stay small.

The import graph is built from the source: every ``import hcmt...`` / ``from hcmt... import`` / relative import,
wherever it stands (module top, function body, ``if TYPE_CHECKING``). A module may import its own layer's modules
and any layer below; ``hcmt/__init__.py`` (the lazy public API, PEP 562) and ``hcmt/__main__.py`` stand above all.
Imports of hcmt modules inside functions are refused too: they only ever dodged a cycle; the one exception is
hcmt.viz (an optional extra) in the design check's drawing functions (``PICTURES_WHEN_ASKED``).
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parent.parent / "src" / "hcmt"

#: layer of each top-level module or subpackage of hcmt, bottom (0) to top; equal numbers may not import each other
LAYERS = {
    "config": 0,
    "data": 1,
    "sim": 2,
    "graph": 2,
    "models": 3,
    "domains": 4,
    "inference": 5,
    "training": 6,
    "viz": 6,
    "design": 7,
    "cli": 8,
    "files": 0,
    "errors": -1,
}


#: modules that import hcmt.viz (the viz extra: matplotlib) inside the function that draws, so that the design check
#: runs without matplotlib unless a picture is asked for; still only downward
PICTURES_WHEN_ASKED = {"hcmt.design.reports", "hcmt.design.sweep"}


def module_name(path: Path) -> str:
    parts = path.relative_to(SRC.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_statements(path: Path) -> list[tuple[str, list[str], int, bool]]:
    """(imported hcmt module, the names a ``from`` import takes from it, line, inside a function) of every import in
    the file, relative ones resolved."""
    tree = ast.parse(path.read_text(), str(path))
    package = module_name(path) if path.name == "__init__.py" else module_name(path).rpartition(".")[0]
    out = []

    def visit(node, in_function: bool):
        for child in ast.iter_child_nodes(node):
            inner = in_function or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
            if isinstance(child, ast.Import):
                out.extend(
                    (a.name, [], child.lineno, in_function) for a in child.names if a.name.split(".")[0] == "hcmt"
                )
            elif isinstance(child, ast.ImportFrom):
                if child.level:
                    base = package.split(".")[: len(package.split(".")) - child.level + 1]
                    name = ".".join(base + ([child.module] if child.module else []))
                else:
                    name = child.module or ""
                if name.split(".")[0] == "hcmt":
                    out.append((name, [a.name for a in child.names], child.lineno, in_function))
            visit(child, inner)

    visit(tree, False)
    return out


def imports(path: Path) -> list[tuple[str, int, bool]]:
    """(imported hcmt module, line, inside a function) of every import in the file."""
    return [(name, line, in_function) for name, _, line, in_function in import_statements(path)]


def layer_of(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else None


def violations() -> list[str]:
    bad = []
    for path in sorted(SRC.rglob("*.py")):
        me = module_name(path)
        mine = layer_of(me)
        for target, line, in_function in imports(path):
            where = f"{path.relative_to(SRC.parent)}:{line} imports {target}"
            if mine in (None, "__main__"):  # the public API and `python -m hcmt`: above every layer
                continue
            if mine not in LAYERS:
                bad.append(f"{where}: {mine} is in no layer (add it to LAYERS)")
                continue
            theirs = layer_of(target)
            if theirs is None:
                bad.append(f"{where}: the top-level package (the lazy API) is for users, not for hcmt's modules")
            elif theirs not in LAYERS:
                bad.append(f"{where}: {theirs} is in no layer")
            elif theirs != mine and LAYERS[theirs] >= LAYERS[mine]:
                bad.append(f"{where}: {mine} (layer {LAYERS[mine]}) may not import {theirs} (layer {LAYERS[theirs]})")
            elif in_function and not (theirs == "viz" and me in PICTURES_WHEN_ASKED):
                bad.append(f"{where} inside a function: import hcmt modules at the top of the module")
    return bad


def module_graph() -> dict[str, set[str]]:
    """Which hcmt modules each module imports (``from hcmt.design import readout``: the module
    ``hcmt.design.readout``; a name that is no module: the package itself), wherever the import stands."""
    modules = {module_name(p) for p in SRC.rglob("*.py")}
    graph = {}
    for path in sorted(SRC.rglob("*.py")):
        me, out = module_name(path), set()
        for target, names, _, _ in import_statements(path):
            subs = {f"{target}.{n}" for n in names} & modules
            out |= subs if subs else {target} & modules
            if len(subs) < len(names) and target in modules:  # some names are the package's own
                out.add(target)
        graph[me] = out - {me}
    return graph


def module_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Each import cycle between modules found by a depth-first search, as the path that closes it
    (``[a, b, c, a]``)."""
    state, stack, found = {}, [], []

    def visit(m: str):
        state[m] = "open"
        stack.append(m)
        for n in sorted(graph.get(m, ())):
            if state.get(n) == "open":
                found.append(stack[stack.index(n) :] + [n])
            elif n not in state:
                visit(n)
        stack.pop()
        state[m] = "done"

    for m in sorted(graph):
        if m not in state:
            visit(m)
    return found


def test_no_module_imports_itself_through_others():
    """No cycle between modules, not only between packages: each module's imports go one way (a cycle works only
    by import order, and only until someone moves an import)."""
    assert module_cycles(module_graph()) == []


def test_the_cycle_check_finds_a_cycle(tmp_path, monkeypatch):
    """The test above can fail: a three-module cycle within one package (one leg under TYPE_CHECKING, one a
    relative import of a module by name) is found, an acyclic one is not."""
    fake = tmp_path / "hcmt"
    (fake / "design").mkdir(parents=True)
    (fake / "design" / "__init__.py").write_text("")
    (fake / "design" / "a.py").write_text("from hcmt.design.b import x\n")
    (fake / "design" / "b.py").write_text("from . import c\n")
    (fake / "design" / "c.py").write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from hcmt.design.a import y\n"
    )
    (fake / "design" / "d.py").write_text("from hcmt.design import a, b\n")
    monkeypatch.setattr(__import__(__name__), "SRC", fake)
    graph = module_graph()
    assert graph["hcmt.design.d"] == {"hcmt.design.a", "hcmt.design.b"}
    assert module_cycles(graph) == [["hcmt.design.a", "hcmt.design.b", "hcmt.design.c", "hcmt.design.a"]]
    (fake / "design" / "c.py").write_text("x = 1\n")
    assert module_cycles(module_graph()) == []


#: the most lines a module of src may hold, as the formatter leaves it: small rooms, one job each; the trainer, which
#: every training option passes through, a little less so that it stays the loop and not its helpers
MAX_LINES = 320
MAX_LINES_OF = {"hcmt.training.trainer": 300}


def too_long() -> list[str]:
    """Each module of src over its limit, with its line count."""
    out = []
    for path in sorted(SRC.rglob("*.py")):
        n, limit = len(path.read_text().splitlines()), MAX_LINES_OF.get(module_name(path), MAX_LINES)
        if n > limit:
            out.append(f"{path.relative_to(SRC.parent)}: {n} lines (at most {limit}): split it by job")
    return out


def test_no_module_is_too_long():
    assert too_long() == []


def test_the_size_check_sees_a_long_module(tmp_path, monkeypatch):
    """The test above can fail: a module one line over the limit is named, one at the limit is not."""
    fake = tmp_path / "hcmt"
    (fake / "training").mkdir(parents=True)
    (fake / "training" / "trainer.py").write_text("x = 1\n" * (MAX_LINES_OF["hcmt.training.trainer"] + 1))
    (fake / "training" / "other.py").write_text("x = 1\n" * MAX_LINES)
    monkeypatch.setattr(__import__(__name__), "SRC", fake)
    assert too_long() == ["hcmt/training/trainer.py: 301 lines (at most 300): split it by job"]


#: the most lines a function of src may hold, ``def`` to last line as the formatter leaves it (docstring included):
#: a longer one does several jobs, and a step with a job of its own becomes a helper with a name and a docstring
MAX_FUNCTION_LINES = 60


def functions(path: Path) -> list[tuple[str, int, int]]:
    """(qualified name in the module, ``def`` line, lines) of each function of the file: methods as
    ``Class.method``, nested functions as ``outer.inner``."""
    out = []

    def visit(node, prefix: str):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                name = prefix + child.name
                if not isinstance(child, ast.ClassDef):
                    out.append((name, child.lineno, child.end_lineno - child.lineno + 1))
                visit(child, name + ".")
            else:
                visit(child, prefix)

    visit(ast.parse(path.read_text(), str(path)), "")
    return out


def too_long_functions() -> list[str]:
    """Each function of src over the limit, as ``path:line name: N lines``."""
    out = []
    for path in sorted(SRC.rglob("*.py")):
        for name, line, n in functions(path):
            if n > MAX_FUNCTION_LINES:
                out.append(f"{path.relative_to(SRC.parent)}:{line} {name}: {n} lines")
    return out


def test_no_function_is_too_long():
    assert too_long_functions() == []


def test_the_function_size_check_sees_a_long_function(tmp_path, monkeypatch):
    """The test above can fail: a function and a method one line over the limit are named; one at the limit is
    not."""
    fake = tmp_path / "hcmt"
    (fake / "sim").mkdir(parents=True)
    (fake / "sim" / "mesh.py").write_text(
        "def short():\n"
        + "    x = 1\n" * (MAX_FUNCTION_LINES - 1)
        + "\n\ndef long():\n"
        + "    x = 1\n" * MAX_FUNCTION_LINES
    )
    (fake / "sim" / "solver.py").write_text(
        "class Model:\n    def __init__(self):\n" + "        x = 1\n" * MAX_FUNCTION_LINES
    )
    monkeypatch.setattr(__import__(__name__), "SRC", fake)
    assert too_long_functions() == [
        "hcmt/sim/mesh.py:63 long: 61 lines",
        "hcmt/sim/solver.py:2 Model.__init__: 61 lines",
    ]


def test_every_layer_imports_only_downward():
    assert violations() == []


def test_every_package_has_a_layer():
    packages = {p.name for p in SRC.iterdir() if p.is_dir() and (p / "__init__.py").is_file()}
    modules = {p.stem for p in SRC.glob("*.py") if p.stem not in ("__init__", "__main__")}
    assert packages | modules == set(LAYERS)


def test_the_checker_sees_violations(tmp_path, monkeypatch):
    """The test above can fail: an upward import, a function-level import and a relative one are each caught."""
    fake = tmp_path / "hcmt"
    (fake / "models").mkdir(parents=True)
    (fake / "inference").mkdir()
    (fake / "models" / "__init__.py").write_text("from hcmt.inference.run import Run\n")
    (fake / "models" / "m.py").write_text("def f():\n    from ..domains import adapters\n")
    (fake / "inference" / "__init__.py").write_text("def g():\n    import hcmt.models\n")
    (fake / "inference" / "ok.py").write_text("from hcmt.models import build_model\nfrom . import metrics\n")
    monkeypatch.setattr(__import__(__name__), "SRC", fake)
    found = violations()
    assert any(
        "models/__init__.py:1 imports hcmt.inference.run: models (layer 3) may not import inference" in v for v in found
    )
    assert any("models/m.py:2 imports hcmt.domains" in v for v in found)
    assert any("inference/__init__.py:2 imports hcmt.models inside a function" in v for v in found)
    assert not any("ok.py" in v for v in found)


@pytest.mark.slow  # one fresh interpreter per module
@pytest.mark.parametrize(
    "module",
    [
        "hcmt.config",
        "hcmt.models",
        "hcmt.domains.adapters",
        "hcmt.inference.run",
        "hcmt.training",
        "hcmt.viz.rollouts",
        "hcmt.design.check",
        "hcmt.cli",
        "hcmt.sim.params",
        "hcmt.design.basics",
        "hcmt.cli.parsers",
    ],
)
def test_each_layer_imports_alone(module):
    """Each module imports in a fresh interpreter (no cycle hidden by import order)."""
    r = subprocess.run([sys.executable, "-c", f"import {module}"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
