"""docs/RESULTS.md's section "Panel families: transfer", from benchmarks/results/transfer.json
(``python benchmarks/transfer/run.py``). Every verdict is computed from the numbers the table prints."""
from __future__ import annotations

import numpy as np

from report_common import SHIPPED_STEPS, command, said, sentences

DATA = ("hcmt generate impact-plate /work/data/fam_train --preset small --family mono,stack2,ring --train 60 "
        "--valid 6 --test 12 --seed 7 --frames 90\n"
        "hcmt generate impact-plate /work/data/fam_stack3 --preset small --family stack3 --train 20 --valid 2 "
        "--test 8 --seed 8 --frames 90\n"
        "hcmt generate impact-plate /work/data/fam_pen --preset small --family pen --train 20 --valid 2 --test 8 "
        "--seed 9 --frames 90")
MODELS = (("hcmt", "HCMT"), ("mgn", "MGN"))
LR = "1e-3, decaying to 1e-5"  # the config's schedule (impact_plate_cpu)
NEXT = ("A tenth of that learning rate, or more runs, is the next thing to measure; it was not run in this "
        "session.")


def _seeds(rows: dict, model: str, tail: str) -> list[dict]:
    return [v for k, v in sorted(rows.items()) if k.startswith(f"{model}_s") and k.endswith(tail)
            and k[len(model) + 2:-len(tail)].isdigit()]


def _pair(values: list[float], fmt: str = "{:.1f}") -> str:
    """``mean (a / b)``: the mean over seeds and each seed's value."""
    if not values:
        return "-"
    each = " / ".join(fmt.format(v) for v in values)
    return fmt.format(float(np.mean(values))) + (f" ({each})" if len(values) > 1 else "")


def _row(label: str, runs: str, got: list[dict], mesh: bool) -> str:
    if not got:
        return f"| {label} | {runs} | not run | - | - | - | - | - |"
    if not got[0].get("designs"):
        return f"| {label} | {runs} | cannot answer: its training designs held {', '.join(got[0]['cannot_take'])} " \
               "fixed | - | - | - | - | - |"
    peak = _pair([g["peak"]["median_abs"] for g in got]) + " / " + _pair(
        [abs(g["peak"]["worst"]) for g in got])
    defl = _pair([g["deflection"]["median_abs"] for g in got]) + " / " + _pair(
        [abs(g["deflection"]["worst"]) for g in got])
    crit = (_pair([g["critical_mm"]["median"] for g in got], "{:.2f}") + " / "
            + _pair([g["critical_mm"]["worst"] for g in got], "{:.2f}")) if mesh else "-"
    rmse = _pair([g["stress_rmse_all"] / 1e3 for g in got], "{:.1f}") if mesh else "-"
    rebound = _pair([100 * g["rebound_agreement"] for g in got], "{:.0f}") + " %" if mesh else "-"
    secs = float(np.mean([g["s_per_design"] for g in got]))
    return f"| {label} | {runs} | {peak} | {defl} | {crit} | {rmse} | {rebound} | {secs:.3g} |"


def table(r: dict, key: str, title: str, shots: list[int], base_runs: int) -> list[str]:
    rows = r["rows"]
    judged = max([v.get("designs", 0) for k, v in rows.items() if f"_{key}_" in k and "designs" in v] or [0])
    out = [f"**{title}** ({judged} held-out designs of the family; mesh models: mean over the seeds, each seed in "
           "brackets)", "",
           "| approach | solver runs of this family | peak plate stress, median / worst error % | deflection, median / "
           "worst % | critical location, median / worst mm | stress RMSE-all ×10⁻³ | rebound agrees | s per design |",
           "|---|---|---|---|---|---|---|---|"]
    for model, name in MODELS:
        out.append(_row(f"{name} zero-shot", f"0 (trained on {base_runs} of other families)",
                        _seeds(rows, model, f"_{key}_zero"), True))
        for n in shots:
            out.append(_row(f"{name} fine-tuned on {n}", f"{n}", _seeds(rows, model, f"_{key}_{n}"), True))
    out.append(_row("GP fitted on the training families", "0", [rows[f"gp_{key}_zero"]] if f"gp_{key}_zero" in rows
                    else [], False))
    for n in shots:
        g = rows.get(f"gp_{key}_{n}")
        label = f"GP fitted on {n}" + (f" ({g['parameters']} parameters: underdetermined)" if g and
                                        g.get("underdetermined") else "")
        out.append(_row(label, f"{n}", [g] if g else [], False))
    solver = rows.get(f"solver_{key}", {}).get("s")
    if solver:
        out.append(f"| solver | every design | 0 | 0 | 0 | 0 | 100 % | {solver:.3g} |")
    return out + [""]


def _mean(rows: dict, model: str, tail: str, what: str) -> float | None:
    got = _seeds(rows, model, tail)
    return float(np.mean([g[what]["median_abs"] for g in got])) if got and got[0].get("designs") else None


