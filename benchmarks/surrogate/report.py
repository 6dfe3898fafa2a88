"""docs/RESULTS.md's section "The design check against a response surface", from benchmarks/results/surrogate.json
(``python benchmarks/surrogate/run.py``). Every verdict below is computed from the numbers it prints."""

from __future__ import annotations

from hcmt.design.check import TRUST
from hcmt.sim.params import Design
from report_common import load, said, sentences

COMMAND = (
    "python benchmarks/surrogate/run.py --data $HCMT_WORK/data/ip480 --work $HCMT_WORK/finish/surrogate "
    "--threads 1   # the shipped model's training data (docs/MODELS.md)"
)
SETS = {
    "in_range": "30 in range",
    "thicker": "6 thicker (1.03-1.2 mm)",
    "higher": "6 higher (1030-1200 mm)",
    "both": "4 thicker and higher",
}
QUANTITY = {
    "peak_plate_stress_mpa": "peak plate stress",
    "max_deflection_mm": "max deflection",
    "peak_ball_stress_mpa": "peak ball stress",
}
METHODS = (("hcmt", "HCMT (shipped)"), ("gp", "Gaussian process"), ("quadratic", "quadratic RS"))
GHOST_GOAL = 0.10
COVERAGE_GOAL = 0.90
NOTE_GOAL = 0.80
OUTSIDE = [k for k in SETS if k != "in_range"]  # the held-out designs outside the training ranges, by name
NO_CANDIDATE = 10.0  # a read-out whose median peak error is this many times the default's is no candidate
POSITION_ERROR_MM = 1e-3  # a micrometre
BOUND_WORDS = {"lo": "lower 95 % bound", "mean": "mean", "hi": "upper 95 % bound"}
READOUT = (
    "The contact read-out (`--readout contact`, reported as `contact_*`): the response surface predicts when "
    "the solver's ball leaves (`contact_end_ms`); its {bound} ends the window (`CONTACT_END_BOUND`). After it, "
    "the plate's stress is its free-vibration bending stress `k E t w_max / R²` from the predicted deflection "
    "(hcmt.design.readout)."
)


def _err(v: dict | None) -> str:
    return "-" if v is None else f"{v['median_abs_pct']:.1f} % / {v['worst_abs_pct']:.1f} %"


def _cov(v: dict | None) -> str:
    return "-" if v is None or "covered" not in v else f"{v['covered']} / {v['of']}"


def accuracy_table(r: dict) -> list[str]:
    lines = [
        "| designs | quantity | "
        + " | ".join(f"{label}: median / worst error" for _, label in METHODS)
        + " | GP 95 % covers | quadratic 95 % covers |",
        "|---" * (len(METHODS) + 4) + "|",
    ]
    for key, label in SETS.items():
        for q, name in QUANTITY.items():
            row = r["accuracy"][key][q]
            lines.append(
                f"| {label} | {name} | "
                + " | ".join(_err(row.get(m)) for m, _ in METHODS)
                + f" | {_cov(row.get('gp'))} | {_cov(row.get('quadratic'))} |"
            )
    return lines


def curve_table(r: dict) -> list[str]:
    lines = [
        "| training designs | GP peak plate stress, median / worst | GP deflection | quadratic peak plate "
        "stress | GP 95 % covers (peak) | union with HCMT covers |",
        "|---|---|---|---|---|---|",
    ]
    for n, c in r["learning_curve"].items():
        q = c["peak_plate_stress_mpa"]
        quadratic = _err(q.get("quadratic")) if q.get("quadratic") else f"cannot fit ({r['quadratic_terms']} terms)"
        lines.append(
            f"| {n} | {_err(q.get('gp'))} | {_err(c['max_deflection_mm'].get('gp'))} | "
            f"{quadratic}"
            f" | {c['trusted_coverage']['surrogate']['covered']} / 30 | "
            f"{c['trusted_coverage']['union']['covered']} / 30 |"
        )
    return lines


