"""docs/RESULTS.md's section "Scaling with budget and designs", from benchmarks/results/scaling.json
(``python benchmarks/scaling/run.py``). Every verdict is computed from the numbers the section prints; with no
point run yet it says so. ``python benchmarks/scaling/report.py [JSON]`` prints the section alone."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/
from report_common import (  # noqa: E402
    MODEL_GOALS,
    OUTSIDE_GOALS,
    PAPER_RATIO,
    PAPER_STEPS,
    PAPER_TRAJECTORIES,
    sentences,
)
from scaling.analysis import (  # noqa: E402
    METRICS,
    extrapolate,
    fit_power_law,
    margin_trend,
    means_by,
    reaches,
    run_of,
)

HEADING = "## Scaling with budget and designs"
MODELS = (("hcmt", "HCMT"), ("mgn", "MGN"))
DATA = (
    "hcmt generate impact-plate $HCMT_WORK/data/ip480 --preset small --train 480 --valid 12 --test 24 --variants "
    "--variant-count 8 --seed 3035 --frames 90 --edge-fraction 0.35 --peak-stress --workers 1"
)
COMMAND = "python benchmarks/scaling/run.py --data $HCMT_WORK/data/ip480 --work $HCMT_WORK/scaling"
# The rules.
MARGIN_FLAT = 0.05  # |exponent of HCMT ÷ MGN against the axis| below this: the margin is "about constant"
FALLS = 0.0  # a fitted exponent above this: the error falls along the axis
LOOSE = 0.8  # a fit's R² below this: marked "loose fit" next to its extrapolation
MIN_FIT = 3  # axis values a power law is fitted to: through two points any line fits (R² 1 by construction)


def _cell(values: list[float], fmt: str) -> str:
    """The mean over seeds, each seed in brackets when there are several."""
    if not values:
        return "-"
    mean = fmt.format(float(np.mean(values)))
    return mean + (f" ({' / '.join(fmt.format(v) for v in values)})" if len(values) > 1 else "")


FORMATS = {
    "position_rmse_all": "{:.4g}",
    "stress_rmse_all": "{:.4g}",
    "peak_error_pct": "{:.1f}",
    "deflection_error_pct": "{:.1f}",
    "ghost_difference": "{:.3f}",
}


def _table(points: list[dict], axis: str, fixed: dict, label: str) -> list[str]:
    rows = sorted(
        {(p[axis], p["model"]) for p in points if all(p[k] == v for k, v in fixed.items())},
        key=lambda t: (t[0], [m for m, _ in MODELS].index(t[1]) if t[1] in dict(MODELS) else 9),
    )
    out = [
        f"| {label} | model | seeds | " + " | ".join(n for _, n in METRICS) + " | ms per step | best step |",
        "|---" * (len(METRICS) + 5) + "|",
    ]
    for x, model in rows:
        got = sorted(
            (p for p in points if p[axis] == x and p["model"] == model and all(p[k] == v for k, v in fixed.items())),
            key=lambda p: p["seed"],
        )
        cells = [_cell([p["errors"][k] for p in got], FORMATS[k]) for k, _ in METRICS]
        ms = float(np.mean([p["train_ms_per_step"] for p in got]))
        best = " / ".join(str(p["checkpoint_step"]) for p in got)
        out.append(
            f"| {x:,} | {dict(MODELS).get(model, model)} | {len(got)} | "
            + " | ".join(cells)
            + f" | {ms:.0f} | {best} |"
        )
    return out + [""]


def _fits(points: list[dict], axis: str, fixed: dict, target: int, what: str, unit: str) -> list[str]:
    """Per model and metric: the fitted exponent, R², and the law's value at ``target`` (an extrapolation)."""
    largest = max(p[axis] for p in points if all(p[k] == v for k, v in fixed.items()))
    out = [
        f"| model | error | points ({unit}) | k in error ∝ {what}^-k | R² | at the paper's {target:,} "
        f"{unit} (extrapolated {target / largest:,.0f}× beyond the largest run) |",
        "|---|---|---|---|---|---|",
    ]
    for model, mname in MODELS:
        for key, label in METRICS:
            means = means_by(points, model, axis, key, fixed)
            fit = fit_power_law(list(means), list(means.values()))
            if fit is None:
                if means:
                    out.append(
                        f"| {mname} | {label} | {len(means)} | - | - | fewer than two {unit} with a positive "
                        "error: no fit |"
                    )
                continue
            at = extrapolate(fit, target)
            said = (
                FORMATS[key].format(at) + (" (loose fit)" if fit["r2"] < LOOSE else "")
                if fit["k"] > FALLS
                else "does not fall with " + what + ": no extrapolation"
            )
            out.append(f"| {mname} | {label} | {fit['points']} | {fit['k']:.3f} | {fit['r2']:.2f} | {said} |")
    return out + [""]


