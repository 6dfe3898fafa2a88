"""docs/RESULTS.md's section "The design check against a response surface", from benchmarks/results/surrogate.json
(``python benchmarks/surrogate.py``). Every verdict below is computed from the numbers it prints."""
from __future__ import annotations

COMMAND = ("python benchmarks/surrogate.py --data DATA --work WORK --threads 1   # DATA: the shipped model's "
           "training data (docs/MODELS.md)")
SETS = {"in_range": "30 in range", "thicker": "6 thicker (1.03-1.2 mm)", "higher": "6 higher (1030-1200 mm)",
        "both": "4 thicker and higher"}
QUANTITY = {"peak_plate_stress_mpa": "peak plate stress", "max_deflection_mm": "max deflection",
            "peak_ball_stress_mpa": "peak ball stress"}
METHODS = (("hcmt", "HCMT (shipped)"), ("gp", "Gaussian process"), ("quadratic", "quadratic RS"))
GHOST_GOAL = 0.10
COVERAGE_GOAL = 0.90
NOTE_GOAL = 0.80


def _err(v: dict | None) -> str:
    return "-" if v is None else f"{v['median_abs_pct']:.1f} % / {v['worst_abs_pct']:.1f} %"


def _cov(v: dict | None) -> str:
    return "-" if v is None or "covered" not in v else f"{v['covered']} / {v['of']}"


def accuracy_table(r: dict) -> list[str]:
    lines = ["| designs | quantity | " + " | ".join(f"{label}: median / worst error" for _, label in METHODS)
             + " | GP 95 % covers | quadratic 95 % covers |", "|---" * (len(METHODS) + 4) + "|"]
    for key, label in SETS.items():
        for q, name in QUANTITY.items():
            row = r["accuracy"][key][q]
            lines.append(f"| {label} | {name} | " + " | ".join(_err(row.get(m)) for m, _ in METHODS)
                         + f" | {_cov(row.get('gp'))} | {_cov(row.get('quadratic'))} |")
    return lines


def curve_table(r: dict) -> list[str]:
    lines = ["| training designs | GP peak plate stress, median / worst | GP deflection | quadratic peak plate "
             "stress | GP 95 % covers (peak) | union with HCMT covers |", "|---|---|---|---|---|---|"]
    for n, c in r["learning_curve"].items():
        q = c["peak_plate_stress_mpa"]
        lines.append(f"| {n} | {_err(q.get('gp'))} | {_err(c['max_deflection_mm'].get('gp'))} | "
                     f"{_err(q.get('quadratic')) if q.get('quadratic') else 'cannot fit (' + str(r['quadratic_terms']) + ' terms)'}"
                     f" | {c['trusted_coverage']['surrogate']['covered']} / 30 | "
                     f"{c['trusted_coverage']['union']['covered']} / 30 |")
    return lines


def sweeps_table(r: dict) -> tuple[list[str], dict]:
    lines = ["| sweep (thickness 0.5 → 1.0 mm, 11 points) | solver's minimum | HCMT alone: minimum, unsafe points | "
             "GP interval: minimum, unsafe, solver runs | union: minimum, unsafe, solver runs | ±60 % band: solver "
             "runs |", "|---|---|---|---|---|---|"]
    totals = {t: {"unsafe": 0, "solver_runs": 0} for t in ("surrogate", "union", "model")}
    totals["model_alone"] = {"unsafe": 0}
    fmt = lambda v: "none passes" if v is None else f"{v:g} mm"  # noqa: E731
    for name, s in r["sweeps"].items():
        for t in ("surrogate", "union", "model"):
            for k in ("unsafe", "solver_runs"):
                totals[t][k] += s[t][k]
        totals["model_alone"]["unsafe"] += s["model_alone"]["unsafe"]
        lines.append(f"| {name} | {fmt(s['solver_minimum'])} | {fmt(s['model_alone']['minimum'])}, "
                     f"{s['model_alone']['unsafe']} | {fmt(s['surrogate']['minimum'])}, {s['surrogate']['unsafe']}, "
                     f"{s['surrogate']['solver_runs']} | {fmt(s['union']['minimum'])}, {s['union']['unsafe']}, "
                     f"{s['union']['solver_runs']} | {s['model']['solver_runs']} |")
    return lines, totals