def sweeps_table(r: dict) -> tuple[list[str], dict]:
    lines = [
        "| sweep (thickness 0.5 → 1.0 mm, 11 points) | solver's minimum | HCMT alone: minimum, unsafe points | "
        "GP interval: minimum, unsafe, solver runs | union: minimum, unsafe, solver runs | ±60 % band: solver "
        "runs |",
        "|---|---|---|---|---|---|",
    ]
    totals = {t: {"unsafe": 0, "solver_runs": 0} for t in ("surrogate", "union", "model")}
    totals["model_alone"] = {"unsafe": 0}

    def fmt(v):
        return "none passes" if v is None else f"{v:g} mm"

    for name, s in r["sweeps"].items():
        for t in ("surrogate", "union", "model"):
            for k in ("unsafe", "solver_runs"):
                totals[t][k] += s[t][k]
        totals["model_alone"]["unsafe"] += s["model_alone"]["unsafe"]
        lines.append(
            f"| {name} | {fmt(s['solver_minimum'])} | {fmt(s['model_alone']['minimum'])}, "
            f"{s['model_alone']['unsafe']} | {fmt(s['surrogate']['minimum'])}, {s['surrogate']['unsafe']}, "
            f"{s['surrogate']['solver_runs']} | {fmt(s['union']['minimum'])}, {s['union']['unsafe']}, "
            f"{s['union']['solver_runs']} | {s['model']['solver_runs']} |"
        )
    return lines, totals


def surrogate(lines: list[str], r: dict | None) -> None:
    lines += ["## The design check against a response surface", ""]
    if r is None:
        lines += ["Not run yet: `" + COMMAND + "`.", ""]
        return
    lines += [
        "```bash",
        r.get("command", COMMAND),
        "```",
        "",  # the command as it ran (older files: the usage)
        f"The shipped HCMT (`{r['model']}`), a Gaussian process (scikit-learn, ARD RBF + white noise on log "
        f"inputs and log outputs; `hcmt.design.surrogate`) and a full quadratic response surface "
        f"({r['quadratic_terms']} terms, least squares on log answers), the two surfaces fitted on the same "
        f"{r['training_designs']} training designs the model learned from ({len(r['parameters'])} varied "
        f"parameters), all judged against the solver on designs none of them saw. Device: {r['device']} "
        f"({r['machine']}), {r['threads']} thread.",
        "",
    ]
    lines += accuracy_table(r) + [""] + accuracy_read(r) + [""]
    lines += ["**Learning curve** (the first n training designs; the same 30 in-range designs):", ""]
    lines += curve_table(r) + [""] + curve_read(r) + [""]
    lines += [
        "**Limit calls** (`--yield-mpa Y`, `--verify auto`: the solver runs where the trusted interval "
        "straddles Y and its call is final there; a pass is unsafe where the solver fails):",
        "",
    ]
    table, totals = sweeps_table(r)
    lines += table + [""] + calls_read(r, totals) + [""]
    ghost(lines, r)
    t = r["time_of_peak"]
    lines += [
        sentences(
            f"**Time of the peak**: the first frame at 95 % of the peak is off by a median "
            f"{t['t95_frames_off_median']:.1f} frames, the argmax frame by "
            f"{t['argmax_frames_off_median']:.1f}.",
            "The critical node's stress history (the solver's peak node), model against solver, correlates "
            f"with a median {t['critical_node_correlation_median']:.2f} (lowest "
            f"{t['critical_node_correlation_min']:.2f}) over {t['designs']} designs.",
        ),
        "",
    ]
    note(lines, r["note"])


def accuracy_read(r: dict) -> list[str]:
    ins = r["accuracy"]["in_range"]
    med = {q: {m: ins[q][m]["median_abs_pct"] for m, _ in METHODS} for q in QUANTITY}
    better = [name for q, name in QUANTITY.items() if med[q]["gp"] < med[q]["hcmt"]]
    what = "every scalar" if len(better) == len(QUANTITY) else said(better) if better else "no scalar"
    p = med["peak_plate_stress_mpa"]
    out = max(r["accuracy"][k]["peak_plate_stress_mpa"]["gp"]["worst_abs_pct"] for k in OUTSIDE)
    sec = r["seconds_per_design"]
    return [
        "- "
        + sentences(
            f"Inside the family the response surface answers {what} better (median error).",
            f"The GP's median peak plate stress error is {p['gp']:.1f} % against HCMT's "
            f"{p['hcmt']:.1f} % ({p['hcmt'] / p['gp']:.1f}x), the quadratic's {p['quadratic']:.1f} %.",
            f"Outside the ranges the GP's worst peak plate stress error is {out:.1f} %.",
        ),
        "- "
        + sentences(
            f"Seconds per design on this machine: HCMT {sec['hcmt']:.2f} s (batched rollout), solver "
            f"{sec['solver']:.2f} s (both while another job shared the two cores), GP "
            f"{sec['gp'] * 1e3:.2f} ms, quadratic {sec['quadratic'] * 1e3:.3f} ms.",
            f"Fitting the GP took {r['fit_s']['gp']:.1f} s (one GP per answer, 3 optimizer restarts).",
        ),
    ]