def _margins(points: list[dict], axis: str, fixed: dict, unit: str) -> list[str]:
    """Whether HCMT's margin over MGN grows along the axis, per metric, from the ratios the lines print."""
    out = []
    for key, label in METRICS:
        trend = margin_trend(means_by(points, "hcmt", axis, key, fixed), means_by(points, "mgn", axis, key, fixed))
        if trend is None:
            continue
        k, last = trend["fit"]["k"], list(trend["ratios"].values())[-1]
        lead = "HCMT ahead" if last < 1 else "MGN ahead"
        word = (
            "HCMT gains on MGN (its error falls faster)"
            if k > MARGIN_FLAT
            else "HCMT loses ground to MGN (MGN's error falls faster)"
            if k < -MARGIN_FLAT
            else "the margin stays about the same"
        )
        ratios = ", ".join(f"{r:.2f} at {x:,}" for x, r in trend["ratios"].items())
        out.append(
            f"- {label}: HCMT ÷ MGN {ratios} {unit} ({lead} at the largest); the ratio ∝ {unit}^{-k:+.3f}: {word}."
        )
    if out:
        out.append(
            f"- The rule: HCMT gains when the ratio falls along the axis faster than {unit}^-{MARGIN_FLAT}, "
            f"loses ground when it rises faster than {unit}^+{MARGIN_FLAT}; a ratio below 1 is HCMT ahead, "
            'so "HCMT\'s margin grows" is a gain while HCMT is ahead.'
        )
    return out + ([""] if out else [])


def _seed_spread(points: list[dict]) -> list[str]:
    """The largest ratio between the seeds of one point, per metric: how much of a difference along an axis the
    seed alone can make."""
    groups: dict = {}  # (model, budget, designs) -> its points, one per seed
    for p in points:
        groups.setdefault((p["model"], p["budget"], p["designs"]), []).append(p)
    out = []
    for key, label in METRICS:
        worst = None
        for (model, budget, _), got in groups.items():
            values = [p["errors"][key] for p in got if p["errors"][key] > 0]  # a ratio needs positive errors
            if len(values) > 1 and (worst is None or max(values) / min(values) > worst[0]):
                worst = (max(values) / min(values), model, budget)
        if worst:
            f, model, budget = worst
            out.append(f"{label} {f:.1f}× ({dict(MODELS).get(model, model)}, {budget:,} steps)")
    return (
        [
            sentences(
                "Seed to seed, one point's errors differ by up to: " + "; ".join(out) + ". A difference "
                "between budgets smaller than this is within what the seed alone moves."
            ),
            "",
        ]
        if out
        else []
    )


def _restored(pts: list[dict]) -> list[str]:
    """A sentence on the points taken from an earlier results file (``run.py --restore``), and whether the test
    designs they were judged on are the same data: the same median solver ghost ratio of the test split."""
    old = [p for p in pts if p.get("restored_from")]
    if not old:
        return []
    new = [p for p in pts if not p.get("restored_from")]
    ratios = {p.get("solver_ghost_ratio") for p in old}, {p.get("solver_ghost_ratio") for p in new}
    same = len(ratios[0] | ratios[1]) == 1 and None not in ratios[0]
    check = (
        f"the test split's median solver ghost ratio is {next(iter(ratios[0])):.10g} for every point, restored or not"
        if same and new
        else "the test designs could not be checked to be the same (their solver ghost ratios differ or are missing)"
    )
    return [
        f"{len(old)} of these points were judged in an earlier run of the study, whose work folder was lost, and "
        f"taken from its results file (`--restore {old[0]['restored_from']}`); the data were generated again by "
        f"the same command: {check}.",
        "",
    ]


