"""docs/RESULTS.md's frame-interval study: benchmarks/interval/run.py,
with the design check per interval (--speed) and what a coarse interval loses of the peak
(benchmarks/interval/peak_sampling.py)."""

from __future__ import annotations

from report_common import ABOUT, PEAK_GOAL_PCT, SHIPPED_STEPS, command, load, opened, pm, said, sentences, worse

FORMS, MODELS, QS = ("today", "recipe"), ("hcmt", "mgn", "mgn-deep"), ("position_rmse_all", "stress_rmse_all")
LARGE_DRIFT_PCT = 100.0  # a max-deflection error above this: the rollout's drift exceeds the deflection itself
PEAK_FIELD = (
    "`hcmt generate --peak-stress` records `stress_max`, each node's largest stress over the substeps since "
    "the previous frame. `--set data.stress_field=stress_max` trains, evaluates and verifies a model on it "
    "(tests/sim/test_sim_generate.py checks it against a run that records every substep)."
)


def interval(lines):
    """The frame-interval study: benchmarks/interval/run.py."""
    t = opened(
        lines, "## Frame interval: HCMT against MGN as the impact outruns a message (`small` preset)", "interval.json"
    )
    if not t:
        return
    dts = list(t["data"])
    frames = {dt: t["data"][dt]["frames"] for dt in dts}
    d0 = t["data"][dts[0]]
    span = (d0["frames"] - 1) * d0["frame_dt"]
    lines += [
        f"`python benchmarks/interval/run.py --work $HCMT_WORK/interval --steps {t['steps']}` (two processes "
        "share the work; then `--speed` and `--table-only`). The same "
        f"{d0['train']} / {d0['valid']} / {d0['test']} designs (seed {d0['seed']}) recorded over the same "
        f"{span:.3f} ms at " + ", ".join(f"{dt} ms ({frames[dt]} frames)" for dt in dts) + " (`hcmt generate "
        "--frame-dt`). Per interval and formulation, three models at equal steps "
        f"({t['steps']}, `{t['config']}`): HCMT (official attention), MGN (11 blocks) and MGN with 22 blocks "
        "(the depth control). Formulations: *today* (velocity target, noise on NORMAL nodes) and *recipe* "
        "(the recipe study's choice: " + " ".join(t["formulations"]["recipe"]) + "). σ per model, interval "
        "and formulation on the validation split (seed 0 at each candidate: "
        + ", ".join(f"{x:g}" for x in t["sigma_candidates_at_0.002"])
        + " mm at 0.002 ms, scaled with the "
        "interval), then seeds " + ", ".join(map(str, t["seeds"][1:])) + " at the chosen σ. Test split, mean ± "
        "std over seeds; physics medians over the designs (|error| unless signed); the time of the peak in "
        "ms (frames × interval).",
        "",
    ]
    reach_table(lines, t, dts, frames)
    table = t["table"]
    for form in FORMS:
        if any(form in table.get(dt, {}) for dt in dts):
            form_table(lines, table, form, dts)
    trend = ratio_table(lines, table, dts)
    lines += [
        "",
        "![HCMT ÷ baseline against the front's hops per frame ÷ the baseline's reach](img/interval_ratio.png)",
        "",
    ]
    lines += reading(t, dts, trend)
    speed_table(lines, t, dts)
    peak_sampling(lines)


def growth(prop, a, b, key):
    return prop[b][key] / prop[a][key]