def _coverage(r: dict) -> tuple[list[str], dict, dict, int]:
    """The learning curve's sizes, and the GP's and the union's in-range coverage at each."""
    curve = r["learning_curve"]
    ns = sorted(curve, key=int)
    gp = {n: curve[n]["trusted_coverage"]["surrogate"]["covered"] for n in ns}
    union = {n: curve[n]["trusted_coverage"]["union"]["covered"] for n in ns}
    return ns, gp, union, curve[ns[0]]["trusted_coverage"]["surrogate"]["of"]


def curve_read(r: dict) -> list[str]:
    ns, gp, union, of = _coverage(r)
    low = [n for n in ns if gp[n] < COVERAGE_GOAL * of]
    more = [n for n in ns if union[n] > gp[n]]
    same = [n for n in ns if union[n] == gp[n]]
    gp_says = (
        f"At {said(low)} runs the GP's interval is over-confident: it covers the solver less often than "
        f"the {COVERAGE_GOAL:.0%} goal ({', '.join(f'{gp[n]} / {of}' for n in low)})."
        if low
        else f"The GP's interval covers at least {COVERAGE_GOAL:.0%} at every size."
    )
    union_says = (
        f"Widening it to hold the mesh model's answer (the *union*) covers the solver more often at "
        f"{said(more)} designs"
        if more
        else "Widening it to hold the mesh model's answer (the *union*) covers the solver no more often"
    )
    same_says = f", and as often at {said(same)} ({', '.join(f'{union[n]} / {of}' for n in same)})" if same else ""
    return ["- " + sentences(gp_says, union_says + same_says + ".")]


def calls_read(r: dict, totals: dict) -> list[str]:
    cov, points = r["coverage_in_range"], 11 * len(r["sweeps"])
    ns, gp, union, _ = _coverage(r)
    u, g = cov[TRUST]["covered"], cov["surrogate"]["covered"]
    covers = (
        "covers as the GP does"
        if u == g
        else "covers more often than the GP"
        if u > g
        else "covers less often than the GP"
    )
    bad = totals[TRUST]["unsafe"]
    unsafe = "makes no unsafe call" if not bad else f"makes {bad} unsafe call{'s' * (bad > 1)}"
    extra = totals[TRUST]["solver_runs"] - totals["surrogate"]["solver_runs"]
    nearer = all(union[n] >= gp[n] for n in ns) and any(union[n] > gp[n] for n in ns)
    share = {k: f"{v['covered']} / {v['of']}" for k, v in cov.items()}
    return [
        "- "
        + sentences(
            f"In-range coverage of the trusted interval: GP {share['surrogate']}, union "
            f"{share['union']}, ±60 % band {share['model']} (goal {COVERAGE_GOAL:.0%}).",
            "Outside the ranges: {covered} / {of} (union).".format(**r["coverage_outside"]["union"]),
        ),
        "- "
        + sentences(
            f"Unsafe final calls over {points} sweep points: GP {totals['surrogate']['unsafe']}, "
            f"union {totals['union']['unsafe']}, HCMT alone {totals['model_alone']['unsafe']}.",
            f"Solver runs: GP {totals['surrogate']['solver_runs']}, union "
            f"{totals['union']['solver_runs']}, ±60 % band {totals['model']['solver_runs']}.",
        ),
        "- "
        + sentences(
            f"hcmt trusts the **{TRUST}** (`TRUST` in hcmt.design.check).",
            f"At {r['training_designs']} designs it {covers} and {unsafe}, for {abs(extra)} "
            f"{'more' if extra >= 0 else 'fewer'} solver runs over {points} points.",
            "With a user's own surrogate on fewer runs it is the one that stays nearer its nominal "
            "coverage (learning curve above)."
            if nearer
            else "",
        ),
    ]


