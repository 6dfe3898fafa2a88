"""The measured part of a shipped model's card in docs/MODELS.md, written by ``python benchmarks/report.py`` with
docs/RESULTS.md, so the card quotes only what a committed command produced and follows a new model by itself.

docs/MODELS.md keeps the hand-written parts of a card (what the model is, its recipe, what to trust it for). Between

    <!-- card NAME: ... -->  and  <!-- /card NAME -->

every number comes from the result files:

* ``model_NAME.json`` (benchmarks/release/ship_model.py): how it was made, the held-out designs of a fresh seed, the
  sweeps, the measured error by region, the test split, the speed;
* ``model_judge.json`` (benchmarks/surrogate/run.py ``--seed-in/--seed-out``): the model goals, where it judged
  *this* model (the same name, training designs and checkpoint step; else the block says which model it judged);
* ``surrogate.json`` (benchmarks/surrogate/run.py): this model beside the response surface on the card's designs,
  where it measured this model;
* ``trust.json`` (benchmarks/trust/run.py): the mesh model's own interval, its coverage and width by region, where
  it measured this model.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from hcmt.design.sweep import TREND_SIZE, trends_agree
from report_common import command, load
from surrogate.report import COMMAND, accuracy_table
from trust.report import COMMAND as TRUST_COMMAND, coverage_table, seeds_text

DOC = Path(__file__).resolve().parent.parent.parent / "docs" / "MODELS.md"


def begin(name: str) -> str:
    return (
        f"<!-- card {name}: written by python benchmarks/report.py from benchmarks/results/model_{name}.json, "
        "model_judge.json, surrogate.json and trust.json; edit those, not this block -->"
    )


def end(name: str) -> str:
    return f"<!-- /card {name} -->"


def measured_this(result: dict | None, name: str, model: dict) -> bool:
    """Whether a design-check result (surrogate.json, model_judge.json) measured this shipped model: the same name,
    the same number of training designs and, where the result records it, the same checkpoint step."""
    if not result or result.get("model") != f"pretrained:{name}":
        return False
    card = model["card"]
    step = result.get("checkpoint_step")
    same_step = step is None or step == card["checkpoint"]["step"]
    return result.get("training_designs") == training_designs(card) and same_step


def training_designs(card: dict) -> int:
    """The card's number of training designs (ship_model.py records it; files written before, only in the summary)."""
    if "training_designs" in card:
        return int(card["training_designs"])
    return int(re.search(r" on (\d+) generated", card["summary"]).group(1))


def _made(m: dict) -> list[str]:
    c = m["card"]
    wall = c["train_wall_s_from_log"]
    took = f"{wall / 3600:.1f} h" if wall >= 7200 else f"{wall / 60:.0f} minutes"
    return [
        f"**How it was made**: {c['summary']}, on {c['device']} ({c['machine']}, torch {c['torch']}, seed "
        f"{c['seed']}): {c['steps']:,} steps at {c['train_ms_per_step']:.0f} ms a step (median), about "
        f"{took} of training by the log; shipped: `{c['checkpoint']['file']}`, "
        f"the weights of step {c['checkpoint']['step']:,}. Packaged by `{command(m)}`.",
        "",
        "```bash",
        c["data_command"],
        c["train_command"],
        "```",
        "",
    ]


def _pct(block: dict) -> str:
    return f"{block['median_abs']:.1f} % / {abs(block['worst']):.1f} %"


def _limit(lim: dict) -> str:
    model, solver = lim["model"], lim["solver"]
    said = {"none pass": "none passes"}
    word = "unsafe" if lim["unsafe"] else "within one sweep step" if lim["within_one_step"] else "safe side"
    return (
        f"{said.get(model['side'], model['call'])} (model) against {said.get(solver['side'], solver['call'])} "
        f"(solver): {word}"
    )


def _trend_word(model: float, solver: float) -> str:
    """Whether a sweep's trend agrees with the solver's, by the one rule (:func:`hcmt.design.sweep.trends_agree`)."""
    if trends_agree(model, solver):
        return "agrees"
    if np.sign(model) != np.sign(solver):
        return "sign wrong: a miss"
    return (
        f"sign right, size {100 * abs(model / solver - 1):.0f} % off: a miss, the rule being within "
        f"{100 * TREND_SIZE:g} %"
    )


