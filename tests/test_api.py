"""The README's Python API example runs as written (in a temporary folder)."""
import re
from pathlib import Path

README = Path(__file__).resolve().parent.parent / "README.md"


def test_readme_api_example_runs_twice_in_a_row(tmp_path, monkeypatch):
    text = README.read_text()
    block = re.search(r"<!-- api-example[^>]*-->\s*```python\n(.*?)```", text, re.S)
    assert block, "README lost its api-example block"
    monkeypatch.chdir(tmp_path)
    for _ in range(2):  # a user runs it again: nothing may ask for a command-line flag
        namespace = {}
        exec(compile(block.group(1), "README.md (api example)", "exec"), namespace)
    assert (tmp_path / "run_tiny" / "metrics_test.json").is_file()
    assert namespace["graph"].num_nodes == namespace["target"].shape[0]
    assert namespace["p"].summary["peak_plate_stress_mpa"] > 0


def test_train_api_refuses_a_held_folder_in_python_words(tmp_path):
    import pytest

    import hcmt

    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "run.yaml").write_text("x: 1\n")
    with pytest.raises(ValueError, match=r"resume=True.*overwrite=True") as exc:
        hcmt.train("impact_plate_cpu", tmp_path / "nodata", "hcmt", tmp_path / "run")
    assert "--" not in str(exc.value)
