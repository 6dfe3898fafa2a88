"""Config files a new user writes by mistake: a ``base`` loop of one, two or
three files, a key given twice at any depth, a config of another dataset than the data's, YAML 1.1's number
strings (``1e-3``), a relative ``base``, wrong types, and the Python API's loose arguments. Each refusal: one line
naming the file and the key and what was expected (``InputError``; ``hcmt train``: exit 2, nothing written)."""

import random
from pathlib import Path

import pytest
import torch

import hcmt
import hcmt.config.threads
from hcmt.cli import GUARD, main as cli
from hcmt.config import Config, check_same_dataset, default_threads, load_config, set_threads
from hcmt.errors import InputError
from hcmt.sim.generate import generate_dataset
from hcmt.sim.params import Settings

ONE_LINE = 300  # the project's bound on a refusal, paths aside


@pytest.fixture(scope="module")
def impact(tmp_path_factory) -> Path:
    """An Impact Plate dataset (meta.json says ``dataset: impact_plate``), 1/1/1 trajectories of 4 frames."""
    out = tmp_path_factory.mktemp("fuzz") / "data"
    generate_dataset(
        out,
        preset="small",
        counts={"train": 1, "valid": 1, "test": 1},
        seed=0,
        settings=Settings(frames=4),
        progress=False,
    )
    return out


def refused(text: str, *paths: Path) -> None:
    """``text`` is one line, short but for the ``paths`` it names."""
    assert "\n" not in text and "Traceback" not in text
    assert len(text) - sum(text.count(str(p)) * len(str(p)) for p in paths) <= ONE_LINE, text


def refused_by_train(capsys, tmp_path: Path, config: str, data: Path, *paths: Path) -> str:
    """``hcmt train`` of ``config``: exit 2, one line, no run folder left."""
    out = tmp_path / "run"
    rc = cli(
        [
            "train",
            "--config",
            config,
            "--data",
            str(data),
            "--model",
            "mgn",
            "--out",
            str(out),
            "--steps",
            "1",
            "--threads",
            "1",
            "--no-progress",
        ]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and len(err[0]) <= GUARD, err
    refused(err[0], *paths)
    assert not out.exists()
    return err[0]


# -- base loops ----------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("n", [1, 2, 3])
def test_a_base_loop_is_refused_naming_its_files(tmp_path, capsys, impact, n):
    names = [f"c{i}.yaml" for i in range(n)]
    for i, name in enumerate(names):
        (tmp_path / name).write_text(f"base: {names[(i + 1) % n]}\ntrain:\n  steps: {i + 1}\n")
    first = tmp_path / names[0]
    with pytest.raises(InputError) as exc:
        load_config(str(first))
    msg = str(exc.value)
    refused(msg, first)
    loop = " -> ".join([str(first), *names[1:], names[0]])
    assert f"config {first}: its base chain is a loop, {loop}" in msg and "`base`" in msg
    line = refused_by_train(capsys, tmp_path, str(first), impact, first)
    assert loop in line and line.startswith("hcmt train: error: config ")


def test_a_loop_below_the_first_file_names_the_loop_only(tmp_path):
    (tmp_path / "top.yaml").write_text("base: a.yaml\n")
    (tmp_path / "a.yaml").write_text("base: b.yaml\n")
    (tmp_path / "b.yaml").write_text("base: ./a.yaml\n")
    with pytest.raises(InputError, match=r"a.yaml: its base chain is a loop, \S+a.yaml -> b.yaml -> a.yaml;"):
        load_config(str(tmp_path / "top.yaml"))


# -- keys given twice ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "text,key,lines",
    [
        ("base: impact_plate_cpu\ntrain:\n  steps: 2\n  steps: 5\n", "train.steps", (3, 4)),
        ("base: impact_plate_cpu\ntrain:\n  steps: 2\nmodel:\n  hidden: 8\ntrain:\n  lr: 1.0\n", "train", (2, 6)),
        ("dataset: impact_plate\nbase: impact_plate_cpu\ndataset: sphere_simple\n", "dataset", (1, 3)),
        ("base: impact_plate_cpu\nbase: sphere_simple_cpu\n", "base", (1, 2)),
        ("base: impact_plate_cpu\nmodel:\n  extra:\n    a: 1\n    b: 2\n    a: 3\n", "model.extra.a", (4, 6)),
        (
            "base: impact_plate_cpu\ndata:\n  exclude_trajectories:\n    - {x: 1, x: 2}\n",
            "data.exclude_trajectories[0].x",
            (4, 4),
        ),
        ("base: impact_plate_cpu\ntrain: {lr: 1.0e-3, steps: 3, lr: 2.0e-3}\n", "train.lr", (2, 2)),
    ],
)
def test_a_key_given_twice_is_refused_with_both_lines(tmp_path, text, key, lines):
    path = tmp_path / "twice.yaml"
    path.write_text(text)
    with pytest.raises(InputError) as exc:
        load_config(str(path))
    refused(str(exc.value), path)
    assert str(exc.value) == f"config {path}: key {key} given twice, lines {lines[0]} and {lines[1]}; keep one"


