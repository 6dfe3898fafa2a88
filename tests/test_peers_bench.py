"""The peers benchmark's arithmetic and report (benchmarks/peers): paired per-round ratios, GFLOP/s from the
counted FLOPs (a peer without a count borrows hcmt's), the core-peak derivation and the RESULTS.md section."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks" / "peers"))
from machine import core_peak  # noqa: E402
from peers.report import peers  # noqa: E402
from peers.run import CONTESTANTS, summarize  # noqa: E402


class _W:
    def __init__(self, info):
        self.info = info


def _result():
    names = [CONTESTANTS[3][0], CONTESTANTS[5][0]]  # hcmt official eager, the authors' TF
    workers = {
        names[0]: _W({"framework": "hcmt", "flops_train": 3e9, "flops_infer": 1e9}),
        names[1]: _W({"framework": "tf"}),
    }
    times = {
        names[0]: {"train": [[100, 100], [300, 300]], "infer": [[40], [40]]},
        names[1]: {"train": [[200, 200], [300, 300]], "infer": [[80], [20]]},
    }
    peak = {"gflops": 100.0, "derivation": "test"}
    return summarize(CONTESTANTS, workers, times, peak), peak


def test_ratios_are_paired_per_round_and_flops_borrowed():
    (rows, ratios), _ = _result()
    train = next(r for r in ratios if r["kind"] == "train")
    assert train["rounds"] == [0.5, 1.0] and train["ratio"] == 0.75
    infer = next(r for r in ratios if r["kind"] == "infer")
    assert infer["rounds"] == [0.5, 2.0]
    tf = rows[1]
    assert tf["train_flops_from"] == CONTESTANTS[3][0]
    assert abs(tf["train_gflops_per_s"] - 3e9 / 250 / 1e6) < 1e-9  # median of round medians: 250 ms
    assert abs(tf["train_peak_share"] - tf["train_gflops_per_s"] / 100) < 1e-12


def test_core_peak_is_lanes_times_fma_times_clock():
    p = core_peak()
    assert p["gflops"] == 2 * p["fp32_lanes"] * 2 * p["ghz"] or p["gflops"] != p["gflops"]  # nan without cpuinfo


def test_report_section():
    (rows, ratios), peak = _result()
    result = {
        "graph": {"nodes": 10, "mesh_edges": 20, "contact_edges": 2, "level_nodes": [5, 3]},
        "rounds": 2,
        "steps_per_round": 2,
        "load_average": [3.0, 0, 0],
        "peak": peak,
        "rows": rows,
        "ratios": ratios,
        "failed": {"PhysicsNeMo MeshGraphNet": "no interpreter"},
    }
    lines: list[str] = []
    peers(lines, result)
    text = "\n".join(lines)
    assert "| 0.75 (0.50-1.00) | met |" in text and "not met" in text
    assert "Not measured: PhysicsNeMo MeshGraphNet" in text
    lines = []
    peers(lines, None)
    assert lines == []


def test_warm_up_times_the_first_calls_then_counts_one_more_of_each():
    """protocol.warm_up, every worker's start: 3 training steps and 2 inferences warm up, then one more call of
    each is counted (a worker without a counter records none)."""
    import torch
    from protocol import warm_up
    from torch.utils.flop_counter import FlopCounterMode

    calls, a, b = [], torch.ones(4, 8), torch.ones(8, 2)
    info = warm_up(
        {"model": "x"},
        lambda: calls.append("train") or a @ b,
        lambda: calls.append("infer"),
        lambda: FlopCounterMode(display=False),
    )
    assert calls == ["train"] * 3 + ["infer"] * 2 + ["train", "infer"]
    assert list(info) == ["model", "warmup_train_s", "warmup_infer_s", "flops_train", "flops_infer"]
    assert info["flops_train"] == 2 * 4 * 8 * 2 and info["flops_infer"] == 0
    assert list(warm_up({}, lambda: None, lambda: None)) == ["warmup_train_s", "warmup_infer_s"]
