"""What the docs and the code tell a reader holds on a fresh clone: no command names a folder of the machine that ran
it (data and run folders are relative paths or ``$HCMT_WORK``, docs/RESULTS.md "Folders"), no comment sends the
reader to a tracker they cannot see instead of saying why, and every ``hcmt.x.y`` a docstring or doc names exists."""

from __future__ import annotations

import ast
import importlib
import inspect
import io
import re
import sys
import tokenize
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
#: folders never scanned: git-ignored work and build output (``benchmarks/work`` is ``$HCMT_WORK``'s default)
SKIP_DIRS = {"work", "__pycache__", ".pytest_cache", ".venv", "build"}


def files(root: Path, parts: tuple[str, ...], suffixes: tuple[str, ...]) -> list[Path]:
    """The files under ``root / part`` (a file or a folder) with one of ``suffixes``, skipping :data:`SKIP_DIRS`."""
    out = []
    for part in parts:
        base = root / part
        found = [base] if base.is_file() else sorted(base.rglob("*")) if base.is_dir() else []
        out += [
            f
            for f in found
            if f.is_file() and f.suffix in suffixes and not SKIP_DIRS & set(f.relative_to(root).parts[:-1])
        ]
    return out


def hits(paths: list[Path], pattern: re.Pattern, root: Path = ROOT) -> list[str]:
    """``FILE:LINE: match`` for every match of ``pattern`` in ``paths``."""
    out = []
    for f in paths:
        for i, line in enumerate(f.read_text(errors="replace").splitlines(), 1):
            out += [f"{f.relative_to(root)}:{i}: {m.group(0)}" for m in pattern.finditer(line)]
    return out


#: an absolute folder of a machine: /work/..., /home/..., /root/..., /tmp/... (not ``benchmarks/work/``, a URL's path
#: or ``$HCMT_WORK/...``: the character before the slash must not belong to a word or a path)
MACHINE_PATH = re.compile(r"(?<![\w.$/~-])/(?:work|home|root|tmp)/[\w.${}/-]*")


def machine_paths(root: Path = ROOT) -> list[str]:
    scanned = files(root, ("README.md", "docs", "benchmarks", "src"), (".md", ".py", ".sh", ".json"))
    return hits([f for f in scanned if f.name != Path(__file__).name], MACHINE_PATH, root)


def test_no_command_or_result_names_a_folder_of_the_machine_that_ran_it():
    found = machine_paths()
    assert not found, (
        "absolute machine paths (write them relative to the checkout or as $HCMT_WORK/..., "
        'docs/RESULTS.md "Folders"; result files: benchmarks/common.py\'s portable):\n' + "\n".join(found)
    )


#: a pointer to the project's tracker: "issue 35", "Issue #4", "issues 36", 'issue "Fast on a GPU"', "the issue's
#: goals" (this file is not scanned: it holds the examples)
TRACKER = re.compile(r"\b[Ii]ssues?\s*(?:#\s*\d+|\d+\b|\"[^\"]+\")|\b[Ii]ssue's\b")


def tracker_references(root: Path = ROOT) -> list[str]:
    scanned = files(root, ("README.md", "docs", "benchmarks", "src", "tests"), (".md", ".py", ".sh", ".json"))
    return hits([f for f in scanned if f.name != Path(__file__).name], TRACKER, root)


def test_no_comment_or_doc_points_at_an_issue_tracker_instead_of_the_reason():
    found = tracker_references()
    assert not found, (
        "references to an issue tracker the reader cannot see (say what the choice does and why):\n" + "\n".join(found)
    )


#: a dotted name in the package (``hcmt.x.y.func``, also inside :func:`...`): not preceded by a word, path or dot
#: character, so ``models/hcmt.py`` and ``pretrained:hcmt.x`` are not read as names
DOTTED = re.compile(r"(?<![\w./:-])hcmt(?:\.[A-Za-z_]\w*)+")
#: a dotted name that ends like a file is a file name (``hcmt.py``, ``hcmt.yaml``), not a Python name
FILE_ENDINGS = {"py", "md", "json", "yaml", "yml", "pt", "h5", "npz", "txt", "toml", "log", "csv", "sh"}


