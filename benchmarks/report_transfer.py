"""docs/RESULTS.md's section "Panel families: transfer", from benchmarks/results/transfer.json
(``python benchmarks/transfer.py``). Every verdict is computed from the numbers the table prints."""
from __future__ import annotations

import numpy as np

DATA = ("hcmt generate impact-plate fam_train --preset small --family mono,stack2,ring --train 60 --valid 6 "
        "--test 12 --seed 7 --frames 90\n"
        "hcmt generate impact-plate fam_stack3 --preset small --family stack3 --train 20 --valid 2 --test 8 "
        "--seed 8 --frames 90\n"
        "hcmt generate impact-plate fam_pen --preset small --family pen --train 20 --valid 2 --test 8 --seed 9 "
        "--frames 90")
MODELS = (("hcmt", "HCMT"), ("mgn", "MGN"))


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
    crit = _pair([g["critical_mm"]["median"] for g in got], "{:.2f}") if mesh else "-"
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
           "worst % | critical location, median mm | stress RMSE-all ×10⁻³ | rebound agrees | s per design |",
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


def verdicts(r: dict, key: str, shots: list[int]) -> list[str]:
    """Who wins peak plate stress (median error) at each budget, measured."""
    rows, out = r["rows"], []
    for n in shots:
        mesh = {name: float(np.mean([g["peak"]["median_abs"] for g in _seeds(rows, m, f"_{key}_{n}")]))
                for m, name in MODELS if _seeds(rows, m, f"_{key}_{n}")}
        gp = rows.get(f"gp_{key}_{n}", {}).get("peak", {}).get("median_abs")
        if not mesh or gp is None:
            continue
        best = min(mesh, key=mesh.get)
        winner = f"the {best} fine-tuned on them ({mesh[best]:.1f} %)" if mesh[best] < gp else \
            f"the GP ({gp:.1f} % against the {best}'s {mesh[best]:.1f} %)"
        out.append(f"- {key}, {n} runs: median peak-stress error is lowest for {winner}.")
    zero = {name: float(np.mean([g["peak"]["median_abs"] for g in _seeds(rows, m, f"_{key}_zero")]))
            for m, name in MODELS if _seeds(rows, m, f"_{key}_zero")}
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
        lines += ["Not run yet: `python benchmarks/transfer.py` (its docstring has the data commands).", ""]
        return
    shots = sorted({int(k.rsplit("_", 1)[1]) for k in r["rows"] if k.startswith("gp_") and
                    k.rsplit("_", 1)[1].isdigit()})
    base = r["rows"].get("gp_base", {}).get("fitted_on", "?")
    lines += ["The data (docs/solver.md, \"Panel families\"):", "", "```bash", DATA, "```", "", "```bash",
              r["command"], "```", "",
              f"Trained on the families {', '.join(r['train_families'])} ({base} runs, the ball); judged on designs "
              f"of those families and of {', '.join(r['new_families'])}, never trained on. Device: {r['device']}. "
              "Critical location: the distance at rest between the nodes of the model's and the solver's peak "
              "plate stress.", ""]
    held = {m: _seeds(r["rows"], m, "_base") for m, _ in MODELS}
    lines += ["**The training families' held-out designs**", "",
              "| approach | solver runs | peak plate stress, median / worst error % | deflection, median / worst % | "
              "critical location, median mm | stress RMSE-all ×10⁻³ | rebound agrees | s per design |",
              "|---|---|---|---|---|---|---|---|"]
    for m, name in MODELS:
        lines.append(_row(name, f"{base}", held[m], True))
    if "gp_base" in r["rows"]:
        lines.append(_row("GP", f"{base}", [r["rows"]["gp_base"]], False))
    lines.append("")
    for key in r["new_families"]:
        lines += table(r, key, f"{key}, a family never trained on", shots, base)
        lines += verdicts(r, key, shots) + [""]
