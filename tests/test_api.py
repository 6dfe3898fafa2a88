"""The README's Python API example runs as written (in a temporary folder)."""
import re
from pathlib import Path

README = Path(__file__).resolve().parent.parent / "README.md"


def test_readme_api_example_runs(tmp_path, monkeypatch):
    text = README.read_text()
    block = re.search(r"<!-- api-example[^>]*-->\s*```python\n(.*?)```", text, re.S)
    assert block, "README lost its api-example block"
    monkeypatch.chdir(tmp_path)
    namespace = {}
    exec(compile(block.group(1), "README.md (api example)", "exec"), namespace)
    assert (tmp_path / "run_tiny" / "metrics_test.json").is_file()
    assert namespace["graph"].num_nodes == namespace["target"].shape[0]
    assert namespace["p"].summary["peak_plate_stress_mpa"] > 0