def _attribute(obj, name: str):
    """``obj.name``; for a class, also an instance attribute its source assigns (``self.name = ...`` or an
    annotation), which only an instance has. Raises AttributeError when neither holds."""
    if hasattr(obj, name):
        return getattr(obj, name)
    if inspect.isclass(obj):
        if name in getattr(obj, "__annotations__", {}):
            return None
        try:
            if re.search(rf"\bself\.{name}\s*(?::[^=]+)?=", inspect.getsource(obj)):
                return None
        except (OSError, TypeError):
            pass
    raise AttributeError(name)


def resolves(name: str) -> bool | None:
    """Whether ``hcmt.x.y.z`` names a module, or an attribute of one, by import (no code of the package runs but its
    modules' top level). None when it cannot be told here: a module that needs an optional dependency this
    environment lacks (e.g. matplotlib for ``hcmt.viz``)."""
    parts = name.split(".")
    for i in range(len(parts), 0, -1):
        module = ".".join(parts[:i])
        try:
            obj = importlib.import_module(module)
        except ModuleNotFoundError as exc:
            if exc.name and (module == exc.name or module.startswith(exc.name + ".")):
                continue  # not a module: the name goes on as attributes of a shorter prefix
            return None  # an optional dependency is missing
        try:
            for attr in parts[i:]:
                obj = _attribute(obj, attr)
        except AttributeError:
            return False
        return True
    return False


def prose(path: Path) -> list[tuple[int, str]]:
    """(line, text) of what a reader reads as prose: a Markdown file's lines; a Python file's comments and docstrings
    (a string in code may name a module on purpose, e.g. a test's made-up ``hcmt.design.a``)."""
    text = path.read_text(errors="replace")
    if path.suffix != ".py":
        return list(enumerate(text.splitlines(), 1))
    try:
        tree = ast.parse(text)
        tokens = list(tokenize.generate_tokens(io.StringIO(text).readline))
    except (SyntaxError, tokenize.TokenError):
        return []
    out = [(t.start[0], t.string) for t in tokens if t.type == tokenize.COMMENT]
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if (
            isinstance(body, list)
            and body
            and isinstance(body[0], ast.Expr)
            and isinstance(body[0].value, ast.Constant)
            and isinstance(body[0].value.value, str)
        ):
            first = body[0].lineno
            out += [(first + k, line) for k, line in enumerate(body[0].value.value.splitlines())]
    return out


def stale_references(root: Path = ROOT) -> list[str]:
    scanned = files(root, ("README.md", "docs", "benchmarks", "src", "tests"), (".md", ".py"))
    scanned = [f for f in scanned if f.name != Path(__file__).name]  # its examples (hcmt.x.y) are not names
    where: dict[str, list[str]] = {}
    for f in scanned:
        for i, line in prose(f):
            for m in DOTTED.finditer(line):
                where.setdefault(m.group(0), []).append(f"{f.relative_to(root)}:{i}")
    return [
        f"{name} ({', '.join(spots[:3])})"
        for name, spots in sorted(where.items())
        if name.rsplit(".", 1)[-1] not in FILE_ENDINGS and resolves(name) is False
    ]


def test_every_named_function_and_module_exists():
    found = stale_references()
    assert not found, (
        "docstrings or docs name a function or module that does not exist (moved? renamed?):\n" + "\n".join(found)
    )


def test_benchmarks_record_folders_as_a_fresh_clone_reads_them():
    """benchmarks/common.py's ``portable``: the work folder becomes ``$HCMT_WORK``, the checkout a relative path,
    anything else and every number stays as it is."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import common

    work, here = str(common.WORK), str(common.CHECKOUT)
    got = common.portable(
        {
            "command": f"python x.py --data {work}/data/ip480 --new {here} --json {here}/a.json",
            "runs": [Path(f"{work}/runs/r"), f"{work}"],
            "other": "/elsewhere/x",
            "n": 0.1 + 0.2,
        }
    )
    assert got == {
        "command": "python x.py --data $HCMT_WORK/data/ip480 --new . --json a.json",
        "runs": ["$HCMT_WORK/runs/r", "$HCMT_WORK"],
        "other": "/elsewhere/x",
        "n": 0.1 + 0.2,
    }
    assert not common.portable(f"{work}ish/x").startswith("$HCMT_WORK")  # a sibling whose name starts alike