def _flag(cmd: str, name: str) -> str:
    """The value of ``--name`` in the benchmark's command."""
    return cmd.split(f"--{name} ")[1].split()[0]


def _peak(rows: dict, key: str, n) -> float | None:
    return rows.get(f"gp_{key}_{n}", {}).get("peak", {}).get("median_abs")


def verdicts(r: dict, key: str, shots: list[int]) -> list[str]:
    """Who wins peak plate stress and deflection (median error) at each budget, and what fine-tuning did."""
    rows, out = r["rows"], []
    for n in shots:
        gp = rows.get(f"gp_{key}_{n}", {}).get("deflection", {}).get("median_abs")
        mesh = {name: _mean(rows, m, f"_{key}_{n}", "deflection") for m, name in MODELS}
        mesh = {k: v for k, v in mesh.items() if v is not None}
        if gp is not None and mesh:
            best = min(mesh, key=mesh.get)
            out.append(f"- {key}, {n} runs, deflection: GP {gp:.1f} %, best mesh model ({best}) {mesh[best]:.1f} % "
                       f"median error.")
    for m, name in MODELS:
        zero = _mean(rows, m, f"_{key}_zero", "peak")
        tuned = {n: _mean(rows, m, f"_{key}_{n}", "peak") for n in shots}
        if zero is not None and all(v is not None for v in tuned.values()):
            trend = ", ".join(f"{v:.1f} % after {n} runs" for n, v in tuned.items())
            worse = [n for n, v in tuned.items() if v > zero]
            out.append(f"- {name} on {key}: {zero:.1f} % zero-shot, {trend}"
                       + (f"; fine-tuning on {said([str(n) for n in worse])} runs made the median peak error worse "
                          "than none" if worse else "") + ".")
    for n in shots:
        mesh = {name: v for m, name in MODELS if (v := _mean(rows, m, f"_{key}_{n}", "peak")) is not None}
        gp = _peak(rows, key, n)
        if not mesh or gp is None:
            continue
        best = min(mesh, key=mesh.get)
        winner = f"the {best} fine-tuned on them ({mesh[best]:.1f} %)" if mesh[best] < gp else \
            f"the GP ({gp:.1f} % against the {best}'s {mesh[best]:.1f} %)"
        out.append(f"- {key}, {n} runs: median peak-stress error is lowest for {winner}.")
    zero = {name: v for m, name in MODELS if (v := _mean(rows, m, f"_{key}_zero", "peak")) is not None}
    if zero:
        best = min(zero, key=zero.get)
        can = rows.get(f"gp_{key}_zero", {}).get("designs")
        out.append(f"- {key}, no run of the family: the {best} answers zero-shot with a {zero[best]:.1f} % median "
                   "peak error; the response surface of the training families "
                   + ("cannot answer at all (the new parameters were fixed in all its designs)." if not can else
                      f"answers with {rows[f'gp_{key}_zero']['peak']['median_abs']:.1f} %."))
    return out


def transfer(lines: list[str], r: dict | None) -> None:
    lines += ["## Panel families: transfer", ""]
    if r is None:
        lines += ["Not run yet: `python benchmarks/transfer/run.py` (its docstring has the data commands).", ""]
        return
    shots = sorted({int(k.rsplit("_", 1)[1]) for k in r["rows"] if k.startswith("gp_") and
                    k.rsplit("_", 1)[1].isdigit()})
    base = r["rows"].get("gp_base", {}).get("fitted_on", "?")
    lines += ["The data (docs/solver.md, \"Panel families\"):", "", "```bash", DATA, "```", "", "```bash",
              command(r), "```", "",
              f"Trained on the families {', '.join(r['train_families'])} ({base} runs, the ball); judged on designs "
              f"of those families and of {', '.join(r['new_families'])}, never trained on. Device: {r['device']}. "
              "Critical location: the distance at rest between the nodes of the model's and the solver's peak "
              "plate stress.", ""]
    held = {m: _seeds(r["rows"], m, "_base") for m, _ in MODELS}
    lines += ["**The training families' held-out designs**", "",
              "| approach | solver runs | peak plate stress, median / worst error % | deflection, median / worst % | "
              "critical location, median / worst mm | stress RMSE-all ×10⁻³ | rebound agrees | s per design |",
              "|---|---|---|---|---|---|---|---|"]
    for m, name in MODELS:
        lines.append(_row(name, f"{base}", held[m], True))
    if "gp_base" in r["rows"]:
        lines.append(_row("GP", f"{base}", [r["rows"]["gp_base"]], False))
    lines.append("")
    for key in r["new_families"]:
        lines += table(r, key, f"{key}, a family never trained on", shots, base)
        lines += verdicts(r, key, shots) + [""]
    lines += analysis(r, shots)