def _long_run(long: dict, pts: list[dict], full: int) -> list[str]:
    """The long run's checkpoints (benchmarks/scaling/long_run.py) beside the study's budget axis, with what the
    study's HCMT fit (from :data:`MIN_FIT` budgets) gives at the same step."""
    rows = long["checkpoints"]
    first = rows[0]
    out = [
        f"**The long run's checkpoints** (`{long['command']}`: HCMT (and MGN where its row says so), the study's "
        f"recipe, {first['designs']} "
        f"training designs, judged on the same {first['trajectories']} test designs; its learning rate decays from "
        f"{first['lr']:g} to {first['lr_final']:g} over {first['schedule_steps']:,} steps, so a checkpoint at step "
        "n is not the study's n-step run, whose rate has fully decayed by n: these rows stand beside the fit, not "
        "in it)",
        "",
        "| run | checkpoint step | " + " | ".join(n for _, n in METRICS) + " | rebound agreement |",
        "|---" * (len(METRICS) + 3) + "|",
    ]
    fits = {}
    if len({p["budget"] for p in pts if p["designs"] == full and p["model"] == "hcmt"}) >= MIN_FIT:
        for key, _ in METRICS:
            means = means_by(pts, "hcmt", "budget", key, {"designs": full})
            fits[key] = fit_power_law(list(means), list(means.values()))
    for r in rows:
        cells = []
        for key, _ in METRICS:
            fit = fits.get(key) if model_of(r) == "hcmt" else None  # the study's fit is HCMT's
            at = (
                f" (fit: {FORMATS[key].format(extrapolate(fit, r['checkpoint_step']))})"
                if fit and fit["k"] > FALLS
                else ""
            )
            cells.append(FORMATS[key].format(r["errors"][key]) + at)
        out.append(
            f"| {run_of(r)} | {r['checkpoint_step']:,} | " + " | ".join(cells) + f" | {r['rebound_agreement']:.2f} |"
        )
    return out + [""]


def model_of(row: dict) -> str:
    """The model a long-run row judged (rows written before long_run.py recorded it are HCMT's)."""
    return row.get("model", "hcmt")


def long_run_ratios(rows: list[dict]) -> list[dict]:
    """HCMT ÷ MGN position and stress RMSE-all at each checkpoint step where both have a test-split row (the same
    recipe, data and schedule: a matched budget), one entry per HCMT run: ``{step, run, mgn_run, position,
    stress}``."""
    mgn = {r["checkpoint_step"]: r for r in rows if model_of(r) == "mgn"}
    return [
        {
            "step": r["checkpoint_step"],
            "run": run_of(r),
            "mgn_run": run_of(mgn[r["checkpoint_step"]]),
            **{
                q: r["errors"][f"{q}_rmse_all"] / mgn[r["checkpoint_step"]]["errors"][f"{q}_rmse_all"]
                for q in ("position", "stress")
            },
        }
        for r in rows
        if model_of(r) == "hcmt" and r["checkpoint_step"] in mgn
    ]


def _long_run_ratio(rows: list[dict]) -> list[str]:
    """HCMT against MGN at the long schedule's matched checkpoints, beside the paper's Table 2 ratio."""
    ratios = long_run_ratios(rows)
    if not ratios:
        return []
    out = [
        "**HCMT against MGN on the long schedule** (the same recipe, 480 designs and 400,000-step schedule; MGN "
        "judged at its kept checkpoints like HCMT; a ratio below 1: HCMT ahead; the paper's Table 2: "
        f"{PAPER_RATIO['position']} / {PAPER_RATIO['stress']} after 10,000,000 steps)",
        "",
        "| checkpoint step | HCMT run | HCMT ÷ MGN position RMSE-all | HCMT ÷ MGN stress RMSE-all |",
        "|---|---|---|---|",
    ]
    out += [f"| {r['step']:,} | {r['run']} | {r['position']:.2f} | {r['stress']:.2f} |" for r in ratios]
    last = max(r["step"] for r in ratios)
    at = [r for r in ratios if r["step"] == last]
    out += [
        "",
        sentences(
            f"At the largest matched step ({last:,} of the 400,000-step schedule, its learning rate not yet "
            "decayed to the end) HCMT ÷ MGN is "
            + " and ".join(f"{r['position']:.2f} / {r['stress']:.2f} ({r['run']})" for r in at)
            + "; one checkpoint of each model, whose validation error still swings from one kept checkpoint to the "
            "next, so read it against the table above, not as the converged ratio."
        ),
        "",
    ]
    return out


