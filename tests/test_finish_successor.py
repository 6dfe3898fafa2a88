"""benchmarks/release/finish_successor.sh (the successor's measured shipping steps, unattended): it runs
the steps in order with the checkpoint chosen on the validation split, marks a step done only when it succeeded,
resumes from the marks, runs the judge beside the transfer, refuses an unfinished run, and writes the report last.
The steps' scripts are replaced by a recorder (``PY``): what is tested is the script's own control flow."""

import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SCRIPT = ROOT / "benchmarks" / "release" / "finish_successor.sh"

# a stand-in for python: runs ``-c`` code, records every script call, fails the script named in $FAIL, and
# writes the choice file as choose_checkpoint.py would
RECORDER = """#!/usr/bin/env bash
if [ "$1" = "-c" ]; then exec python3 "$@"; fi
echo "$*" >> "$CALLS"
case "$1" in *choose_checkpoint.py) echo '{"chosen": "avg_360000_380000_400000"}' \\
    > benchmarks/results/successor_choice.json;; esac
case "$1" in *"$FAIL"*) [ -n "$FAIL" ] && exit 1;; esac
exit 0
"""


@pytest.fixture
def checkout(tmp_path):
    """A checkout holding the script and train_successor.sh (the generate line), finished data and run folders."""
    repo = tmp_path / "repo"
    (repo / "benchmarks" / "release").mkdir(parents=True)
    (repo / "benchmarks" / "results").mkdir()
    for src in (SCRIPT, SCRIPT.parent / "train_successor.sh"):
        shutil.copy(src, repo / "benchmarks" / "release" / src.name)
    for d in ("data", "stack3", "pen"):
        (tmp_path / d).mkdir()
        (tmp_path / d / "meta.json").write_text("{}")
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "train_stats.json").write_text(json.dumps({"steps": 400000}))
    py = tmp_path / "py"
    py.write_text(RECORDER)
    py.chmod(0o755)
    env = dict(
        os.environ,
        PY=str(py),
        RUN=str(tmp_path / "run"),
        DATA=str(tmp_path / "data"),
        STACK3=str(tmp_path / "stack3"),
        PEN=str(tmp_path / "pen"),
        WORK=str(tmp_path / "work"),
        CALLS=str(tmp_path / "calls"),
        FAIL="",
    )
    return repo, env


def finish(repo: Path, env: dict, **extra) -> subprocess.CompletedProcess:
    return subprocess.run(
        ["bash", str(repo / "benchmarks" / "release" / "finish_successor.sh")],
        env={**env, **extra},
        capture_output=True,
        text=True,
        timeout=60,
    )


def calls(env: dict) -> list[str]:
    path = Path(env["CALLS"])
    return path.read_text().splitlines() if path.is_file() else []


def script_of(call: str) -> str:
    return Path(call.split()[0]).name


def test_every_step_runs_once_in_order_with_the_chosen_checkpoint(checkout):
    repo, env = checkout
    done = finish(repo, env)
    assert done.returncode == 0, done.stderr
    got = calls(env)
    names = [script_of(c) for c in got]
    assert names[:6] == [
        "average_checkpoints.py",
        "choose_checkpoint.py",
        "long_run.py",
        "long_run.py",
        "long_run.py",
        "ship_model.py",
    ]
    assert sorted(names[6:9]) == ["run.py", "run.py", "run.py"] and names[9] == "report.py"  # judge, check, transfer
    ship = got[5]
    assert f"--cache {env['WORK']}/choose_cache" in got[1]  # kept steps judged while the run trained are read
    assert "--checkpoint avg_360000_380000_400000" in ship  # the validation split's choice is shipped
    assert f"--data-command hcmt generate impact-plate {env['DATA']} --preset small --train 480" in ship
    judge = next(c for c in got if "--seed-in 8101" in c)
    assert "--seed-out 8102" in judge and "--json model_judge.json" in judge
    assert any("--base new=pretrained:impact_plate_small --ft-lr 1e-4" in c for c in got)
    again = finish(repo, env)  # every step marked: nothing runs twice
    assert again.returncode == 0 and calls(env) == got


def test_a_failed_step_is_not_marked_and_a_rerun_resumes_there(checkout):
    repo, env = checkout
    failed = finish(repo, env, FAIL="ship_model.py")
    assert failed.returncode != 0 and "step ship failed" in failed.stderr
    before = calls(env)
    assert script_of(before[-1]) == "ship_model.py"  # nothing after the failed step ran
    finish(repo, env)
    after = calls(env)[len(before) :]
    assert script_of(after[0]) == "ship_model.py" and script_of(after[-1]) == "report.py"  # resumed at ship


def test_the_judge_failing_beside_the_transfer_stops_before_the_report(checkout):
    repo, env = checkout
    failed = finish(repo, env, FAIL="surrogate/run.py")
    assert failed.returncode == 2 and "the judge or the design check failed" in failed.stderr
    names = [script_of(c) for c in calls(env)]
    assert "report.py" not in names and any("transfer/run.py" in c for c in calls(env))  # the transfer still ran
    assert (Path(env["WORK"]) / "transfer.done").is_file() and not (Path(env["WORK"]) / "judge.done").is_file()


def test_an_unfinished_run_or_missing_data_is_refused_before_anything_runs(checkout, tmp_path):
    repo, env = checkout
    (tmp_path / "run" / "train_stats.json").unlink()
    refused = finish(repo, env)
    assert refused.returncode == 2 and "the run has not finished" in refused.stderr and calls(env) == []
    (tmp_path / "run" / "train_stats.json").write_text("{}")
    refused = finish(repo, env, PEN=str(tmp_path / "nowhere"))
    assert refused.returncode == 2 and "nowhere/meta.json" in refused.stderr and calls(env) == []
