"""The ghost ablations' report (benchmarks/ghost_diagnosis/report.py): an arm is called beyond the protocol's
spread only when it moves the ghost difference more than the two controls differ."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
from ghost_diagnosis.report import ablation_text  # noqa: E402


def arm(ghost: float, sets=()) -> dict:
    return {
        "sets": list(sets),
        "ghost_difference_median": {"rollout": ghost, "teacher_forced": 0.01},
        "peak_error_median": 0.03,
        "deflection_error_median": 0.04,
        "amplification_median": 300.0,
        "rows": [{}] * 12,
    }


def text(arms: dict) -> str:
    lines = []
    ablation_text(
        lines,
        {"command": "c", "init": "run", "steps": 4000, "common": ["train.lr=1e-4"], "arms": arms},
        {
            "run": "pretrained:x",
            "ghost_difference_median": {"rollout": 0.1, "teacher_forced": 0.01},
            "amplification_median": 6000.0,
        },
    )
    return "\n".join(lines)


def test_an_arm_is_beyond_the_spread_only_past_the_controls_difference():
    base = {"start": arm(0.04), "control": arm(0.06), "control-seed1": arm(0.04)}
    inside = text({**base, "no-pushforward": arm(0.045, ["train.pushforward=0"])})
    assert "spread (control against control-seed1) is 0.020" in inside
    assert "no-pushforward: ghost difference -0.015 against control (within that spread)" in inside
    assert "No training option tried moves the ghost difference beyond" in inside
    assert "the shipped model's ghost difference on the same trajectories is 0.100" in inside
    beyond = text({**base, "noise-x10": arm(0.01, ["train.noise_std=0.003"])})
    assert "(lower, beyond that spread)" in beyond and "Beyond the protocol's spread: noise-x10." in beyond
    assert "| 12 trajectories" not in beyond and "medians over its 12 trajectories" in beyond
