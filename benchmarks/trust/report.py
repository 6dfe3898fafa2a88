"""docs/RESULTS.md's section "The mesh model's own interval", from benchmarks/results/trust.json
(``python benchmarks/trust/run.py``). Every verdict below is computed from the numbers it prints."""

from __future__ import annotations

import math

from report_common import command, said, sentences

COMMAND = "python benchmarks/trust/run.py --work $HCMT_WORK/trust --fuzz 200 --write"
ANSWERS = (
    ("peak_plate_stress_mpa", "peak"),
    ("max_deflection_mm", "deflection"),
    ("plate_stress_history_mpa", "whole history"),
)
CALLS = (
    ("model", "the model's interval alone (`model`)"),
    ("union", "with the response surface (`union`)"),
    ("intersection", "narrowed by the response surface (`intersection`)"),
    ("model_before", "before: the model ± 60 %, outside undecided"),
    ("union_before", "before: the response surface and the model's answer, outside undecided"),
)
#: a coverage is "short of the level" when so few covered designs would happen with this probability or less at the
#: nominal level (one-sided binomial): sampling noise alone rarely explains it
SHORT_P = 0.05


def seeds_text(seeds) -> str:
    """A seed or a list of them, as text."""
    return ", ".join(map(str, seeds)) if isinstance(seeds, list) else str(seeds)


def _pct(x, digits=0) -> str:
    return "-" if x is None else f"{100 * x:.{digits}f} %"


def _cov(c: dict) -> str:
    return "-" if not c["of"] else f"{c['covered']} / {c['of']} ({_pct(c['share'])})"


def binomial_tail(k: int, n: int, p: float) -> float:
    """P(at most k of n) at probability p."""
    return sum(math.comb(n, i) * p**i * (1 - p) ** (n - i) for i in range(k + 1))


def short(c: dict, level: float) -> bool:
    return bool(c["of"]) and c["covered"] < level * c["of"] and binomial_tail(c["covered"], c["of"], level) < SHORT_P


def coverage_table(block: dict) -> list[str]:
    lines = [
        "| designs | n | no interval | "
        + " | ".join(f"{name} covered" for _, name in ANSWERS)
        + " | median width (peak) | history band (± share of peak) | median / worst peak error | "
        "response surface: covers, width | ± 60 % band covers |",
        "|---" * 11 + "|",
    ]
    for part in ("by_region", "by_cell"):
        for key, s in block[part].items():
            if part == "by_cell" and key in block["by_region"]:  # inside: its row is the region's
                continue
            g = s["surrogate"]
            gp = "-" if not g["designs"] else f"{_cov(g['coverage'])}, {_pct(g['median_rel_width'])}"
            name = key if part == "by_cell" or key in ("inside", "outside") else f"{key} (all distances)"
            lines.append(
                f"| {name if part == 'by_region' else f'cell {name}'} | {s['designs']} | "
                f"{s['without_interval']} | "
                + " | ".join(_cov(s["coverage"][k]) for k, _ in ANSWERS)
                + f" | {_pct(s['median_rel_width_peak'])} | {_pct(s['median_history_band'])} | "
                f"{s['median_abs_peak_error_pct']:.1f} % / "
                f"{s['worst_abs_peak_error_pct']:.1f} % | {gp} | {_cov(s['model_band']['coverage'])} |"
            )
    return lines


def calls_table(r: dict) -> list[str]:
    factors = [f"{f:g}" for f in r["factors"]]
    lines = [
        "| trusted interval | points | unsafe passes | fails the solver passes | solver needed | "
        + " | ".join(f"solver needed at × {f}" for f in factors)
        + " |",
        "|---" * (5 + len(factors)) + "|",
    ]
    for key, label in CALLS:
        c = r["calls"]["pooled"][key]
        a = c["all"]
        lines.append(
            f"| {label} | {a['points']} | {a['unsafe']} | {a['wrong_fail']} | {_pct(a['undecided_share'])} | "
            + " | ".join(_pct(c["by_factor"][f]["undecided_share"]) for f in factors)
            + " |"
        )
    return lines


