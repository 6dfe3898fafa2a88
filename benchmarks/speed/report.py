"""docs/RESULTS.md's speed sections on the CPU: the models on a paper-size graph (benchmarks/micro/bench_models.py), the
learned rollout against the solver and the scaling with node count (benchmarks/speed/run.py), threads
(benchmarks/speed/threads.py), the old-against-new CPU check (benchmarks/speed/cpu_ab.sh) and training throughput
against the old commit (benchmarks/micro/train_speed.py) and the design check against the old commit and the solver
(benchmarks/micro/design_ab.py)."""

from __future__ import annotations

import statistics

import report_common
from micro.train_speed import RECIPES
from report_common import (
    GOAL_NODES,
    PAPER_ANSYS_MS,
    PAPER_SPEEDUP,
    PAPER_TRAIN_MS,
    command,
    gpu_check_ran,
    load,
    on_gpu,
    opened,
    said,
    sentences,
)
from speed.run import MEMORY_CAP_GB

SCALING_HEAD = [
    "| model | nodes | mesh edges | train ms/step | peak RSS MB | peak kB per node |",
    "|---|---|---|---|---|---|",
]
MODELS = ("hcmt", "mgn", "gt")


def peak(r) -> float:
    return r.get("peak_mb", r.get("peak_rss_mb"))


def scaling_row(r) -> str:
    if "train_ms" in r:
        return (
            f"| {r['model'].upper()} | {r['nodes']} | {r['edges']} | {r['train_ms']:.0f} | {peak(r):.0f} | "
            f"{peak(r) * 1024 / r['nodes']:.0f} |"
        )
    why = f"needs > {MEMORY_CAP_GB} GB (allocation failed)" if "allocat" in r["failed"] else r["failed"][:80]
    return f"| {r['model'].upper()} | ~{r['target_nodes']} | | {why} | | |"


def speed(lines):
    models, roll, scal = load("models_cpu.json"), load("speed_rollout.json"), load("speed_scaling.json")
    if models or roll or scal:
        lines += ["## Speed", ""]
    if models:
        models_table(lines, models)
    if roll:
        rollout(lines, roll)
    if scal:
        scaling(lines, scal)


def models_table(lines, models):
    lines += [
        "### Models on a paper-size Impact Plate graph (paper Table 10 / Appendix E)",
        "",
        "Command: `python benchmarks/micro/bench_models.py --steps 5 --threads 1 --json "
        "benchmarks/results/models_cpu.json` (one CPU thread; paper sizes: hidden 128, HCMT L_C 2 / λ 6, "
        "MGN and GT 15 blocks; the 2,152-node `paper` preset mesh with its contact edges).",
        "",
        "| device | threads | model | parameters | train ms/step | inference ms/step |",
        "|---|---|---|---|---|---|",
    ]
    gpu = "" if any(on_gpu(e["device"]) for e in models) else "No GPU was available to this project's runs."
    for entry in models:
        for name, r in entry["models"].items():
            lines.append(
                f"| {entry['device']} | {entry['threads']} | {name.upper()} | {r['parameters']:,} | "
                f"{r['train_ms']:.0f} | {r['inference_ms']:.0f} |"
            )
        h, g = entry["models"]["hcmt"], entry["models"]["mgn"]
        paper = f"(paper, GPU: {PAPER_TRAIN_MS[0]:g} / {PAPER_TRAIN_MS[1]:g} ms per training step)"
        lines += [
            "",
            sentences(
                f"HCMT ÷ MGN: train {h['train_ms'] / g['train_ms']:.2f}, inference "
                f"{h['inference_ms'] / g['inference_ms']:.2f} {paper}.",
                gpu,
            ),
            "",
        ]