def test_a_key_given_twice_in_a_base_names_the_base(tmp_path, capsys, impact):
    (tmp_path / "base.yaml").write_text("base: impact_plate_cpu\nmodel:\n  hidden: 8\n  hidden: 16\n")
    (tmp_path / "mine.yaml").write_text("base: base.yaml\n")
    line = refused_by_train(capsys, tmp_path, str(tmp_path / "mine.yaml"), impact, tmp_path / "base.yaml")
    assert line.endswith(f"config {tmp_path / 'base.yaml'}: key model.hidden given twice, lines 3 and 4; keep one")


def test_an_override_mapping_with_a_key_twice_is_refused():
    with pytest.raises(InputError, match="key a given twice, lines 1 and 1") as exc:
        load_config("impact_plate_cpu", ["model.ablation={a: 1, a: 2}"])
    assert exc.value.param == "overrides"


# -- a config of another dataset than the data's -------------------------------------------------------------------
def test_a_config_of_another_dataset_is_refused_before_anything_is_written(tmp_path, capsys, impact):
    line = refused_by_train(capsys, tmp_path, "sphere_simple_cpu", impact, impact / "meta.json")
    assert line == (
        "hcmt train: error: config sphere_simple_cpu: dataset sphere_simple (set by its base "
        f"sphere_simple), but {impact / 'meta.json'} holds dataset impact_plate; expected data of dataset "
        "sphere_simple, or a config of dataset impact_plate (built-in: impact_plate, impact_plate_cpu, "
        "impact_plate_official)"
    )
    mine = tmp_path / "mine.yaml"
    mine.write_text("base: impact_plate_cpu\ndataset: deforming_plate\n")
    line = refused_by_train(capsys, tmp_path, str(mine), impact, mine, impact / "meta.json")
    assert f"config {mine}: dataset deforming_plate, but {impact / 'meta.json'} holds dataset impact_plate;" in line
    (tmp_path / "child.yaml").write_text("base: mine.yaml\n")
    line = refused_by_train(
        capsys, tmp_path, str(tmp_path / "child.yaml"), impact, tmp_path / "child.yaml", mine, impact / "meta.json"
    )
    assert f"dataset deforming_plate (set by its base {mine}), but" in line


def test_the_api_refuses_another_dataset_and_keeps_the_run_it_would_overwrite(tmp_path, impact):
    out = tmp_path / "run"
    out.mkdir()
    (out / "run.yaml").write_text("kept: true\n")  # a run overwrite=True would delete
    with pytest.raises(InputError) as exc:
        hcmt.train(
            load_config("sphere_simple_cpu", ["train.steps=1"]), impact, "mgn", out, overwrite=True, progress=False
        )
    assert str(exc.value).startswith("config: dataset sphere_simple, but ") and exc.value.param is None
    assert (out / "run.yaml").read_text() == "kept: true\n"


def test_the_dataset_check_passes_matching_and_unnamed_data():
    check_same_dataset("impact_plate", {"dataset": "impact_plate"}, "d", "config x")
    check_same_dataset("sphere_simple", {"field_names": []}, "d", "config x")  # converted data names none
    check_same_dataset(None, {"dataset": "impact_plate"}, "d", "config x")
    with pytest.raises(
        InputError,
        match=r"^run r: dataset sphere_simple, but d/meta.json holds dataset "
        r"impact_plate; expected data of dataset sphere_simple$",
    ):
        check_same_dataset("sphere_simple", {"dataset": "impact_plate"}, "d", "run r")


# -- numbers, relative bases ---------------------------------------------------------------------------------------
def test_number_strings_read_as_numbers(tmp_path):
    path = tmp_path / "numbers.yaml"
    path.write_text(
        "base: impact_plate_cpu\ntrain:\n  lr: 1e-3\n  lr_final: 1E-5\n  pushforward: .5\n"
        "  steps: 1_000\n  noise_std: 3e-4\n  contact_radius: 4E-1\n  keep_every: 2e3\n"
        "model:\n  clip: -.5\n"
    )
    t, m = load_config(str(path)).train, load_config(str(path)).model
    assert (t.lr, t.lr_final, t.pushforward, t.steps, t.noise_std, t.contact_radius) == (
        1e-3,
        1e-5,
        0.5,
        1000,
        3e-4,
        0.4,
    )
    assert t.keep_every == 2000 and isinstance(t.keep_every, int) and m.clip == -0.5
    path.write_text("base: impact_plate_cpu\ntrain:\n  lr: '1e-3'\n")  # quoted: a string, as the user wrote it
    with pytest.raises(InputError, match=r"train.lr: got '1e-3'; expected a number"):
        load_config(str(path))