def ghost(lines: list[str], r: dict) -> None:
    g = r["ghost"]
    lines += [
        "**Ghost stress** (median over the 46 held-out designs of |model − solver| in (mean plate stress over "
        "the last 10 frames) ÷ peak; the solver's own median ratio is "
        f"{g['solver_median']:.2f}):",
        "",
        "| read-out | ghost difference (all / in range) | peak frames where the solver's ball is gone and its "
        "plate unloaded | peak plate stress error, median / worst |",
        "|---|---|---|---|",
    ]
    bound = g.get("bound", "hi")
    other = "hi" if bound != "hi" else "lo"
    first = g.get("default", "contact")  # results recorded before the model's own read-out was the default: contact
    names = {
        "raw": "the model's own stress head, every frame",
        "learned": "learned head, every frame (hcmt 0.1)",
        "contact_own": "contact window of the model's own ball",
        "contact": f"contact window ended at the GP's {BOUND_WORDS[bound]} of the contact end",
        "contact_upper": f"contact window ended at the GP's {BOUND_WORDS[other]} of the contact end",
        "element": "element law on predicted positions",
    }
    names[first] += " (default)"
    for key in [k for k in ("raw", "learned", "contact_own", "contact_upper", "contact", "element") if k in g]:
        v = g[key]
        bad = v["peaks_where_solver_unloaded"]
        listed = " (" + ", ".join(bad[:4]) + (", ..." if len(bad) > 4 else "") + ")" if bad else ""
        lines.append(
            f"| {names[key]} | {v['median_abs_diff']:.3f} / {v['median_abs_diff_in_range']:.3f} | "
            f"{len(bad)}{listed} | "
            f"{_err(v['peak_error'])} |"
        )
    default, own, lag = g[first], g["contact_own"], g["contact_end_lag_frames"]
    ok = default["median_abs_diff"] <= GHOST_GOAL
    late = lag["median"] > 0
    kinematic = late and own["median_abs_diff"] > default["median_abs_diff"]
    unloaded = default["peaks_where_solver_unloaded"]
    outside = bool(unloaded) and all(n.split("_")[0] in OUTSIDE for n in unloaded)
    which = f" ({', '.join(unloaded)}{': outside the training ranges' * outside})" if unloaded else ""
    lines += [
        "",
        "- "
        + sentences(
            f"The default read-out {'meets' if ok else 'misses'} the goal of {GHOST_GOAL:.2f} "
            f"({default['median_abs_diff']:.3f}).",
            f"Where the solver's ball leaves within the window ({lag['designs']} designs), the "
            f"learned one leaves {when(lag['median'], late)} ({lag['min']} to {lag['max']}).",
            "The ghost's cause is kinematic: a window read from the model's own contact keeps "
            f"its stress ({own['median_abs_diff']:.3f})."
            if kinematic
            else "",
            READOUT.format(bound=BOUND_WORDS[bound]),
        ),
        f"- Peaks read where the solver's plate is unloaded: {len(unloaded)} with the default read-out{which}.",
    ]
    if "contact_upper" in g:
        lines.append("- " + bound_choice(g, bound, other))
    lines += element(g) + [""]


def bound_choice(g: dict, bound: str, other: str) -> str:
    """Why the default bound: its unloaded peaks, ghost difference and peak error against the other bound's."""
    mine, theirs = g["contact"], g["contact_upper"]
    n_mine, n_theirs = (len(v["peaks_where_solver_unloaded"]) for v in (mine, theirs))
    same = (
        mine["peak_error"]["median_abs_pct"] == theirs["peak_error"]["median_abs_pct"]
        and mine["peak_error"]["worst_abs_pct"] == theirs["peak_error"]["worst_abs_pct"]
    )
    before = g.get("solver_peak_before_lower_end_frames")
    errors = "unchanged" if same else _err(mine["peak_error"]) + " instead of " + _err(theirs["peak_error"])
    return sentences(
        f"Ending the window at the {BOUND_WORDS[bound]} instead of the {BOUND_WORDS[other]}: "
        f"{n_mine} peaks where the solver's plate is unloaded instead of {n_theirs}, ghost difference "
        f"{mine['median_abs_diff']:.3f} instead of {theirs['median_abs_diff']:.3f}, peak errors "
        f"{errors}.",
        f"The solver's peak came {before['min']}-{before['max']} frames before the GP's lower bound." if before else "",
    )


def element(g: dict) -> list[str]:
    """The element law on predicted positions against the default read-out, and the strain behind it."""
    el, de = (g[k]["peak_error"]["median_abs_pct"] for k in ("element", g.get("default", "contact")))
    verdict = "is no candidate" if el >= NO_CANDIDATE * de else "is a candidate"
    out = [
        f"The element law on predicted positions {verdict}: its median peak plate stress error is {el:.1f} % "
        f"against the default's {de:.1f} %."
    ]
    prop = (load("propagation.json") or {}).get("small")  # the shipped model's data: its median edge
    if prop:
        edge = prop["median"]["median_edge_mm"]
        strain = POSITION_ERROR_MM / edge
        out.append(
            f"A micrometre of position error across a {edge:.1f} mm element is a strain of {strain:.1g}, "
            f"{strain * Design().plate_modulus:.0f} MPa in glass."
        )
    return ["- " + sentences(*out)]


def when(median: float, late: bool) -> str:
    """How the learned ball's leaving compares with the solver's, in words (a median lag of 0: the same frame)."""
    if round(abs(median)) == 0:
        return "at the solver's frame in the median"
    return f"a median {abs(median):.0f} frames {'later' if late else 'earlier'}"


