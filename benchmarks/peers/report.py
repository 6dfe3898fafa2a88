"""docs/RESULTS.md's section "Speed against the peers", from benchmarks/results/peers_cpu.json
(``benchmarks/peers/run.py``). The verdict per ratio is the target, hcmt ≤ 0.8× the peer, read off the
median of the per-round ratios; the range of the rounds is printed next to it. ``python benchmarks/peers/report.py``
prints the section alone."""

from __future__ import annotations

import json
import sys
from pathlib import Path

HEADING = "## Speed against the peers (one CPU thread)"
COMMAND = "benchmarks/peers/install.sh && PYTHONPATH=src python benchmarks/peers/run.py"
TARGET = 0.8  # the goal: hcmt at most 0.8x the peer's time (no slower than a rewrite should be)
KINDS = (("train", "train step"), ("infer", "inference"))


def _ms(row: dict, kind: str) -> str:
    r = row[f"{kind}_ms_rounds"]
    return f"{row[f'{kind}_ms']:,.0f} ({min(r):,.0f}-{max(r):,.0f})"


def _rate(row: dict, kind: str) -> str:
    if f"{kind}_gflops_per_s" not in row:
        return "-"
    return f"{row[f'{kind}_gflops_per_s']:.1f} ({100 * row[f'{kind}_peak_share']:.1f} %)"


def _rounds(result: dict) -> str:
    """How each model family was timed (a run per family when ``--only`` split them) and the load it met."""
    parts = result.get("parts") or {"all": result}
    return "; ".join(
        f"{'' if f == 'all' else f.upper() + ': '}{p['rounds']} interleaved rounds of "
        f"{p['steps_per_round']} calls each, load average {p['load_average'][0]:.1f} on the 2 cores "
        f"at the end"
        for f, p in parts.items()
    )


def peers(lines: list[str], result: dict | None) -> None:
    if not result:
        return
    g, peak = result["graph"], result["peak"]
    lines += [
        HEADING,
        "",
        (
            f"`{COMMAND}` (README: benchmarks/peers/README.md). One graph for all: the paper-size Impact Plate frame, "
            f"{g['nodes']:,} nodes, {g['mesh_edges']:,} mesh and {g['contact_edges']:,} contact edges, hierarchy "
            f"levels {', '.join(map(str, g['level_nodes']))} nodes. Each contestant in its own process and venv, "
            f"one thread; {_rounds(result)}; times are the median of the round medians, in brackets the range of "
            f"the round medians. GFLOP/s from matmul FLOPs counted by "
            f"`torch.utils.flop_counter` (the authors' TF HCMT is credited with hcmt's official-HCMT count); share of "
            f"the core's peak {peak['gflops']:.0f} GFLOP/s = {peak['derivation']}."
        ),
        "",
        "| contestant | framework | train step ms | inference ms | train GFLOP/s (% peak) | "
        "inference GFLOP/s (% peak) |",
        "|---|---|---|---|---|---|",
    ]
    for row in result["rows"]:
        fw = row["framework"] + (
            "; torch_scatter stood in by torch_geometric.utils.scatter"
            if row.get("scatter", "").startswith("stand-in")
            else ""
        )
        lines.append(
            f"| {row['contestant']} | {fw} | {_ms(row, 'train')} | {_ms(row, 'infer')} | "
            f"{_rate(row, 'train')} | {_rate(row, 'infer')} |"
        )
    lines += ["", f"| hcmt | ÷ peer | what | ratio (rounds' range) | target ≤ {TARGET} |", "|---|---|---|---|---|"]
    for r in result["ratios"]:
        ok = "met" if r["ratio"] <= TARGET else "not met"
        lines.append(
            f"| {r['hcmt']} | {r['peer']} | {dict(KINDS)[r['kind']]} | {r['ratio']:.2f} "
            f"({r['min']:.2f}-{r['max']:.2f}) | {ok} |"
        )
    for fam, what in (("mgn", "MGN against PhysicsNeMo"), ("hcmt", "HCMT (official) against the authors' TF")):
        if not any(r["model"] == fam for r in result["rows"]):
            lines += ["", f"Not measured yet: {what} (`run.py --only {fam}`)."]
    for name, err in result.get("failed", {}).items():
        lines += ["", f"Not measured: {name}: {err}"]
    lines.append("")


if __name__ == "__main__":
    default = Path(__file__).resolve().parents[1] / "results" / "peers_cpu.json"
    path = Path(sys.argv[1]) if len(sys.argv) > 1 else default
    out: list[str] = []
    peers(out, json.loads(path.read_text()))
    print("\n".join(out))
