"""docs/RESULTS.md section "Memory and data feeding" from benchmarks/results/data_memory.json
(``python benchmarks/memory/run.py``)."""

from __future__ import annotations

import math

from report_common import command, load

#: the paper's training splits (trajectories, frames, nodes) the per-trajectory costs are scaled to
PAPER_SPLITS = {"impact": ("Impact Plate", 2000, 52, 2208), "deforming": ("Deforming Plate", 1200, 400, 1271)}


def _worker(rss: dict, name: str, how: str) -> float:
    return rss[f"{name} {how}"]["worker"]["VmHWM"]


def _rss_table(lines: list[str], rss: dict) -> None:
    lines += [
        "| dataset | worker, in memory | worker, read per item | training process, in memory | "
        "training process, read per item |",
        "|---|---|---|---|---|",
    ]
    labels = {
        "impact_paper_4": "Impact Plate `paper`, 4 trajectories",
        "impact_paper_40": "Impact Plate `paper`, 40 trajectories",
        "deforming_2": "Deforming Plate size, 2 trajectories",
        "deforming_6": "Deforming Plate size, 6 trajectories",
    }
    for name, label in labels.items():
        mem, lazy = rss[f"{name} in memory"], rss[f"{name} read per item"]
        lines.append(
            f"| {label} | {mem['worker']['VmHWM']:.1f} MB | {lazy['worker']['VmHWM']:.1f} MB | "
            f"{mem['main_rss_after_build_mb']:.1f} MB | {lazy['main_rss_after_build_mb']:.1f} MB |"
        )


def _expected(lines: list[str], rss: dict) -> None:
    per = {
        "impact": (_worker(rss, "impact_paper_40", "in memory") - _worker(rss, "impact_paper_4", "in memory")) / 36,
        "deforming": (_worker(rss, "deforming_6", "in memory") - _worker(rss, "deforming_2", "in memory")) / 4,
    }
    lazy = _worker(rss, "impact_paper_40", "read per item")
    lazy_gain = lazy - _worker(rss, "impact_paper_4", "read per item")
    lines += [
        "",
        f"Read per item, a worker on 40 trajectories holds {lazy_gain:.1f} MB more than on 4 (the index, "
        "HDF5's metadata cache and an LRU of 4 trajectories' static fields and hierarchies); in memory it held "
        f"{per['impact'] * 36:.0f} MB more: {per['impact']:.1f} MB per Impact Plate trajectory and "
        f"{per['deforming']:.1f} MB per Deforming Plate trajectory. Expected RSS per process at the paper's "
        "sizes (measured cost per trajectory × trajectories):",
        "",
        "| dataset (train split) | in memory | read per item |",
        "|---|---|---|",
    ]
    for key, (label, n, frames, nodes) in PAPER_SPLITS.items():
        lines.append(
            f"| {label}, {n:,} × {frames} frames × {nodes:,} nodes | {n * per[key] / 1e3:.1f} GB per worker "
            f"| ≈ {lazy / 1e3:.2f} GB (the 40-trajectory worker) + an index of 16 B a frame "
            f"({n * frames * 16 / 1e6:.1f} MB) |"
        )
    lines.append(
        "| Sphere Simple (not measured) | about T · N · 12 B of `world_pos` per trajectory, plus its "
        "hierarchy | as above |"
    )


def _feeding(lines: list[str], throughput: dict) -> None:
    lines += [
        "",
        "Feeding a GPU: milliseconds per training frame one worker builds (item and collate, batch 1; the "
        "median), and the workers that keep a 10 ms GPU step fed (`ceil(ms / 10)`):",
        "",
        "| graph | read per item, LRU miss (a new trajectory each frame) | read per item, LRU hit | in memory |",
        "|---|---|---|---|",
    ]
    graphs = (("Impact Plate `paper`", "impact_plate_paper"), ("Deforming Plate size", "deforming_plate_size"))
    for label, key in graphs:
        t = throughput[key]
        cells = [
            f"{t[k]['median_ms']:.1f} ms: {math.ceil(t[k]['median_ms'] / 10)}"
            for k in ("read_per_item_lru_misses", "read_per_item_lru_hits", "in_memory_spread")
        ]
        lines.append(f"| {label} ({t['nodes']:,} nodes, {t['levels']} levels) | " + " | ".join(cells) + " |")
    lines += [
        "",
        "An LRU miss reads the trajectory's static fields and its cached hierarchy (one flat `.npy` per "
        "trajectory, `HIERARCHY_VERSION` 2) besides the frame. `data.in_memory: true` holds the split in memory "
        "(the in-memory column) where it fits.",
    ]


def memory(lines: list[str]) -> None:
    d = load("data_memory.json")
    if not d:
        return
    lines += [
        "## Memory and data feeding",
        "",
        f"Command: `{command(d).strip()}` (one loaded CPU core, torch 1 thread; a few minutes) writes "
        "`benchmarks/results/data_memory.json`. The datasets are synthetic, written with "
        "`hcmt.data.format.write_split`: one `paper`-preset Impact Plate mesh copied with small perturbations "
        "(each copy its own hierarchy), and a tetrahedral plate and obstacle of 400 frames for Deforming Plate. "
        "Each RSS figure is a fresh process building training items in one `DataLoader` worker (peak RSS of the "
        'worker, `VmHWM`; RSS of the training process after building the dataset); "in memory" is '
        '`FrameDataset(in_memory=True)`, "read per item" the default training path.',
        "",
    ]
    _rss_table(lines, d["rss"])
    _expected(lines, d["rss"])
    _feeding(lines, d["throughput"])
    convert = d.get("convert_peak_rss_mb") or {}
    if convert:
        lines += [
            "",
            "`hcmt convert` of official-layout files (Deforming Plate TFRecord), peak RSS: "
            + ", ".join(f"{mb:.1f} MB for {n}" for n, mb in convert.items())
            + ": one trajectory at a time.",
        ]
    lines.append("")