def analysis(r: dict, shots: list[int]) -> list[str]:
    """The section's reading: where a mesh model earned its place in this benchmark and where it did not."""
    rows, out = r["rows"], ["**Reading it.**", ""]
    zero = {k: _mean(rows, "hcmt", f"_{k}_zero", "peak") for k in r["new_families"]}
    fams = [k for k in r["new_families"] if zero[k] is not None and _peak(rows, k, shots[0]) is not None]
    if fams:
        out.append("- " + zero_shot(rows, fams, zero, shots[0]))
    wins = [(k, n) for k in fams for n in shots if _peak(rows, k, n) is not None
            and all(v is None or _peak(rows, k, n) < v
                    for v in (_mean(rows, m, f"_{k}_{n}", "peak") for m, _ in MODELS))]
    base = _mean(rows, "hcmt", "_base", "deflection")
    if base is not None:
        out.append("- " + deflection(r, fams, shots, base, wins))
    tuned = [(m, k, n) for m, _ in MODELS for k in fams for n in shots
             if _mean(rows, m, f"_{k}_{n}", "peak") is not None and _mean(rows, m, f"_{k}_zero", "peak") is not None]
    rose = [t for t in tuned
            if _mean(rows, t[0], f"_{t[1]}_{t[2]}", "peak") > _mean(rows, t[0], f"_{t[1]}_zero", "peak")]
    if tuned:
        out.append("- " + sentences(
            f"**Fine-tuning as run here**: in {len(rose)} of {len(tuned)} (model, family, runs) cases the median peak "
            "error after fine-tuning is above the zero-shot one.",
            f"Each fine-tune restarts the schedule at the config's learning rate ({LR} over its "
            f"{_flag(r['command'], 'ft-steps')} steps) on {' or '.join(map(str, shots))} trajectories with the "
            "normalizers frozen.",
            NEXT if 2 * len(rose) > len(tuned) else ""))
    steps = int(_flag(r["command"], "steps"))
    seeds = len(_seeds(rows, "hcmt", "_base"))
    out.append("- " + sentences(f"**The budget**: every mesh model here trained {steps} steps on one CPU thread, "
                                f"{seeds} seeds (the shipped model: {SHIPPED_STEPS:,} steps).",
                                "The numbers bound what this budget buys, not what the architecture can do."
                                if steps < SHIPPED_STEPS else ""))
    return out + [""]


def zero_shot(rows: dict, fams: list[str], zero: dict, few: int) -> str:
    """A family with no solver runs: the mesh model answers zero-shot, the response surface of the training families
    cannot take a parameter they never varied."""
    silent = [k for k in fams if not rows.get(f"gp_{k}_zero", {}).get("designs")]
    reach = [k for k in fams if zero[k] <= _peak(rows, k, few)]
    rest = [k for k in fams if k not in reach]
    return sentences("Where a mesh model earned its place here: a family with **no solver runs at all**." if silent
                     else "",
                     f"The response surface of the training families gives no answer on {said(silent)}: it was "
                     "fitted on designs that never varied their parameters." if silent else "",
                     "HCMT answers zero-shot with a median peak plate stress error of "
                     + ", ".join(f"{zero[k]:.1f} % on {k}" for k in fams) + ".",
                     f"The GP's, once {few} runs of the family exist: "
                     + ", ".join(f"{_peak(rows, k, few):.1f} % on {k}" for k in fams) + ".",
                     f"Zero-shot is as good as those runs on {said(reach) if reach else 'none of them'} and worse on "
                     f"{said(rest) if rest else 'none'}.")


def deflection(r: dict, fams: list[str], shots: list[int], base: float, wins: list) -> str:
    """Where a mesh model did not earn its place: deflection, and peak stress once the family has runs."""
    rows, most = r["rows"], shots[-1]
    mesh = {k: _mean(rows, "hcmt", f"_{k}_zero", "deflection") for k in fams}
    gp = {k: rows.get(f"gp_{k}_{most}", {}).get("deflection", {}).get("median_abs") for k in fams}
    both = [k for k in fams if mesh[k] is not None and gp[k] is not None]
    lost = (["**deflection**"] if both and all(gp[k] < min(mesh[k], base) for k in both) else []) + (
        ["**peak stress once the family has runs**"] if 2 * len(wins) > len(fams) * len(shots) else [])
    return sentences(f"Where it did not: {said(lost)}." if lost else "",
                     f"HCMT's median deflection error is {base:.1f} % even on its training families' held-out designs, "
                     + ", ".join(f"{mesh[k]:.1f} % zero-shot on {k}" for k in both) + ".",
                     f"The GP's on {most} runs: " + ", ".join(f"{gp[k]:.1f} % on {k}" for k in both) + ".",
                     f"On peak stress once the family has runs, the GP's median error is the lowest in {len(wins)} of "
                     f"the {len(fams) * len(shots)} (family, runs) cases.")