def rollout(lines, roll):
    n = len(roll["trajectories"])
    runs = f" --run {' '.join(roll['trained_runs'])}" if roll.get("trained_runs") else ""
    lines += [
        "### Learned rollout against the solver, same trajectories",
        "",
        f"Command: `python benchmarks/speed/run.py rollout --n {n}{runs}`",
        "",
        f"Solver (built-in explicit FEM, one core): **{roll['solver_ms_per_frame']:.1f} ms per recorded frame** "
        f"(median over {n} paper-preset trajectories). Learned models: the accuracy "
        "study's seed-0 runs (hidden 64, HCMT λ 4), one CPU thread, timed per step including graph "
        "building and contact search.",
    ]
    speedup = {m.upper(): roll[f"{m}_speedup_vs_solver"] for m in ("hcmt", "mgn") if f"{m}_speedup_vs_solver" in roll}
    for m in speedup:
        lines.append(
            f"- {m} rollout: {roll[f'{m.lower()}_ms_per_step']:.1f} ms per step → "
            f"**{speedup[m]:.2f}×** the solver's speed."
        )
    fast = [m for m, v in speedup.items() if v > 1]
    verdict = (
        "the learned rollout is not faster than"
        if not fast
        else "the learned rollout is faster than"
        if len(fast) == len(speedup)
        else f"{said(fast)}'s learned rollout is faster than"
    )
    lines += [
        "",
        sentences(
            f"The paper reports HCMT {PAPER_SPEEDUP}× faster than ANSYS: a GPU model against ANSYS at "
            f"{PAPER_ANSYS_MS:,} ms per step.",
            f"On one CPU core {verdict} hcmt's own lean 2-D explicit solver.",
            "The learned model's cost does not depend on the solver's stable time step.",
            "Finer meshes, stiffer materials, 3-D models and a GPU are not measured on this machine.",
        ),
        "",
    ]


def scaling(lines, scal):
    lines += [
        "### Training-step time and peak memory against node count",
        "",
        "Command: `python benchmarks/speed/run.py scaling --sizes 1000 2000 4000 8000 16000 32000 64000 "
        "--reps 2` (paper-size models, one thread, one process per point, median of 2 steps after a warm-up "
        "step).",
        "",
    ]
    lines += SCALING_HEAD + [scaling_row(r) for r in scal["rows"] if not r.get("checkpoint_blocks")]
    above = all(k > 1 for k in scal["exponent"].values())
    lines += [
        "",
        "Fitted time ∝ N^k: " + ", ".join(f"{m.upper()} k = {k:.2f}" for m, k in scal["exponent"].items()),
        "",
        sentences(
            f"Each measurement process is capped at {MEMORY_CAP_GB} GB of address space (speed.py "
            "MEMORY_CAP_GB): an oversized graph fails instead of swapping, so a failed row needs more.",
            "Meshes are refined at a fixed contact radius γ = 0.4 mm, so contact edges grow faster "
            "than the node count" + (", which likely contributes to the exponents above 1." if above else "."),
        ),
        "",
    ]
    ckpt = [r for r in scal["rows"] if r.get("checkpoint_blocks")]
    if not ckpt:
        return
    lines += [
        "With activation checkpointing per block (`train.checkpoint_blocks: true`; command: `python "
        "benchmarks/speed/run.py scaling --models hcmt --checkpoint-blocks --sizes "
        + " ".join(str(r["target_nodes"]) for r in ckpt)
        + " --reps 2`, same process cap):",
        "",
    ]
    lines += SCALING_HEAD + [scaling_row(r) for r in ckpt] + [""]
    plain = {
        (r["model"], r.get("target_nodes")): r
        for r in scal["rows"]
        if not r.get("checkpoint_blocks") and "train_ms" in r
    }
    pairs = [
        (plain[(r["model"], r["target_nodes"])], r)
        for r in ckpt
        if "train_ms" in r and (r["model"], r["target_nodes"]) in plain
    ]
    if pairs:
        each = "; ".join(
            f"{a['nodes']} nodes: peak {peak(b) / peak(a):.2f}×, time {b['train_ms'] / a['train_ms']:.2f}×"
            for a, b in pairs
        )
        lines += [
            sentences(
                f"Checkpointing against the plain step at the same size: {each}.",
                "Peak RSS includes the process's fixed cost.",
                "The plain rows were measured in an earlier session, the checkpointed ones while a "
                "training run held the other core: the time ratios are indicative only.",
            ),
            "",
        ]
    last = max((r for r in ckpt if "train_ms" in r), key=lambda r: r["nodes"], default=None)
    if last:
        gb = peak(last) / last["nodes"] * GOAL_NODES / 1024
        gpu = "" if gpu_check_ran() else "; GPU memory per node is not measured either"
        lines += [
            f"At {peak(last) * 1024 / last['nodes']:.0f} kB per node ({last['nodes']} nodes), a "
            f"{GOAL_NODES:,}-node HCMT step would need about {gb:.0f} GB (extrapolated from the CPU, not "
            f"measured{gpu}).",
            "",
        ]