def surrogate(lines: list[str], r: dict | None) -> None:
    lines += ["## The design check against a response surface", ""]
    if r is None:
        lines += ["Not run yet: `" + COMMAND + "`.", ""]
        return
    lines += ["```bash", COMMAND, "```", "",
              f"The shipped HCMT (`{r['model']}`), a Gaussian process (scikit-learn, ARD RBF + white noise on log "
              f"inputs and log outputs; `hcmt.design.surrogate`) and a full quadratic response surface "
              f"({r['quadratic_terms']} terms, least squares on log answers), the two surfaces fitted on the same "
              f"{r['training_designs']} training designs the model learned from ({len(r['parameters'])} varied "
              f"parameters), all judged against the solver on designs none of them saw. Device: {r['device']} "
              f"({r['machine']}), {r['threads']} thread.", ""]
    lines += accuracy_table(r) + [""]
    gp_in, hc_in = (r["accuracy"]["in_range"]["peak_plate_stress_mpa"][m]["median_abs_pct"] for m in ("gp", "hcmt"))
    q_in = r["accuracy"]["in_range"]["peak_plate_stress_mpa"]["quadratic"]["median_abs_pct"]
    sec = r["seconds_per_design"]
    lines += [f"- Inside the family the response surface answers the scalars better: the GP's median peak plate "
              f"stress error is {gp_in:.1f} % against HCMT's {hc_in:.1f} % ({hc_in / gp_in:.1f}x), the quadratic's "
              f"{q_in:.1f} %; outside the ranges the GP stays within "
              f"{max(r['accuracy'][k]['peak_plate_stress_mpa']['gp']['worst_abs_pct'] for k in ('thicker', 'higher', 'both')):.1f} % "
              f"on peak plate stress.",
              f"- Seconds per design on this machine: HCMT {sec['hcmt']:.2f} s (batched rollout), solver "
              f"{sec['solver']:.2f} s (both while another job shared the two cores), GP {sec['gp'] * 1e3:.2f} ms, "
              f"quadratic {sec['quadratic'] * 1e3:.3f} ms; fitting the GP took {r['fit_s']['gp']:.1f} s (one GP per "
              "answer, 3 optimizer restarts).", ""]
    lines += ["**Learning curve** (the first n training designs; the same 30 in-range designs):", ""]
    lines += curve_table(r) + [""]
    c120 = r["learning_curve"]["120"]["trusted_coverage"] if "120" in r["learning_curve"] else None
    lines += [f"- With few runs the GP's interval is over-confident (the marginal likelihood fits noise it cannot "
              f"tell from signal); widening it to hold the mesh model's answer (the *union*) covers the solver far "
              f"more often at 15-60 designs, and as often at 120"
              + (f" ({c120['union']['covered']} / 30)" if c120 else "") + ".", ""]
    cov = r["coverage_in_range"]
    lines += ["**Limit calls** (`--yield-mpa Y`, `--verify auto`: the solver runs where the trusted interval "
              "straddles Y and its call is final there; a pass is unsafe where the solver fails):", ""]
    table, totals = sweeps_table(r)
    lines += table + [""]
    points = 11 * len(r["sweeps"])
    chosen = "union"
    lines += [f"- In-range coverage of the trusted interval: GP {cov['surrogate']['covered']} / 30, union "
              f"{cov['union']['covered']} / 30, ±60 % band {cov['model']['covered']} / 30 (goal "
              f"{COVERAGE_GOAL:.0%}); outside the ranges {r['coverage_outside']['union']['covered']} / 16 (union).",
              f"- Unsafe final calls over {points} sweep points: GP {totals['surrogate']['unsafe']}, union "
              f"{totals['union']['unsafe']}, HCMT alone {totals['model_alone']['unsafe']}. Solver runs: GP "
              f"{totals['surrogate']['solver_runs']}, union {totals['union']['solver_runs']}, ±60 % band "
              f"{totals['model']['solver_runs']}.",
              f"- hcmt trusts the **{chosen}** (`TRUST` in hcmt.design.check): at 120 designs it covers as the GP "
              f"does and makes no unsafe call, for {totals['union']['solver_runs'] - totals['surrogate']['solver_runs']} "
              f"more solver runs over {points} points; with a user's own surrogate on fewer runs it is the one that "
              f"stays near its nominal coverage (learning curve above).", ""]
    g = r["ghost"]
    lines += ["**Ghost stress** (median over the 46 held-out designs of |model − solver| in (mean plate stress over "
              "the last 10 frames) ÷ peak; the solver's own median ratio is "
              f"{g['solver_median']:.2f}):", "",
              "| read-out | ghost difference (all / in range) | peak frames where the solver's ball is gone and its plate "
              "unloaded | peak plate stress error, median / worst |", "|---|---|---|---|"]
    names = {"learned": "learned head, every frame (hcmt 0.1)", "contact_own": "contact window of the model's own ball",
             "contact": "contact window bounded by the GP's contact end (default)",
             "element": "element law on predicted positions"}
    for key in ("learned", "contact_own", "contact", "element"):
        v = g[key]
        bad = v["peaks_where_solver_unloaded"]
        lines.append(f"| {names[key]} | {v['median_abs_diff']:.3f} / {v['median_abs_diff_in_range']:.3f} | "
                     f"{len(bad)}{' (' + ', '.join(bad[:4]) + (', ...' if len(bad) > 4 else '') + ')' if bad else ''} | "
                     f"{_err(v['peak_error'])} |")
    ok = g["contact"]["median_abs_diff"] <= GHOST_GOAL
    lines += ["", f"- The default read-out {'meets' if ok else 'misses'} the goal of {GHOST_GOAL:.2f} "
              f"({g['contact']['median_abs_diff']:.3f}). The ghost's cause is kinematic: the learned ball rebounds "
              f"late (where the solver's ball leaves within the window, {g['contact_end_lag_frames']['designs']} designs, the "
              f"learned one leaves a median {g['contact_end_lag_frames']['median']:.0f} frames later, "
              f"{g['contact_end_lag_frames']['min']} to {g['contact_end_lag_frames']['max']}), so a "
              "window read from the model's own contact keeps its stress; the response surface predicts when the "
              "solver's ball leaves (`contact_end_ms`) and its upper 95 % bound ends the window. After it, the "
              "plate's stress is its free-vibration bending stress `k E t w_max / R²` from the predicted "
              "deflection (hcmt.design.readout).",
              f"- Peaks read where the solver's plate is unloaded: {len(g['contact']['peaks_where_solver_unloaded'])}"
              f" with the default read-out"
              + (f" ({', '.join(g['contact']['peaks_where_solver_unloaded'])}: outside the training ranges, where the "
                 "GP's contact end extrapolates late)" if g["contact"]["peaks_where_solver_unloaded"] else "") + ".",
              "- The element law on predicted positions is no candidate: a micrometre of position error across a "
              "0.3 mm element is a strain of 3e-3, hundreds of MPa in glass.", ""]
    t = r["time_of_peak"]
    lines += [f"**Time of the peak**: the first frame at 95 % of the peak is off by a median "
              f"{t['t95_frames_off_median']:.1f} frames, the argmax frame by {t['argmax_frames_off_median']:.1f}; the "
              f"critical node's stress history (the solver's peak node), model against solver, correlates with a "
              f"median {t['critical_node_correlation_median']:.2f} (lowest {t['critical_node_correlation_min']:.2f}) "
              f"over {t['designs']} designs.", ""]
    n = r["note"]
    rules = [k for k in n if isinstance(n[k], dict) and "hit_rate" in n[k]]
    lines += [f"**The low-confidence note** (a peak plate stress error above {n['large_error_pct']:.0f} % is large; "
              f"threshold tuned on the dataset's {n['tuned_on']} valid + test designs, judged on {n['judged_on']} "
              "others):", "", "| rule | large errors flagged | false alarms |", "|---|---|---|"]
    for k in rules:
        v = n[k]
        lines.append(f"| {k} | {v['hits']} / {v['large_errors']} | {v['false_alarms']} / {v['small_errors']} |")
    best = min((k for k in rules if (n[k]["hit_rate"] or 0) >= NOTE_GOAL), key=lambda k: n[k]["false_alarm_rate"],
               default=None)
    lines += ["", f"- hcmt uses the rule with the fewest false alarms among those that flag at least "
              f"{NOTE_GOAL:.0%} of the large errors: **{best}** (`NOTE_DISAGREEMENT`); without a surrogate the "
              "card's regions." if best else "- No rule reached the goal.", ""]
