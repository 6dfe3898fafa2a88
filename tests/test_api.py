"""The README's Python API example runs as written (in a temporary folder)."""

import ast
import inspect
import re
from pathlib import Path

import pytest

import hcmt
from hcmt.data.runs import RunFolder
from hcmt.inference.run import Run
from viz_runs import impact_dataset

pytestmark = pytest.mark.slow  # the README example trains a run

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
    assert namespace["p"].summary.peak_plate_stress_mpa > 0


def test_train_api_refuses_a_held_folder_in_python_words(tmp_path):
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "run.yaml").write_text("x: 1\n")
    data = impact_dataset(tmp_path / "data", n_test=1)  # the arguments are checked first, then the folder
    with pytest.raises(ValueError, match=r"resume=True.*overwrite=True") as exc:
        hcmt.train("impact_plate_cpu", data, "hcmt", tmp_path / "run")
    assert "--" not in str(exc.value)


def test_train_api_applies_overrides_to_a_dict_and_any_model_case(tmp_path, tiny_config):
    """overrides reach a dict config too; "MGN" is the model mgn; Run.load takes the RunFolder it names."""
    data = impact_dataset(tmp_path / "data", n_test=1)
    cfg = tiny_config("train.steps=5")
    summary = hcmt.train(cfg, data, "MGN", tmp_path / "run", overrides=["train.steps=2"], progress=False)
    assert summary["steps"] == 2
    folder = RunFolder(tmp_path / "run")
    assert folder.info["model"]["name"] == "mgn" and folder.info["config"].train.steps == 2
    run = Run.load(folder, "cpu")
    assert run.label == "MGN" and run.folder.path == folder.path and folder.steps_done() == 2
    with pytest.raises(ValueError, match="unknown model 'mesh'"):
        hcmt.train(cfg, data, "mesh", tmp_path / "other", progress=False)


def test_the_public_api_is_declared_for_type_checkers_and_loads_lazily():
    """Every lazy name is also imported under TYPE_CHECKING (what IDEs read), listed in __all__ and resolvable;
    the model classes document their constructor arguments."""
    tree = ast.parse(inspect.getsource(hcmt))
    checked = {
        a.asname or a.name
        for node in ast.walk(tree)
        if isinstance(node, ast.If) and getattr(node.test, "id", "") == "TYPE_CHECKING"
        for imp in node.body
        for a in imp.names
    }
    assert checked == set(hcmt._LAZY)
    assert set(hcmt._LAZY) | {"load_pretrained", "__version__"} == set(hcmt.__all__)
    for name in hcmt._LAZY:
        assert getattr(hcmt, name) is not None
    for cls in (hcmt.HCMT, hcmt.MGN, hcmt.GT):
        doc = cls.__doc__ or ""
        params = [p for p in inspect.signature(cls.__init__).parameters if p != "self"]
        assert all(p in doc for p in params), (cls.__name__, [p for p in params if p not in doc])
        assert "Shapes" in doc
