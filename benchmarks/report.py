"""Write docs/RESULTS.md, and the measured blocks of docs/MODELS.md's cards (release/card.py), from the JSON files
under benchmarks/results/ (only what a benchmark command produced).

    python benchmarks/report.py

Each section is written by the report.py of its study's folder (accuracy/report.py, speed/report.py, ...);
report_common.py, next to this file, holds what they share (reading the result files, the paper's numbers, and the rules
that choose every judging word). This file keeps the order and puts benchmarks/ on sys.path for them."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from accuracy.report import ablations, accuracy, generalization, longer  # noqa: E402
from common import RESULTS, ROOT  # noqa: E402
from ghost_diagnosis.report import ghost_ablations, ghost_diagnosis  # noqa: E402
from gpu_check.report import gpu_check, gpu_path  # noqa: E402
from interval.report import interval  # noqa: E402
from memory.report import memory  # noqa: E402
from parity.report import hierarchy, parity, propagation  # noqa: E402
from peers.report import peers as peers_section  # noqa: E402
from recipe.report import recipe  # noqa: E402
from release.card import write_cards  # noqa: E402
from report_common import load  # noqa: E402
from scaling.report import scaling as scaling_section  # noqa: E402
from speed.report import cpu_ab, design_ab, forward_modes, speed, threads, train_parts, train_speed  # noqa: E402
from surrogate.report import (
    judge as judge_section,  # noqa: E402
    surrogate as surrogate_section,  # noqa: E402
)
from transfer.report import transfer as transfer_section, transfer_given  # noqa: E402
from trust.report import trust as trust_section  # noqa: E402

DOC = ROOT.parent / "docs" / "RESULTS.md"
INTRO = (
    "Every number below was produced by the command quoted with it, on this project's development machine "
    "(2 CPU cores, no GPU) unless stated. This file is written by `python benchmarks/report.py` from "
    "`benchmarks/results/*.json`; the paper's numbers are quoted for comparison only."
)
#: what the commands' folders mean, stated once for every section
FOLDERS = (
    "**Folders.** Run every command from the checkout's root; a relative path is relative to it. `$HCMT_WORK` "
    "is the work folder for data sets, run folders and scratch results, which git does not track: set it "
    "before copying a command, `export HCMT_WORK=${HCMT_WORK:-benchmarks/work}` (the folder inside the "
    "checkout that git ignores, and the scripts' default). `$HCMT_WORK/data/ip480` (the scaling study's and "
    "the shipped model's 480 designs) is made by the `hcmt generate` command of benchmarks/scaling/README.md, "
    '`$HCMT_WORK/data/fam_*` by those of "Panel families: transfer", `$HCMT_WORK/runs/ship480` (the shipped '
    "model's run) by `bash benchmarks/release/train_successor.sh`; `$HCMT_WORK/old-COMMIT`, `$HCMT_WORK/new37` "
    "and `$HCMT_WORK/frozen` are worktrees of the commits a comparison or a restore names (`git worktree add "
    "$HCMT_WORK/old-c18f6a3 c18f6a3`). Result files record their folders in these names "
    "(`portable` in benchmarks/common.py); those written before recorded the running machine's folders, "
    "since renamed to them (scripts/portable_results.py), their numbers untouched."
)
SECTIONS = (
    recipe,
    interval,
    threads,
    parity,
    propagation,
    accuracy,
    longer,
    ghost_diagnosis,
    ghost_ablations,
    ablations,
    generalization,
    memory,
    speed,
    gpu_path,
    cpu_ab,
    train_speed,
    train_parts,
    design_ab,
    forward_modes,
    gpu_check,
    hierarchy,
)


def main() -> None:
    lines = ["# Results", "", INTRO, "", FOLDERS, ""]
    surrogate_section(lines, load("surrogate.json"))
    judge = load("model_judge.json")
    judge_section(lines, judge)
    trust_section(lines, load("trust.json"))
    transfer_section(lines, load("transfer.json"))
    transfer_given(lines, load("transfer_shipped.json"))
    judges = [load(p.name) for p in sorted(RESULTS.glob("scaling_judge_step*.json"))]
    scaling_section(
        lines,
        load("scaling.json"),
        load("scaling_long_run.json"),
        load("scaling_long_run_sweeps.json"),
        [j for j in [judge, *judges] if j],
    )
    for section in SECTIONS:
        section(lines)
    peers_section(lines, load("peers_cpu.json"))
    DOC.parent.mkdir(exist_ok=True)
    DOC.write_text("\n".join(lines).rstrip() + "\n")
    print(f"wrote {DOC}")
    for name in write_cards():
        print(f"wrote the measured block of {name}'s card in docs/MODELS.md")


if __name__ == "__main__":
    main()