def threads(lines):
    t = opened(lines, "## Threads", "threads.json")
    if not t:
        return
    lines += [
        f"`{command(t)}`: `hcmt predict pretrained:impact_plate_small` in a fresh process "
        f"while {t['other_job']} holds one of the {t['cores']} cores; median of 3 runs, wall time of the whole "
        f"command (start-up included). {t['note']}.",
        "",
        "| setting | median s |",
        "|---|---|",
    ]
    for k, r in t["results"].items():
        lines.append(f"| {k} | {r['median_s']:.2f} |")
    lines.append("")


def cpu_ab(lines):
    runs = {(side, i): load(f"cpu_ab_{side}_{i}.json") for side in ("old", "new") for i in (1, 2)}
    if not all(runs.values()):
        return

    def slower(m, key):
        """New ÷ old above 1, in both rounds, by more than the same code varies between its two rounds (per model)."""
        noise = max(
            abs(runs[(side, 1)][0]["models"][m][key] / runs[(side, 2)][0]["models"][m][key] - 1)
            for side in ("old", "new")
        )
        return all(
            runs[("new", i)][0]["models"][m][key] / runs[("old", i)][0]["models"][m][key] > 1 + noise for i in (1, 2)
        )

    worse = [m for m in MODELS if slower(m, "train_ms") or slower(m, "inference_ms")]
    lines += [
        f"### The CPU is {'not slower' if not worse else 'slower for ' + said([m.upper() for m in worse])}",
        "",
        "Command: `git worktree add --detach ../old c18dfe3 && PYTHON=.venv/bin/python bash "
        "benchmarks/speed/cpu_ab.sh ../old .` (c18dfe3: the last commit before the compiled/padded paths; old "
        "and new alternate, twice, one thread each, while a training run held the other core). Paper-size "
        "graph, eager, median of 5 steps, ms:",
        "",
        "| model | train old | train new | new ÷ old | inference old | inference new | new ÷ old |",
        "|---|---|---|---|---|---|---|",
    ]
    for m in MODELS:
        for i in (1, 2):
            a, b = runs[("old", i)][0]["models"][m], runs[("new", i)][0]["models"][m]
            lines.append(
                f"| {m.upper()} (round {i}) | {a['train_ms']:.0f} | {b['train_ms']:.0f} | "
                f"{b['train_ms'] / a['train_ms']:.2f} | {a['inference_ms']:.0f} | {b['inference_ms']:.0f} | "
                f"{b['inference_ms'] / a['inference_ms']:.2f} |"
            )
    lines.append("")


RECIPE_NAMES = {"cpu": "`impact_plate_cpu` defaults", "ship": "the shipped model's recipe"}


def train_speed(lines):
    """Training samples per second of the old commit and the new one, interleaved."""
    d = opened(lines, "### Training throughput against the old commit", "train_speed_cpu.json")
    if d is None:
        return
    loads = [r["load_1min"] for r in d["rows"] if "load_1min" in r]
    lines += [
        f"Command: `{d['command']}`. Old {d['commits']['old']} against new {d['commits']['new']} "
        f"({', '.join(d['new_set']) or 'defaults'} on the new side: what `train.compile: auto` picks for a run "
        f"of 5,000 steps or more), `small` preset, {d['rounds']} rounds with old and new alternating, "
        f"{d['steps']} steps a run, the trainer's median step (loading the batch, forward, loss, backward, "
        f"Adam), {d['cpu']}"
        + (f", 1-minute load {min(loads):.1f}-{max(loads):.1f} as the runs ended" if loads else "")
        + ". Samples per second (median over rounds):",
        "",
    ]
    also = [k for k in d["commits"] if k not in ("old", "new")]  # further checkouts timed in the same rounds
    if also:
        lines[-2] = lines[-2][: -len(" (median over rounds):")] + (
            " (median over rounds); also timed, with the new side's settings: "
            + ", ".join(f"{k} {d['commits'][k]}" for k in also)
            + ":"
        )
    lines += [
        "| threads | recipe | old | "
        + "".join(f"{k} | " for k in also)
        + "new | new ÷ old |"
        + "".join(f" new ÷ {k} |" for k in also),
        "|---|---|---|---|---|" + "---|" * 2 * len(also),
    ]
    for r in d["summary"]:
        lines.append(
            f"| {r['threads']} | {RECIPE_NAMES[r['recipe']]} | {r['old_samples_per_s']:.2f} | "
            + "".join(f"{r[f'{k}_samples_per_s']:.2f} | " for k in also)
            + f"{r['new_samples_per_s']:.2f} | {r['ratio']:.2f}× |"
            + "".join(f" {r[f'new_over_{k}']:.2f}× |" for k in also)
        )
    warm = {
        side: statistics.median(
            r["wall_s"] - d["steps"] * r["ms_per_step"] / 1e3 for r in d["rows"] if r["side"] == side
        )
        for side in d["commits"]
    }
    lines += [
        "",
        "Warm-up of a run (its wall time less the steps at the median step: start-up, data, and compilation "
        "from a warm persistent cache where compiled), median over runs: "
        + ", ".join(f"{side} {s:.0f} s" for side, s in warm.items())
        + ".",
    ]
    reached = [r for r in d["summary"] if r["ratio"] >= 2]
    lines += [
        "",
        f"The goal of 2× (the speed-up this rewrite of the training step aimed at) is reached in "
        f"{len(reached)} of {len(d['summary'])} rows.",
    ]
    by = {(r["recipe"], r["threads"]): r for r in d["summary"]}
    for recipe in dict.fromkeys(r["recipe"] for r in d["summary"]):
        if (recipe, 1) in by and (recipe, 2) in by:
            one, two = by[(recipe, 1)], by[(recipe, 2)]
            lines.append(
                f"With {RECIPE_NAMES[recipe]}, two threads give the old code "
                f"{two['old_samples_per_s'] / one['old_samples_per_s']:.2f}× its one-thread throughput and "
                f"the new (compiled) code {two['new_samples_per_s'] / one['new_samples_per_s']:.2f}×."
            )
    lines.append("")