def _long_run_outside(rows: list[dict]) -> list[str]:
    """The long run's checkpoints on designs outside the training ranges (long_run.py --split), against the model
    goals outside the ranges (the judge's: peak plate stress ≤ 6 %, deflection ≤ 8 %, medians)."""
    label = dict(METRICS)
    out = [
        f"**The long run's checkpoints outside the training ranges** (`python benchmarks/scaling/long_run.py "
        "SNAPSHOT --data $HCMT_WORK/data/ip480 --checkpoint step_N --label RUN --split "
        f"{rows[0]['split'].replace(' + ', ' ')}`: "
        f"the {rows[0]['trajectories']} designs of those splits pooled, medians over them; the model goals "
        "there: " + ", ".join(f"{label[k]} ≤ {g:g}" for k, g in OUTSIDE_GOALS.items()) + ")",
        "",
        "| run | checkpoint step | splits | " + " | ".join(n for _, n in METRICS) + " | rebound agreement |",
        "|---" * (len(METRICS) + 4) + "|",
    ]
    for r in rows:
        out.append(
            f"| {run_of(r)} | {r['checkpoint_step']:,} | {r['split']} | "
            + " | ".join(FORMATS[k].format(r["errors"][k]) for k, _ in METRICS)
            + f" | {r['rebound_agreement']:.2f} |"
        )
    said = []
    for key, goal in OUTSIDE_GOALS.items():
        met = [r for r in rows if r["errors"][key] <= goal]
        best = min(rows, key=lambda r: r["errors"][key])
        said.append(
            f"{label[key]} ≤ {goal:g}: met at {len(met)} of {len(rows)} checkpoints; the lowest, "
            f"{FORMATS[key].format(best['errors'][key])}, at step {best['checkpoint_step']:,}."
        )
    return out + ["", sentences(*said), ""]


def _long_run_sweeps(sw: dict) -> list[str]:
    """The long run's kept checkpoints on the judge's sweeps (long_run_sweeps.py): the two model goals
    that a median error does not measure, the model alone's limit calls and the trends' size, against the budget."""
    rows = sw["rows"]
    height = rows[0]["trends"]["sweep_height"]["peak_plate_stress_mpa"]["solver"]
    out = [
        f"**The long run's checkpoints on the judge's sweeps** (`{sw['command']}`: the sweeps of "
        f"`{sw['judge']['command']}`, whose solver runs they are judged against; the model alone passes a point the "
        "solver fails where its peak is below the sweep's yield stress and the solver's is not; a trend agrees "
        "where its sign is the solver's and its size within 30 %)",
        "",
        f"| checkpoint step | model alone: unsafe passes of {rows[0]['points']} points | trends that agree, of "
        f"{rows[0]['trends_of']} | drop-height trend of the peak (the solver: {100 * height:+.1f} %) |",
        "|---|---|---|---|",
    ]
    for r in rows:
        t = r["trends"]["sweep_height"]["peak_plate_stress_mpa"]["hcmt"]
        out.append(f"| {r['checkpoint_step']:,} | {r['unsafe']} | {r['trends_agree']} | {100 * t:+.1f} % |")
    both = [r for r in rows if r["unsafe"] == 0 and r["trends_agree"] == r["trends_of"]]
    said = [
        f"Both goals (no unsafe pass, every trend) are met at {len(both)} of {len(rows)} kept checkpoints"
        + (": " + ", ".join(f"{r['checkpoint_step']:,}" for r in both) if both else "")
        + "."
    ]
    mine = [r for r in rows if "judge_peak_max_rel_diff" in r]
    if mine:
        said.append(
            f"At the judge's own step ({mine[0]['checkpoint_step']:,}) the peaks are within "
            f"{100 * mine[0]['judge_peak_max_rel_diff']:.2f} % of the judge's (fp32 checkpoint against the "
            "shipped fp16 file)."
        )
    return out + ["", sentences(*said), ""]


