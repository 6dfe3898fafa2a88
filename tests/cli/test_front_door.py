"""The front door's flags spelled alike across commands: evaluate / rollout of a shipped model
with --out, simulate's --design, one --batch default for predict and sweep."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from hcmt.cli import main as cli


def test_evaluate_of_a_shipped_model_without_out_is_refused_in_one_line(tmp_path, capsys):
    (tmp_path / "d").mkdir()
    assert cli(["evaluate", "pretrained:impact_plate_small", "--data", str(tmp_path / "d")]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        "hcmt evaluate: error: RUN pretrained:impact_plate_small: a shipped model has no run folder; give --out DIR "
        "for its rollouts and metrics"
    ]


def test_out_is_for_a_shipped_model_only(tmp_path, capsys):
    (tmp_path / "d").mkdir()
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "run.yaml").write_text("model: {}\n")
    assert cli(["rollout", str(tmp_path / "run"), "--data", str(tmp_path / "d"), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "for a shipped model (pretrained:NAME); a run folder's rollouts" in err[0]


@pytest.mark.slow  # one solver run and the shipped model's rollout of it (~1 min on one thread)
def test_evaluate_a_shipped_model_writes_to_out(tmp_path, capsys):
    data = tmp_path / "d"
    assert cli(["simulate", "--out", str(data / "test.h5"), "--no-progress"]) == 0
    out = tmp_path / "ev"
    assert (
        cli(["evaluate", "pretrained:impact_plate_small", "--data", str(data), "--out", str(out), "--no-progress"]) == 0
    )
    metrics = json.loads((out / "metrics_test.json").read_text())
    assert metrics["trajectories"] == 1 and (out / "rollout_test.h5").is_file()
    assert metrics["physics"]["peak_plate_stress_error_pct"]["median"] < 50


def test_simulate_takes_the_design_as_predict_does():
    import argparse

    from hcmt.cli import CommandError
    from hcmt.cli.parsers import configure_simulate, simulate_inputs

    p = argparse.ArgumentParser()
    configure_simulate(p)
    design, _ = simulate_inputs(p.parse_args(["--design", "thickness=0.8", "drop_height=700"]))
    assert (design.thickness, design.drop_height) == (0.8, 700.0)
    old, _ = simulate_inputs(p.parse_args(["--thickness", "0.8", "--drop-height", "700"]))
    assert old == design  # the per-parameter flags stay as aliases
    with pytest.raises(CommandError, match="the same parameter twice"):
        simulate_inputs(p.parse_args(["--thickness", "0.8", "--design", "thickness=0.7"]))


def test_predict_and_sweep_share_one_batch_default():
    import argparse
    import inspect

    from hcmt.cli.parsers import configure_predict, configure_sweep
    from hcmt.design.basics import DESIGN_BATCH
    from hcmt.design.check import check_designs
    from hcmt.design.sweep import sweep

    defaults = []
    for configure, args in ((configure_predict, []), (configure_sweep, ["--vary", "thickness=0.6:0.8:3"])):
        p = argparse.ArgumentParser()
        configure(p)
        defaults.append(p.parse_args(args).batch)
    assert defaults[0] == defaults[1] == DESIGN_BATCH
    # the default follows the measurement: the batch with the highest speedup over the solver in both committed runs
    results = Path(__file__).resolve().parents[2] / "benchmarks" / "results"
    for name in ("design_speed_cpu.json", "design_speed_cpu_reversed.json"):
        rows = json.loads((results / name).read_text())["batches"]
        assert (
            max(rows.values(), key=lambda r: r["speedup_median_solver"])["speedup_measured"]["batch"] == DESIGN_BATCH
        ), name
    assert inspect.signature(check_designs).parameters["batch"].default == DESIGN_BATCH
    assert inspect.signature(sweep).parameters["batch"].default == DESIGN_BATCH
