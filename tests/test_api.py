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


def test_train_api_applies_overrides_to_a_dict_and_any_model_case(tmp_path, tiny_config):
    """overrides reach a dict config too; "MGN" is the model mgn; Run.load takes the RunFolder it names."""
    import hcmt
    from hcmt.inference.run import Run, RunFolder
    from viz_runs import impact_dataset

    data = impact_dataset(tmp_path / "data", n_test=1)
    cfg = tiny_config("train.steps=5")
    summary = hcmt.train(cfg, data, "MGN", tmp_path / "run", overrides=["train.steps=2"], progress=False)
    assert summary["steps"] == 2
    folder = RunFolder(tmp_path / "run")
    assert folder.info["model"]["name"] == "mgn" and folder.info["config"]["train"]["steps"] == 2
    run = Run.load(folder, "cpu")
    assert run.label == "MGN" and run.folder.path == folder.path and folder.steps_done() == 2
    import pytest

    with pytest.raises(ValueError, match="unknown model 'mesh'"):
        hcmt.train(cfg, data, "mesh", tmp_path / "other", progress=False)