def reading(r: dict) -> list[str]:
    level, pooled = r["level"], r["coverage"]["pooled"]
    shorts = [
        f"{k} ({name}: {_cov(s['coverage'][a])})"
        for k, s in pooled["by_cell"].items()
        for a, name in ANSWERS
        if short(s["coverage"][a], level)
    ]
    below = [
        f"{k} ({name})"
        for k, s in pooled["by_cell"].items()
        for a, name in ANSWERS
        if s["coverage"][a]["of"] and s["coverage"][a]["share"] < level
    ]
    missing = [k for k, s in pooled["by_cell"].items() if s["without_interval"]]
    seeds = [k for k in r["coverage"] if k.startswith("seed ")]

    def peak(seed, region):
        got = r["coverage"][seed]["by_region"].get(region)
        return f"{region} {_pct(got['coverage']['peak_plate_stress_mpa']['share'])}" if got else ""

    per_seed = "; ".join(f"{k}: " + ", ".join(x for x in (peak(k, "inside"), peak(k, "outside")) if x) for k in seeds)
    req = r["requirement"]
    out = [
        "- "
        + sentences(
            f"Nominal level {_pct(level)}.",
            "Every cell's coverage reaches it."
            if not below
            else f"Below it: {said(below)}; "
            + (
                f"short of it beyond sampling noise (one-sided binomial p < {SHORT_P}): {said(shorts)}."
                if shorts
                else f"each within sampling noise of it (one-sided binomial p ≥ {SHORT_P} at its design count)."
            ),
            f"Designs without an interval (a cell the calibration did not hold): {said(missing)}." if missing else "",
            f"Peak coverage per evaluation seed: {per_seed}.",
        )
    ]
    out.append(
        "- "
        + sentences(
            f"Limit calls with the calibrated interval alone: {req['unsafe']} unsafe passes, the solver needed on "
            f"{_pct(req['solver_share'], 1)} of the points (the requirement: none unsafe, the solver on at most "
            f"{_pct(req['solver_share_at_most'])}):",
            "met." if req["met"] else "not met.",
        )
    )
    fz = r.get("fuzz")
    if fz:
        left = [
            f"{fz['too_costly']} estimated at over 60 s of solver time "
            f"({fz['too_costly_in_a_calibrated_cell']} of them in a calibrated cell)"
            if fz["too_costly"]
            else "",
            f"{fz['refused_by_the_check']} refused by the check" if fz["refused_by_the_check"] else "",
        ]
        left = [x for x in left if x]
        out.append(
            "- "
            + sentences(
                f"Fuzzer (seed {fz['seed']}): {fz['designs']} valid designs with 1-3 parameters beyond their range by "
                '0.01 to 10 widths (log-uniform), each through the design check (`verify="auto"`, the fitted '
                "interval, the response surface) at a yield stress drawn from 300-3000 MPa.",
                f"Left out: {said(left)}." if left else "",
                f"Of the {fz['checked']} checked, {fz['in_a_calibrated_cell']} in a calibrated cell, {fz['decided']} "
                f"with a decided call; {fz['final_passes']} final passes ({fz['final_passes_verified']} verified by "
                f"the check, {fz['final_passes_checked']} run on the solver here), {fz['unsafe']} of them failed by "
                "the solver.",
            )
        )
    return out


def trust(lines: list[str], r: dict | None) -> None:
    lines += ["## The mesh model's own interval", ""]
    if r is None:
        lines += ["Not run yet: `" + COMMAND + "`.", ""]
        return
    d = r["designs"]
    cells = said([f"`{c}`" for c in d["cells"]])
    lines += [
        "```bash",
        command(r),
        "```",
        "",
        sentences(
            f"The mesh model's own {_pct(r['level'])} interval (`hcmt.design.model_interval`, model "
            f"`{r['model']}`): split conformal per cell, fitted on the solver's runs of "
            f"{d['calibration']} designs of seed(s) {seeds_text(r['seeds']['calibration'])} "
            f"({d['inside']} per seed inside the "
            f"training ranges and {d['per_cell']} per outside cell: {cells} at "
            + said([f"{x:g}" for x in d["distances"]])
            + " of a range's width beyond it), measured on "
            f"{d['evaluation']} designs of seed{'s' if len(r['seeds']['evaluation']) > 1 else ''} "
            + said([str(s) for s in r["seeds"]["evaluation"]])
            + " drawn the same way.",
            "Covered: the share of designs with an interval whose solver value lies inside it (the "
            "whole history: every frame inside the band).",
            "Width: (hi - lo) / the model's peak; the history band: the model's history ± this share of its peak.",
            "Beside it on the same designs, the response surface's 95 % interval of the peak "
            f"({r['surrogate'] or 'none'}) and the band the calls trusted before (the model's answer "
            f"± {_pct(r['model_band'])}).",
            f"Device: {r['device']} ({r['machine']}), {r['threads']} thread; solver "
            f"{r['seconds']['solver_median_per_design']:.1f} s and model "
            f"{r['seconds']['model_median_per_design']:.1f} s per design (medians).",
        ),
        "",
        "Pooled over the evaluation seeds:",
        "",
    ]
    lines += coverage_table(r["coverage"]["pooled"]) + [""]
    lines += [
        "**Limit calls** at yield stresses of each design's solver peak × "
        + ", ".join(f"{f:g}" for f in r["factors"])
        + " (a pass is unsafe where the solver fails; "
        '"solver needed": the undecided calls, which `--verify auto` hands to the solver; a design outside '
        "the ranges in a cell the calibration does not hold is undecided):",
        "",
    ]
    lines += calls_table(r) + [""] + reading(r) + [""]
    if r.get("wrote_calibration"):
        lines += [f"The calibration ships as `{r['wrote_calibration']}`, its `measured` block these numbers.", ""]
