"""docs/RESULTS.md's impact-physics sections: the recorded window (benchmarks/recipe/window.py) and the
training recipe study (benchmarks/recipe/run.py)."""

from __future__ import annotations

from report_common import command, opened, pm, said, sentences, separated, worse

OLD_FRAMES = 52  # the window of the first datasets
RECORDED_FRAMES = 90  # the window of the recipe study's and the shipped model's data
TODAY = "vel-normal"  # the recipe before the study
RECIPE = {"model.deformation=true", "model.target=acceleration", "train.noise_nodes=predicted"}  # with pushforward
SPRINGS = (
    "The plate's restoring force is a small bending strain, invisible in the normalized x_ij and u_ij; the "
    "edge deformation features make it visible. With them, the acceleration target, noise on every predicted "
    "node and pushforward (training on the model's own states) the plate springs back."
)
NAMES = {
    "rebound_agreement": "rebound agreement",
    "peak_plate_stress_error_pct": "peak plate stress error",
    "max_deflection_error_pct": "max deflection error",
    "position_rmse_all": "position RMSE-all",
}
LARGER = {"rebound_agreement"}  # the criteria where larger is better
AGAINST = (
    ("rebound agreement", "rebound_agreement", ".2f", ""),
    ("max deflection error", "max_deflection_error_pct", ".0f", " %"),
    ("far-field deflection error", "far_deflection_error_um", ".0f", " µm"),
    ("position RMSE-all", "position_rmse_all", ".0f", ""),
)


