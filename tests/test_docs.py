"""The documentation that is generated or promised stays true: docs/cli.md is the
argument parsers' own help, regenerated in memory; the README stays a front door and its links lead somewhere."""

import importlib.util
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def gen_cli_docs():
    spec = importlib.util.spec_from_file_location("gen_cli_docs", ROOT / "scripts" / "gen_cli_docs.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_cli_reference_is_fresh():
    text = gen_cli_docs().render()
    assert (ROOT / "docs" / "cli.md").read_text() == text, (
        "docs/cli.md is stale: run `PYTHONPATH=src python scripts/gen_cli_docs.py`"
    )


def test_cli_reference_has_every_command_and_no_machine_numbers(monkeypatch):
    """Every command has its section; the text does not depend on the terminal's width or this machine's cores."""
    import hcmt.cli

    monkeypatch.setenv("COLUMNS", "40")
    text = gen_cli_docs().render()
    for name in hcmt.cli.COMMANDS:
        assert f"\n## hcmt {name}\n" in text
    assert "## hcmt surrogate fit" in text
    assert "this machine's cores (N)" in text
    assert (ROOT / "docs" / "cli.md").read_text() == text
    assert hcmt.cli.machine_cores() >= 1  # restored: a real count again


def test_architecture_map_names_every_module_and_the_layers():
    """docs/architecture.md, the map of the code, names every module of src/hcmt and every layer of
    tests/test_layers.py."""
    from test_layers import LAYERS

    text = (ROOT / "docs" / "architecture.md").read_text()
    src = ROOT / "src" / "hcmt"
    missing = [
        str(p.relative_to(src)) for p in sorted(src.rglob("*.py")) if p.name != "__init__.py" and p.name not in text
    ]
    assert missing == [], f"docs/architecture.md does not name {missing}"
    chain = re.search(r"```\n(errors .*?)\n```", text).group(1)
    assert set(re.findall(r"\w+", chain)) == set(LAYERS)


def test_readme_is_a_front_door():
    """The README stays under 200 lines and every relative link in it leads to a file."""
    text = (ROOT / "README.md").read_text()
    assert text.count("\n") < 200
    links = re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", text)
    assert "docs/cli.md" in links and "docs/architecture.md" in links and "docs/MODELS.md" in links
    assert [link for link in links if "://" not in link and not (ROOT / link).exists()] == []
    for name in ("architecture.md", "design-check.md", "gpu.md", "results-summary.md"):
        page = ROOT / "docs" / name
        links = re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", page.read_text())
        assert [link for link in links if "://" not in link and not (page.parent / link).exists()] == [], name


def test_no_python_line_over_120_characters():
    """ruff's E501 does not count a trailing ``# noqa`` pragma, so a long import with one would pass it: this counts
    every character of every line of the Python files under src, tests, benchmarks and scripts."""
    long = [
        f"{p.relative_to(ROOT)}:{i}"
        for folder in ("src", "tests", "benchmarks", "scripts")
        for p in sorted((ROOT / folder).rglob("*.py"))
        for i, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1)
        if len(line) > 120
    ]
    assert not long, f"lines over 120 characters: {', '.join(long)}"
