"""docs/RESULTS.md's GPU sections: eager against compiled steps and batch throughput
(benchmarks/micro/bench_models.py --compile), the learned design sweep against the solver
(benchmarks/micro/design_speed.py), the GPU goals, and benchmarks/gpu_check/run.py's JSON."""

from __future__ import annotations

import json

from report_common import GOAL_NODES, GOALS, MACHINE, command, gpu_check_ran, load, on_gpu, reached, sentences

NO_GPU = (
    "GPU rows: **not measured**: no GPU was lent to the sessions that ran these commands (the code paths are "
    "the same; on CUDA `bench_models.py --compile` uses `reduce-overhead`, i.e. CUDA graphs, and fused Adam). "
    "The rows below are the CPU's."
)
AGREES = (
    "agrees with the eager step to float tolerance, not bit for bit (tests/training/test_train.py): "
    "`train.compile` stays off by default."
)


def gpu_path(lines):
    """The GPU sections: eager vs compiled steps, throughput by batch size, learned design check vs solver."""
    modes, designs = load("models_modes_cpu.json"), load("design_speed_cpu.json")
    if not modes and not designs:
        return
    models, roll = load("models_cpu.json") or [], load("speed_rollout.json")
    lines += ["### Compiled steps, batch throughput and the design sweep", ""]
    if not any(on_gpu(d) for d in [e["device"] for e in modes or []] + [designs["device"] if designs else None]):
        lines += [NO_GPU, ""]
    for entry in modes or []:
        compiled_steps(lines, entry, models)
    if designs:
        sweep(lines, designs)
        goals(lines, modes or [], designs, models, roll or {})