def test_a_relative_base_is_read_from_the_configs_folder(tmp_path, monkeypatch):
    (tmp_path / "cfgs" / "deep").mkdir(parents=True)
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "cfgs" / "parent.yaml").write_text("base: impact_plate_cpu\ntrain:\n  steps: 7\n")
    (tmp_path / "cfgs" / "deep" / "child.yaml").write_text("base: ../parent.yaml\nmodel:\n  hidden: 8\n")
    (tmp_path / "cfgs" / "mine.yaml").write_text("base: deep/child.yaml\n")
    (tmp_path / "cfgs" / "named.yaml").write_text("base: impact_plate\n")  # a built-in config's name
    monkeypatch.chdir(tmp_path / "elsewhere")
    c = load_config(tmp_path / "cfgs" / "mine.yaml")
    assert (c.train.steps, c.model.hidden, c.model.levels) == (7, 8, 4)
    assert load_config("../cfgs/named.yaml").model.levels == 6
    (tmp_path / "cfgs" / "lost.yaml").write_text("base: nowhere.yaml\n")
    with pytest.raises(InputError) as exc:
        load_config("../cfgs/lost.yaml")
    assert "'nowhere.yaml' (the base of ../cfgs/lost.yaml, looked for in ../cfgs): neither a file nor" in str(exc.value)


# -- wrong types -----------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("base", ["5", "[a.yaml]", "{a: 1}", "true", "''"])
def test_a_base_of_the_wrong_type_is_refused(tmp_path, base):
    path = tmp_path / "mine.yaml"
    path.write_text(f"base: {base}\n")
    with pytest.raises(InputError) as exc:
        load_config(str(path))
    refused(str(exc.value), path)
    assert str(exc.value).startswith(f"config {path}: base: got ") and "expected a built-in config's name" in str(
        exc.value
    )


@pytest.mark.parametrize(
    "call,param,expected",
    [
        (lambda: load_config(None), "name_or_path", "expected a built-in config's name or a YAML path, got None"),
        (lambda: load_config(5), "name_or_path", "got 5"),
        (lambda: load_config("impact_plate_cpu", 5), "overrides", "expected a list of section.key=value strings"),
        (lambda: load_config("impact_plate_cpu", {"train.steps": 3}), "overrides", "got dict"),
        (lambda: hcmt.train("impact_plate_cpu", None, "mgn", "out"), "data", "expected a path, the native dataset"),
        (lambda: hcmt.train("impact_plate_cpu", "data", "mgn", None), "out", "expected a path, the run folder"),
        (lambda: hcmt.train(3.5, "data", "mgn", "out"), "config", "expected a Config, a config mapping"),
        (lambda: hcmt.train("impact_plate_cpu", "data", "mgn", "out", overrides=7), "overrides", "got int 7"),
    ],
)
def test_the_api_names_the_parameter(tmp_path, monkeypatch, call, param, expected):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(InputError) as exc:
        call()
    assert exc.value.param == param and expected in str(exc.value) and str(exc.value).startswith(param)
    assert list(tmp_path.iterdir()) == []


def test_one_override_string_is_one_override():
    """A single ``section.key=value`` string is that override, never its characters: one reading only, the one
    the command line's ``--set train.steps=20`` gives."""
    assert load_config("impact_plate_cpu", "train.steps=20").train.steps == 20
    assert load_config("impact_plate_cpu").with_overrides("model.hidden=8").model.hidden == 8


def test_a_config_nested_too_deeply_is_one_line(tmp_path):
    path = tmp_path / "deep.yaml"
    path.write_text("train: " + "[" * 3000 + "]" * 3000 + "\n")
    with pytest.raises(InputError) as exc:
        load_config(str(path))
    assert str(exc.value) == f"config {path}: nested too deeply for a config (its sections hold keys, one level)"


# -- the fuzzer ------------------------------------------------------------------------------------------------------
KEYS = [
    ("train", "lr"),
    ("train", "steps"),
    ("model", "hidden"),
    ("train", "pushforward"),
    ("data", "remesh"),
    ("model", "attention"),
    ("train", "noise_std"),
]
VALUES = [
    "1e-3",
    "1E-3",
    ".5",
    "1_000",
    "-.5",
    "3",
    "0",
    "-2",
    "true",
    "abc",
    "[1, 2]",
    "{a: 1}",
    "null",
    "''",
    "1e",
    "paper",
]


