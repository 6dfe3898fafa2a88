"""What every docs/RESULTS.md section shares (benchmarks/report.py and its report_* modules): reading the result files,
formatting mean ± std, and the rules that choose the report's judging words.

Every judging phrase of the report ("ahead", "faster", "not reproduced", "the clearest effect", ...) is chosen by a
comparison of the numbers it prints, by the rules below. A fact that no result file holds (the paper's numbers, the
machine, the goals a study was built to check) is a named constant here or in its section's module."""

from __future__ import annotations

import json
import re

from common import RESULTS

# The paper's numbers, quoted for comparison.
PAPER_RATIO = {"position": 0.51, "stress": 0.41}  # Table 2, HCMT ÷ MGN RMSE-all
PAPER_STEPS = 2_000_000  # training steps
PAPER_TRAJECTORIES = 2_000  # training trajectories
PAPER_WIDTH = 128  # hidden size
PAPER_SIGMA_MM = 0.003  # Table 8's training noise σ, Impact Plate
PAPER_LEVELS = [2208, 1108, 559, 285, 148, 78, 42]  # Table 6, nodes per level
PAPER_QUALITY = {"jacobian": (0.32, 0.51), "min_angle": (16.7, 27.2), "max_angle": (120.4, 99.4)}  # Table 7
PAPER_TRAIN_MS = (51.12, 51.56)  # GPU ms per training step, as quoted (Table 10 / Appendix E)
PAPER_SPEEDUP = 176  # HCMT against ANSYS
PAPER_ANSYS_MS = 14_280  # ANSYS, ms per step
PAPER_WORST_ABLATION = "only-hmt"  # the worst variant of Table 3

# This project's fixed facts.
MACHINE = "2-core CPU"  # the development machine (no GPU)
SHIPPED_STEPS = 36_000  # training steps of the shipped model (docs/MODELS.md)
GOAL_NODES = 250_000  # the GPU goals: the mesh size a GPU step should take
# the GPU goals, what makes a GPU worth its cost for a design check: (goal, threshold, larger is better)
GOALS = (
    ("≥ 40× for one paper design", 40, True),
    ("≥ 400× for a 64-design sweep", 400, True),
    ("≤ 12 ms per paper-size train step", 12, False),
    ("≥ 1,000 samples/s", 1000, True),
    ("≤ 3 ms inference", 3, False),
)

# The rules.
SAME_SIZE = 2.0  # "of the same size": largest ÷ smallest below this factor
ABOUT = 1.25  # "about as large as": within this factor
TINY = 0.01  # "tiny next to the paper's": below this fraction of its budget
PEAK_GOAL_PCT = 5.0  # the shipped model's peak plate stress goal (median error; within what a design margin absorbs)
#: the model goals: the median errors a shipped mesh model must reach on designs of fresh seeds before its design
#: check stands in for the solver's (the judge, choose_checkpoint.py, the scaling study's "what budget would reach
#: them"), keyed as a scaling point's ``errors``
MODEL_GOALS = {"peak_error_pct": 3.0, "deflection_error_pct": 4.0, "ghost_difference": 0.05}
#: the model goals outside the training ranges (thicker, higher): the medians, looser since a model extrapolates
OUTSIDE_GOALS = {"peak_error_pct": 6.0, "deflection_error_pct": 8.0}