def compiled_steps(lines, entry, models):
    rows = {(r["model"], r["mode"], r["batch"]): r for r in entry["rows"]}
    pairs = [(m, b) for (m, mode, b) in rows if mode == "eager" and (m, "compiled", b) in rows]
    # above the one-thread table: every model's eager batch-1 step is slower here than there
    ref = {
        m: r["train_ms"]
        for e in models
        if (e["device"], e["threads"]) == (entry["device"], entry["threads"])
        for m, r in e["models"].items()
    }
    eager1 = {m: r["train_ms"] for (m, mode, b), r in rows.items() if mode == "eager" and b == 1 and m in ref}
    above = bool(eager1) and all(eager1[m] > ref[m] for m in eager1)
    hcmt = [(rows[("hcmt", "eager", b)], rows[("hcmt", "compiled", b)]) for m, b in pairs if m == "hcmt"]
    compiled = ""
    if hcmt:
        faster = all(c["train_ms"] < e["train_ms"] for e, c in hcmt)
        minutes = all(c["train_warmup_s"] >= 60 for _, c in hcmt)
        cost = f" {'but' if faster else 'and'} costs minutes of compilation per shape" if minutes else ""
        compiled = f"The compiled step is {'faster' if faster else 'not faster'} for HCMT on this CPU{cost}."
    batches = " ".join(sorted({str(r["batch"]) for r in entry["rows"]}, key=int))
    command = (
        f"Command: `python benchmarks/micro/bench_models.py --device cpu --threads {entry['threads']} --steps "
        f"{entry['steps']} --compile --batches {batches} --json benchmarks/results/models_modes_cpu.json` "
        f"({entry['device']}, {entry['threads']} thread, paper-size graph of {entry['nodes']} nodes; batch B "
        "= B copies of it; the trainer's step: eager, or padded + eager normalizer accumulation + "
        "`torch.compile` (inductor) of forward and backward; median of the timed steps; warm-up = the first "
        "3 steps, compilation included)."
    )
    load_note = ", so the absolute times are above the one-thread table above." if above else "."
    lines += [
        sentences(
            command,
            "Measured while a training run held the machine's other core" + load_note,
            "Eager and compiled ran in the same process, one after the other, under the same load.",
            compiled,
            f"{'It' if compiled else 'The compiled step'} {AGREES}",
        ),
        "",
        "| model | mode | batch | train ms/step | samples/s | inference ms | warm-up s |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in entry["rows"]:
        inf = f"{r['inference_ms']:.0f}" if "inference_ms" in r else ""
        lines.append(
            f"| {r['model'].upper()} | {r['mode']} | {r['batch']} | {r['train_ms']:.0f} | "
            f"{r['samples_per_s']:.2f} | {inf} | {r['train_warmup_s']:.0f} |"
        )

    def over(m, b, key):
        return rows[(m, "compiled", b)][key] / rows[(m, "eager", b)][key]

    ratios = [
        f"{m.upper()} batch {b}: train {over(m, b, 'train_ms'):.2f}×"
        + (f", inference {over(m, b, 'inference_ms'):.2f}×" if "inference_ms" in rows[(m, "eager", b)] else "")
        for m, b in pairs
    ]
    if ratios:
        lines += ["", "Compiled ÷ eager (same run): " + "; ".join(ratios) + "."]
    lines.append("")


def sweep(lines, designs):
    lines += [
        f"Command: `{command(designs)}` ({designs['device']}, {designs['threads']} thread): "
        f"{designs['designs']} designs drawn from the model's training ranges; the built-in solver simulates "
        f"each one (median {designs['solver_s_median']:.2f} s per design), the shipped model predicts them "
        "from their parameters (wall time per design = batch wall time ÷ designs, compilation included).",
        "",
        "| batch / mode | s per design | speedup (solver median ÷ prediction) | median peak-stress error % |",
        "|---|---|---|---|",
    ]
    for key, r in designs["batches"].items():
        lines.append(
            f"| {key} | {r['per_design_s']:.3f} | {r['speedup_median_solver']:.2f}× | "
            f"{r['peak_stress_error_pct_median']:.1f} |"
        )
    hows = dict.fromkeys(r["speedup_measured"]["how"] for r in designs["batches"].values() if "speedup_measured" in r)
    if hows:
        lines += ["", sentences(*(f"Speedup: {how}." for how in hows))]
    one, many = designs["batches"].get("1"), designs["batches"].get("64")
    if one and many:
        slower = many["per_design_s"] > one["per_design_s"]
        why = "On one CPU thread a batch brings no parallelism." if slower and designs["threads"] == 1 else ""
        lines += [
            "",
            sentences(
                "The 64-design sweep (the first half of it while `benchmarks/release/ship_model.py` "
                f"used the other core) is {'slower' if slower else 'not slower'} per design in one "
                "batch of 64 than one by one.",
                why,
            ),
        ]


def goals(lines, modes, designs, models, roll):
    """The GPU goals against the best CPU value of the rows above (None: no row measures it)."""
    one, many = designs["batches"].get("1"), designs["batches"].get("64")
    step_rows = [r for e in modes for r in e["rows"] if r["batch"] == 1]
    plain = [r for e in models for r in e["models"].values()]

    def best(vals, f):
        return f(vals) if vals else None

    values = [
        best(
            ([one["speedup_median_solver"]] if one else [])
            + [v for k, v in roll.items() if k.endswith("_speedup_vs_solver")],
            max,
        ),
        many["speedup_median_solver"] if many else None,
        best([r["train_ms"] for r in step_rows + plain], min),
        best([r["samples_per_s"] for e in modes for r in e["rows"]], max),
        best([r["inference_ms"] for r in step_rows + plain if "inference_ms" in r], min),
    ]
    state = [
        "not measured" if v is None else "reached" if reached(v, t, up) else "not reached"
        for v, (_, t, up) in zip(values, GOALS)
    ]
    cpu = (
        "they are not reached (rows above)"
        if set(state) == {"not reached"}
        else "; ".join(f"{g}: {s}" for (g, _, _), s in zip(GOALS, state)) + " (rows above)"
    )
    gpu = "see the GPU check below" if gpu_check_ran() else "they are not measured"
    lines += [
        "",
        sentences(
            f"The GPU goals ({', '.join(g for g, _, _ in GOALS)}) are GPU goals.",
            f"On this {MACHINE} {cpu}; on a GPU {gpu}.",
        ),
        "",
    ]


NODE_GOAL = (f"a {GOAL_NODES:,}-node step", GOAL_NODES, True)  # the GPU check's goal beside GOALS


def gpu_goals(d) -> list[tuple[float | None, str]]:
    """The GPU goals (:data:`GOALS`, then :data:`NODE_GOAL`) against gpu_check.json: the best
    measured value (None: not measured) and which row it comes from."""
    steps = d["steps"]
    rows = steps.get("train step", {}).get("rows", [])
    roll, mem = steps.get("rollout vs solver", {}), steps.get("memory", {}).get("rows", [])

    def best(cands, f):
        cands = [c for c in cands if c[0] is not None]
        return f(cands, key=lambda c: c[0]) if cands else (None, "not measured")

    one = best([(roll.get(k), k) for k in ("speedup_one", "speedup_one_aot")], max)
    sweep = (roll.get("speedup_batch"), f"batch of {roll.get('batch')}") if "speedup_batch" in roll else (None, "")
    step = best([(r["train_ms"], f"{r['model']} {r['mode']}") for r in rows if r["batch"] == 1], min)
    rate = best([(r["samples_per_s"], f"{r['model']} {r['mode']} batch {r['batch']}") for r in rows], max)
    infer = best([(r["inference_ms"], f"{r['model']} {r['mode']}") for r in rows if "inference_ms" in r], min)
    big = [r for r in mem if "train_ms" in r]
    nodes = best(
        [
            (
                r["nodes"],
                f"{r['train_ms'] / 1e3:.2f} s a step, {r['peak_mb'] / 1024:.0f} GiB"
                + (" with activation checkpointing" if r["checkpoint_blocks"] else ""),
            )
            for r in big
        ],
        max,
    )
    return [one, sweep, step, rate, infer, nodes]


def reading(d) -> str:
    """What the train-step rows say, computed from them: where a small graph's step goes on the GPU."""
    train = d["steps"].get("train step", {}).get("rows", [])
    rows = {(r["model"], r["mode"], r["batch"]): r["train_ms"] for r in train}
    models = dict.fromkeys(m for m, _, _ in rows)

    def ratios(a, b, digits=2, suffix=""):  # step time of row a ÷ row b, per model that has both
        return ", ".join(
            f"{m} {rows[(m, *a)] / rows[(m, *b)]:.{digits}f}×{suffix}"
            for m in models
            if (m, *a) in rows and (m, *b) in rows
        )

    out = []
    if grow := ratios(("eager", 32), ("eager", 1), 1):
        out.append(
            f"Eager, 32 copies of the graph take this much longer than one: {grow}: at the paper's mesh size a "
            "step is bound by kernel launches and Python, not by arithmetic, so the GPU's throughput comes "
            "from batches."
        )
    if comp := ratios(("eager", 1), ("compile-default", 1), 1):
        out.append(f"`torch.compile` (default) makes the one-graph step faster by {comp}.")
    if graphs := ratios(("compile-reduce-overhead", 1), ("compile-default", 1)):
        out.append(
            f"Step time with CUDA graphs (`reduce-overhead`) ÷ with `default`: {graphs} (no gain: what "
            "remains is not launch overhead inside the compiled graph; not profiled)."
        )
    bf = [part for b in (1, 32) if (part := ratios(("bf16", b), ("eager", b), suffix=f" at batch {b}"))]
    if bf:
        out.append("Step time with bf16 autocast ÷ fp32 eager: " + "; ".join(bf) + ".")
    out.append("Compiled steps were timed at batch 1 only, so the samples/s goal is read from eager batches.")
    return sentences(*out)


def gpu_check(lines):
    """benchmarks/gpu_check/run.py's JSON (copied to benchmarks/results/gpu_check.json from a GPU machine)."""
    d = load("gpu_check.json")
    lines += ["## GPU check", ""]
    if not d or d.get("smoke"):
        every = ", ".join(g for g, _, _ in GOALS + (NODE_GOAL,))
        lines += [
            sentences(
                "`PYTHONPATH=src python benchmarks/gpu_check/run.py --out $HCMT_WORK/gpu_check` has not "
                "run on a GPU yet (no GPU lent).",
                f"Every GPU goal ({every}) is **not measured**.",
            ),
            "",
        ]
        return
    calls = d.get("earlier_calls", []) + [{"budget_s": d["budget_s"]}]
    budgets = ", then ".join(f"{c['budget_s']:.0f} s" for c in calls)
    how = (
        f"{len(calls)} calls ({budgets} of budget; the later "
        "ones with `--resume`, which keeps the steps an earlier call finished)"
        if len(calls) > 1
        else f"budget {d['budget_s']:.0f} s"
    )
    lines += [
        "Command: `PYTHONPATH=src python benchmarks/gpu_check/run.py --out $HCMT_WORK/gpu_check` on "
        f"{d['device']} (torch {d['torch']}; {how}). The train step times one paper-size Impact Plate graph "
        "(batch B = B copies), median of 20 steps after 5.",
        "",
        "| goal | best measured | row | reached |",
        "|---|---|---|---|",
    ]
    for (goal, threshold, up), (value, row) in zip(GOALS + (NODE_GOAL,), gpu_goals(d)):
        state = "not measured" if value is None else "yes" if reached(value, threshold, up) else "no"
        if goal == NODE_GOAL[0] and state == "no":  # a smaller mesh ran: the goal's size itself did not
            state = f"not measured at {GOAL_NODES:,} (the largest mesh run)"
        shown = "" if value is None else f"{value:,.0f}" if value >= 100 else f"{value:.3g}"
        lines.append(f"| {goal} | {shown} | {row} | {state} |")
    lines += [
        "",
        "| model | mode | batch | nodes | train ms | samples/s | inference ms |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in d["steps"].get("train step", {}).get("rows", []):
        inf = f"{r['inference_ms']:.2f}" if "inference_ms" in r else ""
        lines.append(
            f"| {r['model']} | {r['mode']} | {r['batch']} | {r['nodes']:,} | {r['train_ms']:.1f} | "
            f"{r['samples_per_s']:.0f} | {inf} |"
        )
    mem = d["steps"].get("memory", {}).get("rows", [])
    if mem:
        lines += [
            "",
            "| nodes | activation checkpointing | train s a step | peak GiB | kB a node |",
            "|---|---|---|---|---|",
        ]
        for r in mem:
            if "oom" in r:
                lines.append(f"| {r['nodes']:,} | {r['checkpoint_blocks']} | out of memory | | |")
            else:
                lines.append(
                    f"| {r['nodes']:,} | {'yes' if r['checkpoint_blocks'] else 'no'} | "
                    f"{r['train_ms'] / 1e3:.2f} | {r['peak_mb'] / 1024:.1f} | {r['peak_kb_per_node']:.0f} |"
                )
    roll = d["steps"].get("rollout vs solver")
    if roll and "error" not in roll:
        lines += [
            "",
            sentences(
                "Design check on the GPU with the model shipped at the time of the run: one design "
                f"{roll['one_design_s']:.2f} s against the "
                f"solver's {roll['solver_one_design_s']:.2f} s ({roll['speedup_one']:.2f}×; {roll['solver']}).",
                f"{roll['batch']} designs in one batch: {roll['batch_per_design_s']:.3f} s a design against the "
                f"solver's median {roll['solver_median_s']:.2f} s over "
                f"{roll.get('solver_designs', roll['batch'])} designs ({roll['speedup_batch']:.2f}×).",
            ),
        ]
    lines += ["", reading(d)]
    for name in ("deterministic resume", "accuracy", "cuda tests"):
        r = d["steps"].get(name)
        if r:
            lines += ["", f"**{name}**: `{json.dumps({k: v for k, v in r.items() if k != 'rows'})}`"]
    lines += [""] + [f"- skipped: {s}" for s in d["skipped"]] + [""]