def note(lines: list[str], n: dict) -> None:
    rules = [k for k in n if isinstance(n[k], dict) and "hit_rate" in n[k]]
    lines += [
        f"**The low-confidence note** (a peak plate stress error above {n['large_error_pct']:.0f} % is large; "
        f"threshold tuned on the dataset's {n['tuned_on']} valid + test designs, judged on {n['judged_on']} "
        "others):",
        "",
        "| rule | large errors flagged | false alarms |",
        "|---|---|---|",
    ]
    for k in rules:
        v = n[k]
        lines.append(f"| {k} | {v['hits']} / {v['large_errors']} | {v['false_alarms']} / {v['small_errors']} |")
    best = min(
        (k for k in rules if (n[k]["hit_rate"] or 0) >= NOTE_GOAL), key=lambda k: n[k]["false_alarm_rate"], default=None
    )
    if "shipped_threshold_pct" not in n:  # a result file written before the shipped threshold was judged beside
        lines += [
            "",
            sentences(
                f"- hcmt uses the rule with the fewest false alarms among those that flag at least "
                f"{NOTE_GOAL:.0%} of the large errors: **{best}** (`NOTE_DISAGREEMENT`).",
                "Without a surrogate: the card's regions.",
            )
            if best
            else "- No rule reached the goal.",
            "",
        ]
        return
    shipped = next(k for k in rules if k.endswith("(hcmt's NOTE_DISAGREEMENT)"))
    v = n[shipped]
    lines += [
        "",
        "- "
        + sentences(
            f"The rule with the fewest false alarms among those that flag at least {NOTE_GOAL:.0%} of the large "
            f"errors: **{best}**."
            if best
            else f"No rule flags {NOTE_GOAL:.0%} of the large errors.",
            f"hcmt's note uses a model-GP disagreement above {n['shipped_threshold_pct']:.1f} % (`NOTE_DISAGREEMENT`): "
            f"on these designs it flagged {v['hits']} of {v['large_errors']} large errors with {v['false_alarms']} "
            f"false alarms in {v['small_errors']}.",
            "Without a surrogate: the card's regions.",
        ),
        "",
    ]


def judge(lines, d) -> None:
    """A model judged on designs of fresh seeds against the model goals, the response surface fitted on the
    same runs beside it (``python benchmarks/surrogate/run.py ... --json model_judge.json``)."""
    if not d or "goals" not in d:
        return
    lines += [
        "### The mesh model judged against the model goals",
        "",
        f"Command: `{d['command']}` (model {d['model']}"
        + (f" at step {d['checkpoint_step']:,}" if d.get("checkpoint_step") else "")
        + f"; designs of seeds {d['seeds']['in_range']} in range and {d['seeds']['outside']} outside; "
        f"the Gaussian process fitted on the model's {d['training_designs']} "
        "training designs; the model's default read-out, its own outputs).",
        "",
        "| goal | target | HCMT | met | response surface |",
        "|---|---|---|---|---|",
    ]
    for g in d["goals"]:

        def num(v):
            return "-" if v is None else f"{v:.3g}"

        lines.append(
            f"| {g['goal']} | {'≥' if g['at_least'] else '≤'} {num(g['target'])} | {num(g['hcmt'])} | "
            f"{'yes' if g['hcmt_met'] else 'no'} | {num(g['gp'])} |"
        )
    met = sum(g["hcmt_met"] for g in d["goals"])
    both = [g for g in d["goals"] if g["gp"] is not None]
    gp_better = sum((g["gp"] > g["hcmt"]) if g["at_least"] else (g["gp"] < g["hcmt"]) for g in both)
    lines += [
        "",
        sentences(
            f"The model meets {met} of {len(d['goals'])} goals.",
            f"Where the response surface answers the same number ({len(both)} goals), it does better in {gp_better}.",
        ),
    ]
    lines += [
        "",
        "Trends (change from a sweep's first point to its last):",
        "",
        "| sweep | quantity | solver | HCMT | response surface |",
        "|---|---|---|---|---|",
    ]
    for name, g in d["trends"].items():
        sweep = (
            "drop height 520 → 990 mm at 0.75 mm"
            if name == "sweep_height"
            else f"thickness 0.5 → 1.0 mm at {name.split('_', 1)[1]} mm"
        )
        for q, t in g.items():
            gp = "-" if t["gp"] is None else f"{100 * t['gp']:+.1f} %"
            lines.append(f"| {sweep} | {QUANTITY[q]} | {100 * t['solver']:+.1f} % | {100 * t['hcmt']:+.1f} % | {gp} |")
    lines.append("")