#: the scripts' paths before benchmarks/ was split into folders (benchmarks/README.md, "Old paths"): a result
#: file written before then names the old one in its ``command``, which the report quotes at the current path
MOVED = {
    "benchmarks/bench_graph.py": "benchmarks/micro/bench_graph.py",
    "benchmarks/bench_models.py": "benchmarks/micro/bench_models.py",
    "benchmarks/bench_solver.py": "benchmarks/micro/bench_solver.py",
    "benchmarks/design_speed.py": "benchmarks/micro/design_speed.py",
    "benchmarks/train_speed.py": "benchmarks/micro/train_speed.py",
    "benchmarks/speed.py": "benchmarks/speed/run.py",
    "benchmarks/threads.py": "benchmarks/speed/threads.py",
    "benchmarks/cpu_ab.sh": "benchmarks/speed/cpu_ab.sh",
    "benchmarks/accuracy.py": "benchmarks/accuracy/run.py",
    "benchmarks/ablations.py": "benchmarks/accuracy/ablations.py",
    "benchmarks/generalization.py": "benchmarks/accuracy/generalization.py",
    "benchmarks/parity.py": "benchmarks/parity/run.py",
    "benchmarks/propagation.py": "benchmarks/parity/propagation.py",
    "benchmarks/interval.py": "benchmarks/interval/run.py",
    "benchmarks/peak_sampling.py": "benchmarks/interval/peak_sampling.py",
    "benchmarks/peak_convergence.py": "benchmarks/interval/peak_convergence.py",
    "benchmarks/recipe.py": "benchmarks/recipe/run.py",
    "benchmarks/window.py": "benchmarks/recipe/window.py",
    "benchmarks/data_memory.py": "benchmarks/memory/run.py",
    "benchmarks/surrogate.py": "benchmarks/surrogate/run.py",
    "benchmarks/transfer.py": "benchmarks/transfer/run.py",
    "benchmarks/gpu_check.py": "benchmarks/gpu_check/run.py",
    "benchmarks/ghost_diagnosis.py": "benchmarks/ghost_diagnosis/run.py",
    "benchmarks/ship_model.py": "benchmarks/release/ship_model.py",
    "benchmarks/report_accuracy.py": "benchmarks/accuracy/report.py",
    "benchmarks/report_gpu.py": "benchmarks/gpu_check/report.py",
    "benchmarks/report_interval.py": "benchmarks/interval/report.py",
    "benchmarks/report_memory.py": "benchmarks/memory/report.py",
    "benchmarks/report_parity.py": "benchmarks/parity/report.py",
    "benchmarks/report_recipe.py": "benchmarks/recipe/report.py",
    "benchmarks/report_speed.py": "benchmarks/speed/report.py",
    "benchmarks/report_surrogate.py": "benchmarks/surrogate/report.py",
    "benchmarks/report_transfer.py": "benchmarks/transfer/report.py",
}


def command(result: dict) -> str:
    """A result file's ``command``, each moved script named by its current path (:data:`MOVED`)."""
    return re.sub(r"benchmarks/[\w.]+\.(?:py|sh)\b", lambda m: MOVED.get(m.group(0), m.group(0)), result["command"])


def load(name):
    path = RESULTS / name
    return json.loads(path.read_text()) if path.is_file() else None


def pm(ms, digits=4):
    return f"{ms['mean']:.{digits}g} ± {ms['std']:.2g}"


def opened(lines, heading, *names):
    """The result files ``names`` (one: itself), with the section's heading written first; None, and nothing written,
    where one is missing."""
    got = [load(n) for n in names]
    if not all(got):
        return None
    lines += [heading, ""]
    return got[0] if len(got) == 1 else got


def separated(a, b) -> bool:
    """Two mean ± std entries differ by more than the larger of the two stds over seeds."""
    return abs(a["mean"] - b["mean"]) > max(a["std"], b["std"])


def worse(x, y, key, larger_better=False) -> bool:
    """x's mean of ``key`` is worse than y's by more than the larger std over seeds."""
    return separated(x[key], y[key]) and (x[key]["mean"] < y[key]["mean"]) == larger_better


def ratio(a, b, q, key="rmse_all") -> float:
    """a's mean error of quantity ``q`` over b's."""
    return a[q][key]["mean"] / b[q][key]["mean"]


def on_gpu(device) -> bool:
    return bool(device) and not str(device).lower().startswith("cpu")


def gpu_check_ran() -> bool:
    d = load("gpu_check.json")
    return bool(d) and not d.get("smoke")


def reached(value, threshold, larger_better) -> bool:
    return value >= threshold if larger_better else value <= threshold


def said(names: list[str]) -> str:
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]


def keeps_up(p) -> bool:
    """propagation.json, one preset: MGN's hops per step reach as far as the stress front moves per frame."""
    return p["median"]["front_hops_per_frame"] <= p["models"]["mgn_gt_hops_per_step"]


def hcmt_keeps_up(p) -> bool:
    """The same for HCMT's reach per step."""
    return p["median"]["front_hops_per_frame"] <= p["models"]["hcmt"]["hops_per_step"]


def sentences(*parts: str) -> str:
    """Short sentences into one paragraph; empty parts are left out."""
    return " ".join(p for p in parts if p)