def reach_table(lines, t, dts, frames):
    prop = t["propagation"]
    lines += [
        "How far the impact travels per frame (plate mesh hops; benchmarks/parity/propagation.py's measures on "
        "the test designs) against each model's reach per step (MGN: one hop per block; HCMT: L_C plus its "
        "hierarchy's spans):",
        "",
        "| interval ms | frames | stress front hops/frame | P-wave hops/frame | frames until the front "
        "reaches the clamp | front ÷ MGN's 11 | front ÷ deep MGN's 22 | front ÷ HCMT's reach |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for dt in dts:
        q = prop[dt]
        r, f = q["reach_per_step"], q["front_hops_per_frame"]
        lines.append(
            f"| {dt} | {frames[dt]} | {f:.1f} | {q['p_wave_hops_per_frame']:.0f} | "
            f"{q['frames_to_reach_clamp']:.0f} | {f / r['mgn']:.2f} | {f / r['mgn-deep']:.2f} | "
            f"{f / r['hcmt']:.2f} ({r['hcmt']:.0f} hops) |"
        )
    a, b = dts[0], dts[-1]
    k = float(b) / float(a)  # how much the interval grows

    def keeps_pace(key):  # hops per frame grow about as the interval does
        return growth(prop, a, b, key) * ABOUT >= k

    front = "grow with the interval" if keeps_pace("front_hops_per_frame") else "are bounded by the plate"
    p_wave = "grow with it" if keeps_pace("p_wave_hops_per_frame") else "do not grow with it either"
    last = prop[b]
    lines += [
        "",
        sentences(
            f"The front reaches the clamp (about {last['impact_to_clamp_hops']:.0f} hops) within "
            f"{last['frames_to_reach_clamp']:.0f} frames at {b} ms.",
            f"Its hops per frame {front}; the P wave's {p_wave}.",
        ),
        "",
    ]


def form_table(lines, table, form, dts):
    lines += [
        f"**{form}** formulation, test split:",
        "",
        "| interval ms | model | σ mm | seeds | position RMSE-all ×10³ | stress RMSE-all ×10³ | rebound "
        "agreement | peak plate stress error % | signed % | time of peak error ms | max deflection error % "
        "| far-field µm | train ms/step | inference ms/step | steps per design |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for dt in dts:
        for model in MODELS:
            r = table.get(dt, {}).get(form, {}).get(model)
            if not r:
                continue
            lines.append(
                f"| {dt} | {model} | {r['sigma_mm']:g} | {r['seeds']} | {pm(r['position_rmse_all'], 3)} | "
                f"{pm(r['stress_rmse_all'], 3)} | {pm(r['rebound_agreement'], 2)} | "
                f"{pm(r['peak_plate_stress_error_pct'], 3)} | "
                f"{pm(r['peak_plate_stress_error_pct_signed'], 3)} | "
                f"{r['peak_time_error_ms']['mean']:.3f} | {pm(r['max_deflection_error_pct'], 3)} | "
                f"{pm(r['far_deflection_error_um'], 3)} | {r['train_ms_per_step']['mean']:.0f} | "
                f"{r['inference_ms_per_step']['mean']:.1f} | {r['model_steps_per_design']} |"
            )
    lines.append("")


def ratio_table(lines, table, dts) -> dict:
    """HCMT ÷ each baseline per interval and formulation; returns HCMT ÷ MGN by formulation, by interval."""
    lines += [
        "HCMT ÷ baseline, RMSE-all of the seed means (test); * where the two means differ by more than the "
        "larger std over seeds:",
        "",
        "| interval ms | formulation | ÷ MGN position | ÷ MGN stress | ÷ deep MGN position | ÷ deep MGN stress |",
        "|---|---|---|---|---|---|",
    ]
    trend = {}
    for form in FORMS:
        for dt in dts:
            ratios = table.get(dt, {}).get(form, {}).get("ratios")
            if not ratios:
                continue
            cells = []
            for other in ("hcmt/mgn", "hcmt/mgn-deep"):
                for q in QS:
                    x = ratios.get(other, {}).get(q)
                    cells.append("–" if x is None else f"{x['ratio']:.2f}{'*' if x['separated'] else ''}")
            lines.append(f"| {dt} | {form} | " + " | ".join(cells) + " |")
            if "hcmt/mgn" in ratios:
                trend.setdefault(form, []).append((float(dt), ratios["hcmt/mgn"]))
    return trend


def reading(t, dts, trend) -> list[str]:
    """The bullets under the ratio table, each from a comparison of the numbers above."""
    table, prop = t["table"], t["propagation"]
    out, grown = [], []
    for form, pts in trend.items():  # does HCMT's margin over MGN grow with the interval?
        if len(pts) < 2:
            continue
        (a_dt, a), (b_dt, b) = sorted(pts, key=lambda p: p[0])[:: len(pts) - 1]
        grows = [q for q in QS if b[q]["ratio"] < a[q]["ratio"] and b[q]["separated"]]
        shrinks = [q for q in QS if b[q]["ratio"] > a[q]["ratio"]]
        verdict = "grows" if grows and not shrinks else "does not grow" if not grows else "is mixed"
        grown += [form] * (verdict != "does not grow")
        where = f" (separated from MGN at {b_dt:g} ms in {said([q.split('_')[0] for q in grows])})" if grows else ""
        pair = " / ".join(f"{a[q]['ratio']:.2f}" for q in QS), " / ".join(f"{b[q]['ratio']:.2f}" for q in QS)
        out.append(
            f"- **{form}**: "
            + sentences(
                f"HCMT ÷ MGN goes from {pair[0]} (position / stress) at {a_dt:g} ms to {pair[1]} at {b_dt:g} ms.",
                f"The margin {verdict} with the interval{where}.",
            )
        )

    def pos(dt, form, model):
        return table.get(dt, {}).get(form, {}).get(model)

    a_dt, b_dt = dts[0], dts[-1]
    for form in FORMS:
        drops = [
            (m, pos(a_dt, form, m)["position_rmse_all"]["mean"], pos(b_dt, form, m)["position_rmse_all"]["mean"])
            for m in MODELS
            if pos(a_dt, form, m) and pos(b_dt, form, m)
        ]
        if drops:
            fell = [m for m, a, b in drops if b < a]
            each = ", ".join(f"{b / a:.2f} ({m})" for m, a, b in drops)
            falls = (
                "Every model's error falls with the coarser interval."
                if len(fell) == len(drops)
                else f"The error falls for {said(fell)} only."
                if fell
                else "No model's error falls."
            )
            out.append(
                f"- **{form}**, fewer autoregressive steps: "
                + sentences(f"position RMSE-all at {b_dt} ms ÷ at {a_dt} ms is {each}.", falls)
            )
    depth = [
        (dt, form, q) for dt in dts for form in FORMS for q in QS if pos(dt, form, "mgn") and pos(dt, form, "mgn-deep")
    ]
    deeper = [x for x in depth if worse(pos(x[0], x[1], "mgn"), pos(x[0], x[1], "mgn-deep"), x[2])]
    r, (m, deep) = prop[a_dt]["reach_per_step"], (pos(a_dt, "today", k) for k in ("mgn", "mgn-deep"))
    out.append(
        "- Depth control: "
        + sentences(
            f"MGN with {r['mgn-deep']} blocks is below MGN with {r['mgn']}, separated by the seeds' spread, in "
            f"{len(deeper)} of {len(depth)} (interval, formulation, quantity) cells.",
            f"Its training step takes "
            f"{deep['train_ms_per_step']['mean'] / m['train_ms_per_step']['mean']:.1f}× as long.",
        )
    )
    pa, pb = prop[a_dt], prop[b_dt]
    gp, gf = (growth(prop, a_dt, b_dt, k) for k in ("p_wave_hops_per_frame", "front_hops_per_frame"))
    within = [dt for dt in dts if prop[dt]["front_hops_per_frame"] <= prop[dt]["reach_per_step"]["hcmt"]]
    where = "at every interval" if len(within) == len(dts) else f"at {said(within)} ms" if within else "at no interval"
    ratios = [f"{p['front_hops_per_frame'] / p['reach_per_step']['mgn']:.2f}" for p in (pa, pb)]
    out.append(
        "- Reach: "
        + sentences(
            f"from {a_dt} to {b_dt} ms the P wave's hops per frame grow {gp:.1f}×, the stress front's "
            f"{'only ' * (gf < gp)}{gf:.1f}× (front ÷ MGN's reach {ratios[0]} → {ratios[1]}).",
            f"The front is within HCMT's {pb['reach_per_step']['hcmt']:.0f} hops per step {where}.",
        )
    )
    worst = max(
        r["max_deflection_error_pct"]["mean"]
        for dt in dts
        for form in FORMS
        for k, r in table.get(dt, {}).get(form, {}).items()
        if k != "ratios"
    )
    drift = worst > LARGE_DRIFT_PCT
    out += [
        "- Budget: "
        + sentences(
            f"{t['steps']} steps per run; max-deflection errors reach {worst:.0f} % "
            "(median over designs, mean over seeds).",
            "At this budget the rollout's drift exceeds the deflection itself"
            + (", and no margin shows." if not grown else ".")
            if drift
            else "",
            f"docs/MODELS.md has a model trained {SHIPPED_STEPS / t['steps']:.0f}× longer.",
        ),
        "",
    ]
    return out


def speed_table(lines, t, dts):
    sp = t.get("speed")
    if not sp:
        return
    table = t["table"]
    n = next(v for k, v in sp.items() if k != "device")["designs"]
    lines += [
        f"The design check at each interval (`python benchmarks/interval/run.py --speed`): `predict --verify` "
        f"of the {n} test designs with each interval's HCMT (recipe, seed 0), {sp['device']}; median seconds per "
        "design, learned one design at a time and all in one batch, the solver one design at a time:",
        "",
        "| interval ms | frames | learned s/design | learned s/design, batched | solver s/design | speedup "
        f"| speedup, batched | peak plate stress error % (median, these {n}) | HCMT recipe position "
        "RMSE-all ×10³ (3 seeds) | peak error % (3 seeds) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for dt in dts:
        r = sp.get(dt)
        if not r:
            continue
        pk = r["verify"].get("peak_plate_stress_error_pct", {})
        h = table.get(dt, {}).get("recipe", {}).get("hcmt")
        three = f"{pm(h['position_rmse_all'], 3)} | {pm(h['peak_plate_stress_error_pct'], 3)} |" if h else "– | – |"
        lines.append(
            f"| {dt} | {r['frames']} | {r['learned_s_per_design_one_at_a_time']:.3f} | "
            f"{r['learned_s_per_design_batched']:.3f} | {r['solver_s_per_design']:.3f} | "
            f"{r['speedup_one_at_a_time']:.2f}× | {r['speedup_batched']:.2f}× | "
            f"{pk.get('median', float('nan')):.1f} | " + three
        )
    lines.append("")


def peak_sampling(lines):
    ps = load("peak_sampling.json")
    if not ps:
        return
    lines += [
        f"What a coarse interval loses of the peak (`{command(ps)}`): the solver re-run on the "
        f"{len(ps['rows'])} test designs recording every substep ("
        f"{ps['summary']['substeps_per_frame']['median']:.0f} per 0.002 ms frame, median); the recorded "
        "peak (the largest stress over the recorded frames) against the true one (over every substep), "
        "(true − recorded) ÷ true; 'any phase': the recording grid slid over every starting substep.",
        "",
        "| interval ms | plate median % | plate worst % | plate mean, any phase % | plate worst, any phase "
        "% | ball median % | ball worst % |",
        "|---|---|---|---|---|---|---|",
    ]
    for dt in (f"{x:g}" for x in ps["intervals_ms"]):
        a, b = ps["summary"]["plate"][dt], ps["summary"]["ball"][dt]
        lines.append(
            f"| {dt} | {a['median_shortfall_pct']:.2f} | {a['worst_shortfall_pct']:.2f} | "
            f"{a['phases_mean_shortfall_pct']:.2f} | {a['phases_worst_shortfall_pct']:.2f} | "
            f"{b['median_shortfall_pct']:.2f} | {b['worst_shortfall_pct']:.2f} |"
        )
    last = f"{ps['intervals_ms'][-1]:g}"
    worst = ps["summary"]["plate"][last]["worst_shortfall_pct"]
    matters = worst > PEAK_GOAL_PCT  # as large as the peak-stress error asked of a shipped model
    lines += [
        "",
        sentences(
            f"At {last} ms a sharp peak can fall between two frames: up to {worst:.1f} % of the "
            "plate's true peak is not in the data.",
            f"That is more than the {PEAK_GOAL_PCT:g} % peak-stress goal of a shipped model." if matters else "",
            PEAK_FIELD,
        ),
        "",
    ]