def _mutant(rng: random.Random, folder: Path, i: int) -> tuple[Path, set[str]]:
    """One config file (and its bases) with a mistake or none; returns it and the texts its refusal may name."""
    path = folder / f"m{i}.yaml"
    kind = rng.choice(["value", "twice", "loop", "base"])
    section, key = rng.choice(KEYS)
    value = rng.choice(VALUES)
    if kind == "value":
        path.write_text(f"base: impact_plate_cpu\n{section}:\n  {key}: {value}\n")
        return path, {f"{section}.{key}"}
    if kind == "twice":
        depth = rng.choice([0, 1, 2])
        body = {
            0: f"{section}:\n  {key}: 1\n{section}:\n  {key}: 2\n",
            1: f"{section}:\n  {key}: {value}\n  {key}: {value}\n",
            2: f"{section}:\n  {key}:\n    x: 1\n    x: 2\n",
        }[depth]
        path.write_text("base: impact_plate_cpu\n" + body)
        return path, {f"key {section}" + ("" if depth == 0 else f".{key}") + ("" if depth < 2 else ".x")}
    if kind == "loop":
        n = rng.choice([1, 2, 3])
        names = [path.name] + [f"m{i}_{j}.yaml" for j in range(1, n)]
        for j, name in enumerate(names):
            (folder / name).write_text(f"base: {names[(j + 1) % n]}\n{section}:\n  {key}: {value}\n")
        # a bad value is found in the first file, before its base is read
        return path, {
            f"base chain is a loop, {path} -> " + " -> ".join([*names[1:], names[0]])
            if n > 1
            else f"base chain is a loop, {path} -> {path.name};",
            f"{section}.{key}",
        }
    path.write_text(f"base: {rng.choice(['5', '[x]', 'nowhere.yaml', 'impact_plate_cpu'])}\n")
    return path, {"base"}


def test_fuzzed_configs_load_or_fail_in_one_line_naming_file_and_key(tmp_path):
    rng = random.Random(7)
    outcomes = {"loaded": 0, "refused": 0}
    for i in range(300):
        path, names = _mutant(rng, tmp_path, i)
        try:
            cfg = load_config(str(path))
        except InputError as exc:
            msg = str(exc)
            refused(msg, path, tmp_path)
            assert str(tmp_path) in msg and any(n in msg for n in names), (path.read_text(), msg)
            outcomes["refused"] += 1
        else:
            assert isinstance(cfg, Config)
            outcomes["loaded"] += 1
    assert outcomes["loaded"] > 20 and outcomes["refused"] > 150, outcomes


# -- threads ---------------------------------------------------------------------------------------------------------
@pytest.fixture
def threads(monkeypatch):
    """torch's thread count put back after the test; the busy machine's auto count made 1, and torch's start
    count the one it has now."""
    before = torch.get_num_threads()
    monkeypatch.setattr(hcmt.config.threads, "_THREADS", {})
    monkeypatch.setattr(hcmt.config.threads, "auto_threads", lambda: 1)
    monkeypatch.setattr(hcmt.config.threads, "_torch_start_counts", lambda: {3})
    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        monkeypatch.delenv(var, raising=False)
    torch.set_num_threads(3)  # torch's start count (above), so the default applies
    yield
    torch.set_num_threads(before)


def test_the_api_takes_the_commands_thread_default_unless_the_caller_chose(threads, monkeypatch):
    assert default_threads() == 1 and torch.get_num_threads() == 1  # torch's own count: the command's default
    monkeypatch.setattr(hcmt.config.threads, "auto_threads", lambda: 2)  # the load fell: the count chosen stays
    assert default_threads() == 1
    torch.set_num_threads(5)  # the caller's choice: kept
    assert default_threads() == 5 and torch.get_num_threads() == 5
    torch.set_num_threads(3)
    monkeypatch.setenv("OMP_NUM_THREADS", "3")  # so is the environment's
    assert default_threads() == 3
    monkeypatch.delenv("OMP_NUM_THREADS")
    set_threads(3)  # a command's --threads 3: kept too
    assert default_threads() == 3


@pytest.mark.slow  # trains one step
def test_hcmt_train_applies_the_thread_default(threads, tmp_path, impact, tiny_config):
    hcmt.train(tiny_config("train.steps=1", base="impact_plate_cpu"), impact, "mgn", tmp_path / "run", progress=False)
    assert torch.get_num_threads() == 1