def _fresh(m: dict) -> list[str]:
    v, p = m["verify"], m["verify"]["physics"]
    n = v["designs"]
    seed = m["card"]["verify_designs"]["seed"]
    out = [
        f"**On {n} held-out designs of a fresh seed** (`--design-seed {seed}`, uniform "
        "inside the training ranges; the shipped fp16 file predicts each design from its parameters, the solver "
        "simulates it again):",
        "",
        "| quantity | measured |",
        "|---|---|",
        f"| rebound agreement | {round(p['rebound_agreement'] * n)} / {n} (the solver: {p['solver_rebounds']} "
        "rebounds) |",
        f"| peak plate stress error, median / worst | {_pct(p['peak_plate_stress_error_pct'])} |",
        f"| max deflection error, median / worst | {_pct(p['max_deflection_error_pct'])} |",
        f"| where the plate's peak is, median / worst | {v['peak_plate_location_error_mm']['median']:.2f} / "
        f"{v['peak_plate_location_error_mm']['max']:.2f} mm |",
        f"| time of the plate's peak, median frames off | {p['peak_plate_frame_error']['median_abs']:.1f} |",
        f"| far-field deflection error (r > R/2), median | {p['far_deflection_error_um']['median']:.1f} µm |",
    ]
    for sweep, s in m["sweeps"].items():
        lim = s["limit"]
        for q, label in (("peak_plate_stress_mpa", "peak plate stress"), ("max_deflection_mm", "max deflection")):
            t = s["trend"][q]
            out.append(
                f"| sweep {sweep} at {', '.join(s['design'])}: {label} | {t['model']['change_pct']:+.1f} % "
                f"(the solver: {t['solver']['change_pct']:+.1f} %; "
                f"{_trend_word(t['model']['change_pct'], t['solver']['change_pct'])}) |"
            )
        side = "minimum" if lim["solver"]["side"] == "minimum" else "maximum"
        out.append(f"| sweep {sweep}: {side} {s['param']} with a peak below {lim['yield_mpa']:g} MPa | {_limit(lim)} |")
    return out + [""]


def _regions(m: dict) -> list[str]:
    rows = m["card"]["confidence"]
    out = [
        "**Measured error by region** (the card's `confidence`, the same designs with the fp32 checkpoint; regions "
        "are fifths of the training ranges, `hcmt.design.inputs.region_of`):",
        "",
        "| region | designs | peak plate stress error, median / worst | max deflection error, median |",
        "|---|---|---|---|",
    ]
    for r in rows:
        out.append(
            f"| {r['label']} | {r['designs']} | {r['peak_plate_stress_error_pct_median']:.1f} % / "
            f"{r['peak_plate_stress_error_pct_worst']:+.1f} % | {r['max_deflection_error_pct_median']:.1f} % |"
        )
    weak = max(rows, key=lambda r: r["peak_plate_stress_error_pct_median"])
    return out + [
        "",
        f'The largest median peak plate stress error is in the region "{weak["label"]}": '
        f"{weak['peak_plate_stress_error_pct_median']:.1f} % over {weak['designs']} designs.",
        "",
    ]


def _test_and_speed(m: dict) -> list[str]:
    t, p = m["test_metrics"], m["test_metrics"]["physics"]
    return [
        f"**Test split** (the dataset's {t['trajectories']} test designs, fp32 checkpoint, the paper's metrics "
        f"×10³): position RMSE-1 {t['position']['rmse_1']:.2f}, RMSE-all {t['position']['rmse_all']:.1f}, stress "
        f"RMSE-all {t['stress']['rmse_all']:,.0f}; rebound {p['model_rebounds']} / {t['trajectories']} (the "
        f"solver: {p['solver_rebounds']}), peak plate stress error {_pct(p['peak_plate_stress_error_pct'])} "
        f"(median / worst), deflection {_pct(p['max_deflection_error_pct'])}, time of the peak "
        f"{p['peak_plate_frame_error']['median_abs']:.0f} frames.",
        "",
        f"**Speed** ({m['device']}): one design alone {m['single_design_wall_s']:.2f} s, the solver "
        f"{m['solver_wall_s_median']:.2f} s median; in batches of {m['batch']} on {m['threads']} thread(s), "
        f"{m['verify']['speedup']['median']:.2f}× the solver (`speedup`: the solver's wall time ÷ the "
        f"prediction's per design, median; {_solver_how(m['verify'])}).",
        "",
    ]