def _shipped(judge: dict) -> bool:
    """A judge's result file of the shipped model (``--model pretrained:NAME``), not of a run's checkpoint."""
    return judge["model"].startswith("pretrained:")


def _long_run_judges(judges: list[dict]) -> list[str]:
    """The model goals, all of them, at several checkpoints of the long run on the judge's designs (its seeds):
    the shipped one's model_judge.json and scaling_judge_step*.json (``surrogate/run.py --checkpoint step_N
    --solver-from``), a column each."""
    judges = sorted(judges, key=lambda j: j["checkpoint_step"])
    cols = [f"step {j['checkpoint_step']:,}" + (" (shipped, fp16)" if _shipped(j) else "") for j in judges]
    seeds = {(j["seeds"]["in_range"], j["seeds"]["outside"]) for j in judges}
    out = [
        "**The judge's goals at other checkpoints of the long run** (the judge's designs, seeds "
        + "; ".join(f"{a} and {b}" for a, b in sorted(seeds))
        + "; the other checkpoints' commands: "
        + "; ".join(f"`{j['command']}`" for j in judges if not _shipped(j))
        + "; a missed goal in bold)",
        "",
        "| goal | target | " + " | ".join(cols) + " |",
        "|---|---|" + "---|" * len(cols),
    ]
    for k, g in enumerate(judges[0]["goals"]):
        cells = []
        for j in judges:
            row = j["goals"][k]
            v = f"{row['hcmt']:.3g}" if isinstance(row["hcmt"], float) else f"{row['hcmt']}"
            cells.append(v if row["hcmt_met"] else f"**{v}**")
        out.append(f"| {g['goal']} | {'≥' if g['at_least'] else '≤'} {g['target']:g} | " + " | ".join(cells) + " |")
    met = [sum(r["hcmt_met"] for r in j["goals"]) for j in judges]
    best = max(range(len(judges)), key=lambda i: met[i])
    never = [g["goal"] for k, g in enumerate(judges[0]["goals"]) if not any(j["goals"][k]["hcmt_met"] for j in judges)]
    said = [
        f"The most goals met at one checkpoint: {met[best]} of {len(judges[0]['goals'])}, at step "
        f"{judges[best]['checkpoint_step']:,}.",
        (
            "Met at none of these checkpoints: " + "; ".join(never) + "."
            if never
            else "Every goal is met at one checkpoint or another."
        ),
        "These designs judged the shipped checkpoint, chosen on the validation split before they were drawn; a "
        "checkpoint chosen by them would be judged again on designs of seeds not yet used.",
    ]
    said += _judged_budget(judges)
    return out + ["", sentences(*said), ""]


def _judged_budget(judges: list[dict]) -> list[str]:
    """For each goal the shipped checkpoint misses: an error (a median or worst %), the power law of the error against
    the checkpoint's step over the judged checkpoints and the step where it would reach the goal; a count (trends,
    unsafe passes), the judged steps where it is met, or its value at each."""
    shipped = next((j for j in judges if _shipped(j)), None)
    if shipped is None or len(judges) < MIN_FIT:
        return []
    said = []
    last = max(j["checkpoint_step"] for j in judges)
    for k, g in enumerate(shipped["goals"]):
        if g["hcmt_met"]:
            continue
        steps, values = [j["checkpoint_step"] for j in judges], [j["goals"][k]["hcmt"] for j in judges]
        if g["at_least"] or "%" not in g["goal"]:  # a count: where it is met, or how it went
            met = [f"{j['checkpoint_step']:,}" for j in judges if j["goals"][k]["hcmt_met"]]
            said.append(
                f'"{g["goal"]}" is met at step{"s" * (len(met) > 1)} {", ".join(met)} of these, not at '
                f"the shipped {shipped['checkpoint_step']:,}."
                if met
                else f'"{g["goal"]}" is met at none of these: '
                + ", ".join(f"{v:g} at {s:,}" for s, v in zip(steps, values))
                + "."
            )
            continue
        fit = fit_power_law(steps, values)
        at = reaches(fit, g["target"])
        law = (
            f'Fitted to the step, "{g["goal"]}" ({len(judges)} checkpoints, {min(values):.2f}-{max(values):.2f}) '
            f"∝ step^{-fit['k']:.2f}, R² {fit['r2']:.2f}" + (", a loose fit" if fit["r2"] < LOOSE else "")
        )
        said.append(
            law
            + (
                f"; it would reach {g['target']:g} at about {at:.2g} steps ({at / last:.1f}× the run's "
                f"last judged step) if that law holds, an extrapolation."
                if at is not None
                else "; it does not fall with the step: no budget along this run reaches it."
            )
        )
    return said