def train_parts(lines):
    """Where the compiled training step's time goes, and how much of it runs at the core's peak."""
    d = opened(lines, "### Where a training step's time goes", "train_parts_cpu.json")
    if d is None:
        return
    rounds = d["rows"][0].get("rounds", 1)
    lines += [
        f"Command: `{d['command']}` ({d['cpu']}; the trainer's compiled CPU step, `train.compile=default`, "
        "after its warm-up; a fresh process per row"
        + (f", {rounds} rounds interleaved, each number the median over them" if rounds > 1 else "")
        + "). The parts are wall-clock means per step (the shipped "
        "recipe's steps are of two kinds, with and without a pushforward item); the matrix products and "
        "Inductor's fused kernels are their self time under `torch.profiler` (means per step; the profiled "
        "step is slower than the plain one by the profiler's own cost); the rest is the plain step less "
        "those two: what runs outside both (Python, the compiled wrapper, autograd, Adam, the batch):",
        "",
        "| recipe | threads | step ms | batch | forward + loss | backward | Adam | profiled step ms | matrix "
        "products ms (calls) | their GFLOP/s | Inductor kernels ms (calls) | rest ms |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in d["rows"]:
        rest = r["step"] - r["matmul_ms"] - r["inductor_kernels_ms"]
        lines.append(
            f"| {RECIPE_NAMES[r['recipe']]} | {r['threads']} | {r['step']:.1f} | {r['batch']:.1f} | "
            f"{r['forward_loss']:.1f} | {r['backward']:.1f} | {r['adam']:.1f} | {r['profiled_step_ms']:.1f} | "
            f"{r['matmul_ms']:.1f} ({r['matmul_calls']:.0f}) | {r['matmul_gflops']:.0f} | "
            f"{r['inductor_kernels_ms']:.1f} ({r['inductor_kernel_calls']:.0f}) | {rest:.1f} |"
        )
    one = [r for r in d["rows"] if r["threads"] == 1]
    if one:
        share = statistics.median(r["matmul_ms"] / r["step"] for r in one)
        fused = statistics.median(r["inductor_kernels_ms"] / r["step"] for r in one)
        rate = statistics.median(r["matmul_gflops"] for r in one)
        lines += [
            "",
            f"On one thread the matrix products take {100 * share:.0f} % of the step at {rate:.0f} GFLOP/s, "
            f"Inductor's fused kernels (gathers, scatters, layer norms, the attention's exponentials) "
            f"{100 * fused:.0f} %, and the rest {100 * (1 - share - fused):.0f} % (medians over the recipes). "
            + (
                f"Against this core's fp32 peak of {d['core_peak']['gflops']:.0f} GFLOP/s "
                f"({d['core_peak']['derivation']}) the matrix products run at "
                f"{100 * rate / d['core_peak']['gflops']:.0f} %."
                if "core_peak" in d
                else "The run did not record the core's peak (train_parts.py records it since 2026-12-04)."
            ),
        ]
    speed = report_common.load("train_speed_cpu.json")  # looked up as opened() does (tests stand in for it)
    if speed:
        two_x_floor(lines, d, speed)
    lines.append("")


def two_x_floor(lines, parts: dict, speed: dict) -> None:
    """What a 2× speed-up would leave for everything but the kernels: half the old commit's step
    (train_speed_cpu.json) against the new step's kernel time (train_parts_cpu.json: the matrix products and
    Inductor's kernels, profiled self time, and Adam)."""
    old = {
        (r["recipe"], r["threads"]): statistics.median(
            x["ms_per_step"]
            for x in speed["rows"]
            if x["side"] == "old" and x["recipe"] == r["recipe"] and x["threads"] == r["threads"]
        )
        for r in speed["summary"]
    }
    rows = [
        (r, old[(r["recipe"], r["threads"])] / 2, r["matmul_ms"] + r["inductor_kernels_ms"] + r["adam"])
        for r in parts["rows"]
        if (r["recipe"], r["threads"]) in old
    ]
    if not rows:
        return
    lines += [
        "",
        "**What 2× would need.** Half the old commit's step (the table above it, medians of its runs) is the "
        "step the goal allows; the new step's kernel time (matrix products and Inductor's kernels, their "
        "profiled self time, and Adam) is what it spends in arithmetic at the kernels' present speed. What is "
        "left between them is all the goal allows for the rest (the batch, Python, the compiled wrapper, "
        "autograd), which the new step spends now:",
        "",
        "| recipe | threads | old step ms | 2× allows ms | new step ms | its kernel time ms | left for the rest "
        "ms | the rest now ms | the rest must fall to |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r, allowed, kernels in rows:
        left, rest = allowed - kernels, r["step"] - kernels
        lines.append(
            f"| {RECIPE_NAMES[r['recipe']]} | {r['threads']} | {2 * allowed:.1f} | {allowed:.1f} | "
            f"{r['step']:.1f} | {kernels:.1f} | {left:.1f} | {rest:.1f} | {100 * max(left, 0) / rest:.0f} % |"
        )
    # without pushforward the batch runs no model kernel: its time is all graph building and reading
    short = [
        (r, allowed - kernels)
        for r, allowed, kernels in rows
        if not any("pushforward" in k for k in RECIPES[r["recipe"]]) and allowed - kernels < r["batch"]
    ]
    lines += [""] + [
        f"With {RECIPE_NAMES[r['recipe']]} on {r['threads']} thread{'s' * (r['threads'] > 1)} the goal "
        f"leaves {left:.2f} ms for everything outside the kernels, less than building the batch alone "
        f"takes ({r['batch']:.2f} ms): there 2× needs the kernels themselves faster."
        for r, left in short
    ]
    lines.append(
        f"The two timings are separate runs on the same data (train_speed at {speed['commits']['new']}, "
        f"train_parts at {parts.get('commit', 'an unrecorded commit')}), one after the other."
    )


def defaults(d: dict) -> str:
    """What each checkout's ``check_designs`` defaults were in a design_ab run (recorded since the aot default)."""
    if not any("batch" in r for r in d["rows"]):
        return (
            "old: batches of 8, eager; new: batches of 8, `compile=auto`, which compiles once with symbolic sizes "
            "for this many designs"
        )

    def side(name):
        r = next(r for r in d["rows"] if r["side"] == name)
        mode = {
            "aot": "the ahead-of-time compiled forward, its package built on this machine before the run",
            "aot, built in the call": "the ahead-of-time compiled forward, its package built inside the call",
            "none": "eager",
            "default": "compiled once with symbolic sizes",
        }.get(r.get("compile"), r.get("compile"))
        return f"{name}: batches of {r.get('batch', 8)}, {mode}"

    return "; ".join(side(n) for n in ("old", "new"))


def design_ab(lines):
    """The design check per design, old commit against new against the solver, interleaved."""
    d = opened(lines, "### The design check against the old commit and the solver", "design_ab_cpu.json")
    if d is None:
        return
    s, loads = d["summary"], [r["load_1min"] for r in d["rows"]]
    lines += [
        f"Command: `{d['command']}`. Old {d['commits']['old']} against new {d['commits']['new']} and the "
        f"built-in solver, {d['designs']} designs of the shipped model's preset, {d['threads']} thread, "
        f"{d['rounds']} rounds of three fresh processes in alternating order (1-minute load "
        f"{min(loads):.1f}-{max(loads):.1f} as they ended), {d['device']}. Each design check is "
        f"`check_designs` with its checkout's defaults ({defaults(d)}); seconds per design, medians over "
        "rounds:",
        "",
        "| | old | new | solver | new ÷ old | new ÷ solver |",
        "|---|---|---|---|---|---|",
        f"| whole call (compilation included) | {s['old_s_per_design']:.2f} | {s['new_s_per_design']:.2f} | "
        f"{s['solver_s_per_design']:.2f} | {s['new_over_old']:.2f}× | {s['new_over_solver']:.2f}× |",
        f"| after the first chunk | {s['steady_old_s']:.2f} | {s['steady_new_s']:.2f} | "
        f"{s['solver_s_per_design']:.2f} | {s['steady_new_over_old']:.2f}× | "
        f"{s['steady_new_over_solver']:.2f}× |",
        "",
        f"The speed goals (≥ 2× the old code, ≥ 2× the solver per design): 2× the old code "
        f"{'reached' if s['new_over_old'] >= 2 else 'not reached'} for the whole call, 2× the solver "
        f"{'reached' if s['new_over_solver'] >= 2 else 'not reached'}.",
    ]
    if any(r.get("compile") == "aot" for r in d["rows"]):
        spread = ", ".join(
            f"{side} {min(t):.2f}-{max(t):.2f}"
            for side in ("old", "new", "solver")
            for t in [[r["per_design_s"] for r in d["rows"] if r["side"] == side]]
        )
        lines.append(
            "The new side loads its package (the forward compiled ahead of time) built on this machine before "
            "the run: a cost paid once per machine and model, by the first check of 2,000 model steps or "
            f"more, not inside these calls. Whole-call seconds per design across rounds: {spread}; a ratio "
            "this close to 2 depends on the round."
        )
    fm = load("forward_modes_cpu.json")
    if fm and "compiled-dynamic" in fm["modes"] and min(s["new_over_old"], s["new_over_solver"]) < 2:
        dyn, flops = fm["modes"]["compiled-dynamic"], fm["gflop_per_forward"]
        lines.append(
            f"Why not further: a forward of the shipped model is {flops:.2f} GFLOP of matmuls; compiled with "
            f"symbolic sizes it runs at {dyn['gflop_per_s']:.0f} GFLOP/s ({dyn['ms']:.1f} ms, the section "
            "below), so the 88 steps of a design cost about "
            f"{88 * dyn['ms'] / 1e3:.2f} s of forward passes alone, and each process pays the compilation "
            "(the whole-call row). 2× the solver in the whole call needs fewer FLOPs (a narrower model) or "
            "bf16 matmuls (not exact: see the relative differences below), or the compilation kept across "
            "processes (an ahead-of-time compiled model)."
        )
    lines.append("")


FORWARD_MODES = {
    "eager": "eager",
    "compiled-static": "compiled, static shapes (padded graph)",
    "compiled-dynamic": "compiled, symbolic sizes (rollouts)",
    "frozen": "compiled, frozen weights",
    "frozen-bf16": "compiled, frozen, bf16 autocast",
    "bf16": "eager, bf16 autocast",
    "aot": "exported ahead of time (AOTInductor, symbolic sizes)",
}


def forward_modes(lines):
    """One rollout step of the shipped model in each inference mode."""
    d = opened(lines, "### One rollout step in each inference mode", "forward_modes_cpu.json")
    if d is None:
        return
    lines += [
        f"Command: `{d['command']}` ({d['device']}, {d['threads']} thread): the shipped model's forward on "
        f"one design's graph ({d['nodes']} nodes, {d['mesh_edges']} mesh edges, {d['contact_edges']} contact "
        f"edges; {d['padded_nodes']} nodes padded), {d['gflop_per_forward']:.2f} GFLOP of matmuls a forward. "
        "Relative difference: ‖y − y_eager‖ / ‖y_eager‖ of the normalized output.",
        "",
        "| mode | ms | GFLOP/s | first call s | relative difference |",
        "|---|---|---|---|---|",
    ]
    for mode, r in d["modes"].items():
        lines.append(
            f"| {FORWARD_MODES.get(mode, mode)} | {r['ms']:.1f} | {r['gflop_per_s']:.1f} | "
            f"{r['first_call_s']:.1f} | {r['rel_diff']:.1e} |"
        )
    if "aot" in d["modes"]:
        lines += [
            "",
            "The ahead-of-time row's package is built (once per machine and model) or loaded before its "
            "first call, outside these timings; the modes run one after the other, not interleaved.",
        ]
    lines.append("")