def window(lines):
    win = opened(lines, "## The recorded window", "window.json")
    if not win:
        return
    d = win["designs"]
    late = [r for r in d if r["peak_frame"] >= OLD_FRAMES]
    short = max(100 * (1 - r[f"peak_within_{OLD_FRAMES}_mpa"] / r["peak_mpa"]) for r in d)
    turn = max(r["rebound_frame"] for r in d if r["rebound_frame"] is not None)
    fits = all(r["peak_frame"] < RECORDED_FRAMES and (r["rebound_frame"] or 0) < RECORDED_FRAMES for r in d)
    ms = (RECORDED_FRAMES - 1) * win["frame_dt_ms"]
    lines += [
        sentences(
            f"`{command(win)}`: the solver on the corners of the `small` ranges over {win['frames']} "
            f"frames of {win['frame_dt_ms']} ms.",
            f"The plate's peak falls at frames {min(r['peak_frame'] for r in d)}-{max(r['peak_frame'] for r in d)}.",
            f"{len(late)} of {len(d)} corner designs peak after frame {OLD_FRAMES - 1}, the end of the "
            f"old {OLD_FRAMES}-frame window (up to {short:.0f} % below the true peak within it).",
            f"The ball turns up by frame {turn}.",
            f"The data of the recipe study and of the shipped model are {'therefore ' * fits}recorded "
            f"over {RECORDED_FRAMES} frames ({ms:.3f} ms).",
        ),
        "",
        "| thickness mm | drop mm | ball radius mm | peak frame | peak MPa | peak within 52 frames | "
        "rebound frame | max deflection frame |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in d:
        lines.append(
            f"| {r['thickness']} | {r['drop_height']:.0f} | {r['ball_radius']} | {r['peak_frame']} | "
            f"{r['peak_mpa']:.0f} | {r[f'peak_within_{OLD_FRAMES}_mpa']:.0f} | {r['rebound_frame']} | "
            f"{r['max_deflection_frame']} |"
        )
    lines.append("")


def recipe(lines):
    """The training-recipe study: benchmarks/recipe/run.py."""
    window(lines)
    t = opened(
        lines, f"## Impact physics: the training recipe (`small` preset, {RECORDED_FRAMES} frames)", "recipe_small.json"
    )
    if not t:
        return
    chosen = min(t["rank_sums"], key=t["rank_sums"].get) if t["rank_sums"] else t["chosen"]
    ranks = ", ".join(f"{k} {v:g}" for k, v in sorted(t["rank_sums"].items(), key=lambda kv: kv[1]))
    lines += [
        f"`python benchmarks/recipe/run.py --work $HCMT_WORK/study --steps {t['steps']}` (then `--table-only`): "
        "HCMT "
        f"(`{t['config']}`, {' '.join('--set ' + b for b in t['base'])}) on {t['dataset']['train']} / "
        f"{t['dataset']['valid']} / {t['dataset']['test']} designs (seed {t['dataset']['seed']}), "
        f"{t['steps']} steps per run, the validation checkpoint with the lowest position RMSE. Mean ± std over "
        "seeds; physics medians over the split's designs, |error| unless 'signed'. The recipe is chosen on the "
        f"validation split by the lowest rank sum over {', '.join(t['criteria'])} (tied values share a rank): "
        f"**{chosen}** (rank sums: {ranks}).",
        "",
        f"Test split ({t['dataset']['test']} designs):",
        "",
        "| recipe | seeds | position RMSE-all ×10³ | stress RMSE-all ×10³ | rebound agreement "
        "| peak plate stress error % | signed % | time of peak (frames) | max deflection error % "
        "| far-field deflection error µm | "
        "train ms/step |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for label, r in t["recipes"].items():
        te = r["test"]
        cells = [pm(te[k], 3) for k in ("position_rmse_all", "stress_rmse_all")] + [pm(te["rebound_agreement"], 2)]
        cells += [
            pm(te[k], 3)
            for k in (
                "peak_plate_stress_error_pct",
                "peak_plate_stress_error_pct_signed",
                "peak_plate_frame_error",
                "max_deflection_error_pct",
                "far_deflection_error_um",
                "train_ms_per_step",
            )
        ]
        lines.append(f"| {label} ({', '.join(r['overrides']) or 'today'}) | {r['seeds']} | " + " | ".join(cells) + " |")
    lines += [
        "",
        f"Validation split ({t['dataset']['valid']} designs; what chose the recipe):",
        "",
        "| recipe | position RMSE-all ×10³ | rebound agreement | peak plate stress error % | max deflection error % |",
        "|---|---|---|---|---|",
    ]
    for label, r in t["recipes"].items():
        v = r["valid"]
        lines.append(
            f"| {label} | {pm(v['position_rmse_all'], 3)} | {pm(v['rebound_agreement'], 2)} | "
            f"{pm(v['peak_plate_stress_error_pct'], 3)} | {pm(v['max_deflection_error_pct'], 3)} |"
        )
    steps = {lab: r["test"]["error_by_step"] for lab, r in t["recipes"].items()}
    lines += [
        "",
        "Position error by body at rollout steps 10 / 40 / 88 (test, ×10³ mm, mean over seeds): where the "
        "deflection error sits.",
        "",
        "| recipe | ball | contact zone (r ≤ R/2) | far plate (r > R/2) |",
        "|---|---|---|---|",
    ]
    for lab, e in steps.items():
        cell = [
            " / ".join(f"{e[k][i]:.0f}" for i in (9, 39, len(e[k]) - 1))
            for k in ("position_ball", "position_contact", "position_far")
        ]
        lines.append(f"| {lab} | " + " | ".join(cell) + " |")
    if chosen in t["recipes"] and TODAY in t["recipes"] and chosen != TODAY:
        lines += ["", study(t, chosen, steps)]
    lines.append("")


def study(t, chosen, steps) -> str:
    """What the study says: the chosen recipe against today's, each sentence from a comparison of the tables."""
    R, n_test = t["recipes"], t["dataset"]["test"]
    a, b = R[chosen]["test"], R[TODAY]["test"]
    ea, eb = steps[chosen], steps[TODAY]
    pairs = ", ".join(
        f"{name} {a[k]['mean']:{f}}{unit} against {b[k]['mean']:{f}}{unit}" for name, k, f, unit in AGAINST
    )
    out = ["**What the study says** (test split, means over seeds).", f"The chosen recipe against today's: {pairs}."]
    if "acc-normal" in R:
        out.append(acceleration(R, b, n_test))
    drift = (
        eb["position_contact"][-1] > eb["position_far"][-1]
        and eb["position_contact"][-1] - ea["position_contact"][-1] > eb["position_far"][-1] - ea["position_far"][-1]
    )
    out += [
        f"At the last step today's contact-zone error is {eb['position_contact'][-1]:.0f} ×10⁻³ mm and the far "
        f"plate's {eb['position_far'][-1]:.0f}; the chosen recipe's {ea['position_contact'][-1]:.0f} and "
        f"{ea['position_far'][-1]:.0f}.",
        "What drives the deflection error is the contact zone's drift." * drift,
    ]
    ov = set(R[chosen]["overrides"])
    if RECIPE <= ov and any(o.startswith("train.pushforward=") for o in ov) and worse(b, a, "max_deflection_error_pct"):
        out.append(SPRINGS)
    if "vel-normal-def" in R:
        vd = R["vel-normal-def"]["test"]
        signed = vd["peak_plate_stress_error_pct_signed"]["mean"]
        why = (
            ["the ball does not rebound"]
            if vd["model_rebounds"]["mean"] == 0
            else ["its rebound agreement is below today's"]
            if worse(vd, b, "rebound_agreement", True)
            else []
        )
        fail = bool(why) or worse(vd, b, "peak_plate_stress_error_pct")
        peak = f"the peak stress is {'over' if signed > 0 else 'under'}-predicted by {abs(signed):.0f} %"
        out.append(
            f"Deformation features with today's velocity target{' fail' * fail} (vel-normal-def): "
            + said(why + [peak])
            + "."
        )
    out += pushforward(t)
    frames = f"{a['peak_plate_frame_error']['mean']:.0f} frames (median over designs, mean over seeds)"
    out.append(
        f"The time of the peak is off by {frames}, less than today's."
        if worse(b, a, "peak_plate_frame_error")
        else f"The time of the peak stays off by {frames}."
    )
    return sentences(*out)


def acceleration(R, b, n_test) -> str:
    """The acceleration target alone (acc-normal) against today's."""
    an = R["acc-normal"]["test"]
    acc = [k for k, r in R.items() if "model.target=acceleration" in r["overrides"]]
    rebound = bool(acc) and all(
        R[k]["test"]["rebound_agreement"]["mean"] == 1
        and R[k]["test"]["rebound_agreement"]["std"] == 0
        and R[k]["test"]["solver_rebounds"]["mean"] == n_test
        for k in acc
    )
    sinks = worse(an, b, "max_deflection_error_pct") and an["max_deflection_error_pct_signed"]["mean"] > 0
    defl = f"max deflection error {an['max_deflection_error_pct']['mean']:.0f} % (acc-normal)"
    if rebound:
        return sentences(
            "The acceleration target alone gets the rebound (every acceleration recipe rebounds in every test design).",
            f"But the plate then sinks: {defl}." if sinks else f"Its {defl}.",
        )
    return (
        f"With the acceleration target alone the plate sinks: {defl}."
        if sinks
        else f"With the acceleration target alone: {defl}."
    )


def pushforward(t) -> list[str]:
    """Each recipe with pushforward against the same recipe without it, criterion by criterion."""
    R = t["recipes"]
    pairs = [(k, k.replace("-pf", "")) for k in R if "-pf" in k and k.replace("-pf", "") in R]
    if not pairs:
        return []
    moved = {
        k: [
            f"{NAMES.get(c, c)} {'worse' if worse(R[k]['test'], R[base]['test'], c, c in LARGER) else 'better'}"
            for c in t["criteria"]
            if separated(R[k]["test"][c], R[base]["test"][c])
        ]
        for k, base in pairs
    }
    out = [
        "Pushforward against the same recipe without it (beyond the larger std over seeds): "
        + "; ".join(f"{k} against {base}: " + (", ".join(moved[k]) or "no criterion") for k, base in pairs)
        + "."
    ]
    alone = [k for k, _ in pairs if "-def" not in k]
    if alone and not any(moved[k] for k in alone) and any(moved[k] for k, _ in pairs if k not in alone):
        out.append(f"Pushforward alone ({', '.join(alone)}) changes little; it shows only in combination.")
    return out