def _goal_budgets(long: dict | None, pts: list[dict], full: int) -> list[str]:
    """The budget at which the study's HCMT fit against the budget reaches each goal, and beside it
    what the long run's latest run reached at its kept checkpoints (where it did better than the fit, by how much)."""
    means = {key: means_by(pts, "hcmt", "budget", key, {"designs": full}) for key in MODEL_GOALS}
    fits = {key: fit_power_law(list(m), list(m.values())) for key, m in means.items()}
    hcmt = [r for r in (long or {}).get("checkpoints", []) if model_of(r) == "hcmt"]  # the fit is HCMT's
    rows = [r for r in hcmt if run_of(r) == run_of(hcmt[-1])] if hcmt else []
    name = run_of(rows[-1]) if rows else None
    out = [
        "**What budget would reach the goals** (the model goals: the median errors on held-out designs; the study's "
        "HCMT fit against the budget above, solved for the goal"
        + (f"; beside it the long run's {name} at its kept checkpoints" if rows else "")
        + ")",
        "",
        "| goal | target | the study's fit reaches it at | × the paper's steps | R² |"
        + (
            f" long run ({name}): kept checkpoints that meet it | its best (step) | fit ÷ long run at that step |"
            if rows
            else ""
        ),
        "|---|---|---|---|---|" + ("---|---|---|" if rows else ""),
    ]
    label = dict(METRICS)
    below = []
    for key, goal in MODEL_GOALS.items():
        fit = fits[key]
        at = reaches(fit, goal)
        cells = (
            [f"{at:,.3g} steps", f"{at / PAPER_STEPS:,.3g}", f"{fit['r2']:.2f}"]
            if at is not None
            else ["does not fall with steps", "-", f"{fit['r2']:.2f}" if fit else "-"]
        )
        line = f"| {label[key]} | ≤ {goal:g} | " + " | ".join(cells) + " |"
        if rows:
            met = [r for r in rows if r["errors"][key] <= goal]
            best = min(rows, key=lambda r: r["errors"][key])
            ratio = (
                extrapolate(fit, best["checkpoint_step"]) / best["errors"][key]
                if fit and fit["k"] > FALLS and best["errors"][key] > 0
                else None
            )
            if ratio is not None:
                below.append(ratio)
            steps = ", ".join(f"{r['checkpoint_step']:,}" for r in met)
            line += (
                f" {len(met)} of {len(rows)}"
                + (f" ({steps})" if met else "")
                + f" | {FORMATS[key].format(best['errors'][key])} ({best['checkpoint_step']:,}) | "
                + (f"{ratio:.1f}×" if ratio is not None else "-")
                + " |"
            )
        out.append(line)
    out.append("")
    said = [
        "The fit's budgets come from runs of at most "
        f"{max(p['budget'] for p in pts if p['designs'] == full):,} steps, each with its learning rate decayed "
        "to the end within its budget; a budget far beyond them is an extrapolation of a loose fit."
    ]
    if below:
        said.append(
            f"The long run's best checkpoints lie {min(below):.1f}-{max(below):.1f}× below what the fit gives "
            "at the same step: the short runs' law is pessimistic for a long run, so its budgets are an upper "
            "bound on what the goals need, not a forecast; the long run's own kept checkpoints are the "
            "measured answer."
        )
    return out + [sentences(*said), ""]