def _solver_how(verify: dict) -> str:
    """How the card's solver ran: as its verify block says, or, for a block written before it said so, the check's
    solver of that time, which recorded between-frame peaks the comparison did not read."""
    said = (verify.get("speedup_measured") or {}).get("solver")
    return said or (
        "the solver recorded between-frame peaks, as the check's solver did until 87498c4, which the comparison did "
        "not read: slower than `hcmt simulate`, so this speedup is high"
    )


def _judged(name: str, m: dict, judge: dict | None) -> list[str]:
    if not measured_this(judge, name, m):
        if not judge:
            return ["**Against the model goals**: not judged (no model_judge.json).", ""]
        return [
            f"**Against the model goals**: this model is not judged; model_judge.json judged "
            f"`{judge['model']}` (step {judge['checkpoint_step']:,}, {judge['training_designs']} training "
            'designs), docs/RESULTS.md "The mesh model judged against the model goals".',
            "",
        ]
    goals = judge["goals"]
    met = sum(g["hcmt_met"] for g in goals)
    out = [
        f"**Against the model goals** (`{command(judge)}`: designs of seeds {judge['seeds']['in_range']} in range "
        f"and {judge['seeds']['outside']} outside, which no study used; the response surface fitted on the same "
        f"{judge['training_designs']} runs): it meets {met} of {len(goals)}.",
        "",
        "| goal | target | this model | met | response surface |",
        "|---|---|---|---|---|",
    ]
    for g in goals:
        sign = "≥" if g["at_least"] else "≤"
        gp = "-" if g["gp"] is None else f"{g['gp']:.3g}"
        out.append(
            f"| {g['goal']} | {sign} {g['target']:g} | {g['hcmt']:.3g} | {'yes' if g['hcmt_met'] else 'no'} | {gp} |"
        )
    return out + [""]


def _beside(name: str, m: dict, surrogate: dict | None) -> list[str]:
    if not measured_this(surrogate, name, m):
        what = f"`{surrogate['model']}` on {surrogate['training_designs']} training designs" if surrogate else "nothing"
        return [f"**Beside the response surface**: not measured for this model (surrogate.json measured {what}).", ""]
    run = command(surrogate) if surrogate.get("command") else COMMAND
    return [
        f"**Beside the response surface on the card's designs** (`{run}`; docs/RESULTS.md \"The "
        'design check against a response surface" has the calls, the ghost stress and the note):',
        "",
        *accuracy_table(surrogate),
        "",
    ]


def _interval(name: str, trust: dict | None) -> list[str]:
    """The mesh model's own interval by region, where trust.json measured this model (pretrained:NAME)."""
    if not trust or trust.get("model") != f"pretrained:{name}":
        return [f"**The mesh model's own interval**: not measured for this model (`{TRUST_COMMAND}` writes it).", ""]
    pooled = trust["coverage"]["pooled"]
    return [
        f"**The mesh model's own {100 * trust['level']:.0f} % interval** (`{command(trust)}`: calibrated on "
        f"{trust['designs']['calibration']} solver runs of seed(s) {seeds_text(trust['seeds']['calibration'])}, "
        "measured on "
        f"{trust['designs']['evaluation']} designs of seed(s) "
        + ", ".join(str(x) for x in trust["seeds"]["evaluation"])
        + '; docs/RESULTS.md "The mesh model\'s own interval" has the calls and the fuzzer):',
        "",
        *coverage_table(pooled),
        "",
    ]


def card(name: str, m: dict, judge: dict | None, surrogate: dict | None, trust: dict | None = None) -> list[str]:
    """The block's lines, markers included."""
    return [
        begin(name),
        *_made(m),
        *_fresh(m),
        *_regions(m),
        *_test_and_speed(m),
        *_judged(name, m, judge),
        *_beside(name, m, surrogate),
        *_interval(name, trust),
        end(name),
    ]


def write_cards(doc: Path = DOC) -> list[str]:
    """Rewrite every card block docs/MODELS.md holds (a block whose model has no result file is left as it is);
    the names written."""
    text = doc.read_text()
    written = []
    for line in text.splitlines():
        if not line.startswith("<!-- card "):
            continue
        name = line.split()[2].rstrip(":")
        m = load(f"model_{name}.json")
        if m is None or end(name) not in text:
            continue
        head, rest = text.split(line, 1)
        tail = rest.split(end(name), 1)[1]
        text = (
            head + "\n".join(card(name, m, load("model_judge.json"), load("surrogate.json"), load("trust.json"))) + tail
        )
        written.append(name)
    doc.write_text(text)
    return written