def scaling(
    lines: list[str],
    r: dict | None,
    long: dict | None = None,
    sweeps: dict | None = None,
    judges: list[dict] | None = None,
) -> None:
    lines += [HEADING, ""]
    if not r or not r.get("points"):
        lines += [
            sentences(
                "**Not run yet**: no point of the study has been trained and judged, so this section has no numbers.",
                "The data and the command (benchmarks/scaling/README.md has the cost):",
            ),
            "",
            "```bash",
            DATA,
            COMMAND,
            "```",
            "",
        ]
        if r:
            lines += [f"`{r['command']}` planned {r['planned']} points; none is finished.", ""]
        return
    pts = r["points"]
    partial = r["done"] < r["planned"]
    lines += [
        "```bash",
        r["command"],
        "```",
        "",
        sentences(
            f"Data: `{r['data']}` ({r['train_designs_in_data']} training designs; the first N of them "
            "for a design count N); judged on its held-out test designs "
            f"({pts[0]['trajectories']} per point). Device: {r['device']}.",
            f"**Partial: {r['done']} of {r['planned']} planned points run so far**; every fit below uses only them."
            if partial
            else f"All {r['planned']} planned points ran.",
            "Errors: position and stress RMSE-all ×10⁻³ (the paper's metric, mean over trajectories); "
            "medians over trajectories of |peak plate stress error|, |max deflection error| and the ghost "
            "difference |model ghost ratio − solver ghost ratio|.",
        ),
        "",
    ]
    lines += [
        "Points run: "
        + ", ".join(f"{p['model']} {p['budget']:,} steps / {p['designs']} designs / seed {p['seed']}" for p in pts)
        + ".",
        "",
    ]
    lines += _restored(pts)
    full = max(r["designs"])
    lines += [f"**Against the training budget** ({full} training designs)", ""]
    lines += _table(pts, "budget", {"designs": full}, "steps")
    lines += _seed_spread(pts)
    budgets = len({p["budget"] for p in pts if p["designs"] == full})
    if budgets < MIN_FIT:
        lines += [
            sentences(
                f"{budgets} budget(s) run so far: no power law is fitted and nothing is extrapolated "
                f"until {MIN_FIT} are (through two points any line fits, R² 1 by construction)."
            ),
            "",
        ]
    else:
        lines += _fits(pts, "budget", {"designs": full}, PAPER_STEPS, "steps", "steps")
        lines += [
            sentences(
                f"The last column is **an extrapolation**: the fitted law carried to the paper's "
                f"{PAPER_STEPS:,} steps, far beyond anything run here; it holds only if the trend does."
            ),
            "",
        ]
        lines += _margins(pts, "budget", {"designs": full}, "steps")
    outside = [r for r in (long or {}).get("checkpoints", []) if "split" in r]
    if long:  # the test split's rows (the study's designs); rows of other splits have a table of their own
        long = {**long, "checkpoints": [r for r in long.get("checkpoints", []) if "split" not in r]}
    if long and long.get("checkpoints"):
        lines += _long_run(long, pts, full)
        lines += _long_run_ratio(long["checkpoints"])
    if outside:
        lines += _long_run_outside(outside)
    if sweeps and sweeps.get("rows"):
        lines += _long_run_sweeps(sweeps)
    if judges and len(judges) > 1:
        lines += _long_run_judges(judges)
    if budgets >= MIN_FIT:
        lines += _goal_budgets(long, pts, full)
    axis = [p for p in pts if p["budget"] == r["designs_budget"]]
    if axis:
        lines += [f"**Against the number of training designs** ({r['designs_budget']:,} steps)", ""]
        lines += _table(pts, "designs", {"budget": r["designs_budget"]}, "designs")
        counts = len({p["designs"] for p in axis})
        if counts < MIN_FIT:
            lines += [
                sentences(f"{counts} design count(s) run so far: no power law is fitted until {MIN_FIT} are."),
                "",
            ]
        else:
            lines += _fits(pts, "designs", {"budget": r["designs_budget"]}, PAPER_TRAJECTORIES, "designs", "designs")
            lines += _margins(pts, "designs", {"budget": r["designs_budget"]}, "designs")


def main() -> None:
    from common import RESULTS

    path = Path(sys.argv[1]) if len(sys.argv) > 1 else RESULTS / "scaling.json"
    lines: list[str] = []
    scaling(lines, json.loads(path.read_text()) if path.is_file() else None)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
