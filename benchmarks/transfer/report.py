"""docs/RESULTS.md's sections "Panel families: transfer", from benchmarks/results/transfer.json
(``python benchmarks/transfer/run.py``), and "Panel families: transfer from a given model", from
benchmarks/results/transfer_shipped.json (``run.py --base NAME=RUN``). Every verdict is computed from the numbers the
table prints."""

from __future__ import annotations

import numpy as np

from report_common import SHIPPED_STEPS, command, said, sentences

DATA = (
    "hcmt generate impact-plate $HCMT_WORK/data/fam_train --preset small --family mono,stack2,ring --train 60 "
    "--valid 6 --test 12 --seed 7 --frames 90\n"
    "hcmt generate impact-plate $HCMT_WORK/data/fam_stack3 --preset small --family stack3 --train 20 --valid 2 "
    "--test 8 --seed 8 --frames 90\n"
    "hcmt generate impact-plate $HCMT_WORK/data/fam_pen --preset small --family pen --train 20 --valid 2 --test 8 "
    "--seed 9 --frames 90"
)
MODELS = (("hcmt", "HCMT"), ("mgn", "MGN"))
LR = "1e-3, decaying to 1e-5"  # the config's schedule (impact_plate_cpu)
GIVEN = (
    "python benchmarks/transfer/run.py ... --base new=pretrained:impact_plate_small --ft-lr 1e-4 "
    "--json transfer_shipped.json"
)  # the form of the given-model run (transfer_given)
NEXT = "A tenth of that learning rate, or more runs, is the next thing to measure; it was not run in this session."


def _seeds(rows: dict, model: str, tail: str) -> list[dict]:
    """The rows ``{model}_s{seed}{tail}``, one per seed, in seed order."""
    return [
        v
        for k, v in sorted(rows.items())
        if k.startswith(f"{model}_s") and k.endswith(tail) and k[len(model) + 2 : -len(tail)].isdigit()
    ]


def _one(rows: dict, key: str) -> list[dict]:
    """The row ``key`` as a list of one, or none."""
    return [rows[key]] if key in rows else []


def _pair(values: list[float], fmt: str = "{:.1f}") -> str:
    """``mean (a / b)``: the mean over seeds and each seed's value."""
    if not values:
        return "-"
    each = " / ".join(fmt.format(v) for v in values)
    return fmt.format(float(np.mean(values))) + (f" ({each})" if len(values) > 1 else "")


def _row(label: str, runs: str, got: list[dict], mesh: bool) -> str:
    """One table line: the quantities of the rows ``got`` (one per seed), "not run" where there are none."""
    if not got:
        return f"| {label} | {runs} | not run | - | - | - | - | - |"
    if not got[0].get("designs"):
        return (
            f"| {label} | {runs} | cannot answer: its training designs held {', '.join(got[0]['cannot_take'])} "
            "fixed | - | - | - | - | - |"
        )
    peak = _pair([g["peak"]["median_abs"] for g in got]) + " / " + _pair([abs(g["peak"]["worst"]) for g in got])
    defl = (
        _pair([g["deflection"]["median_abs"] for g in got])
        + " / "
        + _pair([abs(g["deflection"]["worst"]) for g in got])
    )
    crit = (
        (
            _pair([g["critical_mm"]["median"] for g in got], "{:.2f}")
            + " / "
            + _pair([g["critical_mm"]["worst"] for g in got], "{:.2f}")
        )
        if mesh
        else "-"
    )
    rmse = _pair([g["stress_rmse_all"] / 1e3 for g in got], "{:.1f}") if mesh else "-"
    rebound = _pair([100 * g["rebound_agreement"] for g in got], "{:.0f}") + " %" if mesh else "-"
    secs = float(np.mean([g["s_per_design"] for g in got]))
    return f"| {label} | {runs} | {peak} | {defl} | {crit} | {rmse} | {rebound} | {secs:.3g} |"


def _head(runs: str) -> list[str]:
    """A table's header: the approach, the solver-runs column (named ``runs``), the quantities."""
    return [
        f"| approach | {runs} | peak plate stress, median / worst error % | deflection, median / worst % | "
        "critical location, median / worst mm | stress RMSE-all ×10⁻³ | rebound agrees | s per design |",
        "|---|---|---|---|---|---|---|---|",
    ]


def _shots(r: dict) -> list[int]:
    """The fine-tuning budgets (runs of a new family) of the summary's GP rows."""
    return sorted(
        {int(k.rsplit("_", 1)[1]) for k in r["rows"] if k.startswith("gp_") and k.rsplit("_", 1)[1].isdigit()}
    )


def _fitted(r: dict):
    """The training families' runs (the GP's fit on them), "?" where it is missing."""
    return r["rows"].get("gp_base", {}).get("fitted_on", "?")


def _scratch(rows: dict, key: str, shots: list[int]) -> dict[str, dict]:
    """Per model trained here (its name): its rows on family ``key`` per budget ("zero", each n), one per seed."""
    return {name: {n: _seeds(rows, m, f"_{key}_{n}") for n in ("zero", *shots)} for m, name in MODELS}


def _given(rows: dict, name: str, key: str, shots: list[int]) -> dict[str, dict]:
    """The given model's rows on family ``key`` as :func:`_scratch` has them: zero-shot once, fine-tuned per seed."""
    return {name: {"zero": _one(rows, f"{name}_{key}_zero"), **{n: _seeds(rows, name, f"_{key}_{n}") for n in shots}}}


def held_out(rows: dict, mesh: list[tuple[str, str, list[dict]]], base) -> list[str]:
    """The table of the training families' held-out designs: each mesh model's line (label, solver runs, its rows),
    then the GP's."""
    return (
        ["**The training families' held-out designs**", "", *_head("solver runs")]
        + [_row(label, runs, got, True) for label, runs, got in mesh]
        + [_row("GP", f"{base}", _one(rows, "gp_base"), False), ""]
    )


def _references(rows: dict, key: str, shots: list[int]) -> list[str]:
    """The GP's lines on family ``key`` (fitted on the training families, then on each n of its runs) and the
    solver's."""
    out = [_row("GP fitted on the training families", "0", _one(rows, f"gp_{key}_zero"), False)]
    for n in shots:
        g = rows.get(f"gp_{key}_{n}")
        label = f"GP fitted on {n}" + (
            f" ({g['parameters']} parameters: underdetermined)" if g and g.get("underdetermined") else ""
        )
        out.append(_row(label, f"{n}", [g] if g else [], False))
    solver = rows.get(f"solver_{key}", {}).get("s")
    return out + [
        f"| solver | every design | 0 | 0 | 0 | 0 | 100 % | {solver:.3g} |"
        if solver
        else "| solver | every design | not run | - | - | - | - | - |"
    ]


def table(r: dict, key: str, title: str, shots: list[int], mesh: dict[str, dict], zero_runs: str) -> list[str]:
    """The table of family ``key``: each mesh model's zero-shot and fine-tuned lines (``mesh`` as :func:`_scratch`
    gives it; ``zero_runs``: the zero-shot line's solver runs), then the GP's and the solver's."""
    rows = r["rows"]
    judged = max([v.get("designs", 0) for k, v in rows.items() if f"_{key}_" in k and "designs" in v] or [0])
    out = [
        f"**{title}** ({judged} held-out designs of the family; mesh models: mean over the seeds, each seed in "
        "brackets)",
        "",
        *_head("solver runs of this family"),
    ]
    for name, got in mesh.items():
        out.append(_row(f"{name} zero-shot", zero_runs, got["zero"], True))
        out += [_row(f"{name} fine-tuned on {n}", f"{n}", got[n], True) for n in shots]
    return out + _references(rows, key, shots) + [""]


def _avg(got: list[dict], what: str) -> float | None:
    """The mean over the rows ``got`` (one per seed) of the median |error| of ``what``; None where none judged."""
    return float(np.mean([g[what]["median_abs"] for g in got])) if got and got[0].get("designs") else None


def _mean(rows: dict, model: str, tail: str, what: str) -> float | None:
    """:func:`_avg` of a model trained here, its rows ``{model}_s{seed}{tail}``."""
    return _avg(_seeds(rows, model, tail), what)


def _flag(cmd: str, name: str) -> str:
    """The value of ``--name`` in the benchmark's command."""
    return cmd.split(f"--{name} ")[1].split()[0]


def _peak(rows: dict, key: str, n) -> float | None:
    return rows.get(f"gp_{key}_{n}", {}).get("peak", {}).get("median_abs")


def _tuning(name: str, key: str, got: dict, shots: list[int]) -> list[str]:
    """A bullet: ``name``'s median peak error on ``key`` zero-shot and after each fine-tuning that was judged, and
    which fine-tunings made it worse than none (``got`` as :func:`_scratch` gives one model's)."""
    zero = _avg(got["zero"], "peak")
    tuned = {n: v for n in shots if (v := _avg(got[n], "peak")) is not None}
    if zero is None:
        return []
    trend = "".join(f", {v:.1f} % after {n} runs" for n, v in tuned.items())
    worse = [n for n, v in tuned.items() if v > zero]
    return [
        f"- {name} on {key}: {zero:.1f} % zero-shot{trend}"
        + (
            f"; fine-tuning on {said([str(n) for n in worse])} runs made the median peak error worse than none"
            if worse
            else ""
        )
        + "."
    ]


def verdicts(r: dict, key: str, shots: list[int]) -> list[str]:
    """Who wins peak plate stress and deflection (median error) at each budget, and what fine-tuning did."""
    rows, models, out = r["rows"], _scratch(r["rows"], key, shots), []
    for n in shots:
        gp = rows.get(f"gp_{key}_{n}", {}).get("deflection", {}).get("median_abs")
        mesh = {name: v for name, got in models.items() if (v := _avg(got[n], "deflection")) is not None}
        if gp is not None and mesh:
            best = min(mesh, key=mesh.get)
            out.append(
                f"- {key}, {n} runs, deflection: GP {gp:.1f} %, best mesh model ({best}) {mesh[best]:.1f} % "
                f"median error."
            )
    for name, got in models.items():
        out += _tuning(name, key, got, shots)
    for n in shots:
        mesh = {name: v for name, got in models.items() if (v := _avg(got[n], "peak")) is not None}
        gp = _peak(rows, key, n)
        if not mesh or gp is None:
            continue
        best = min(mesh, key=mesh.get)
        winner = (
            f"the {best} fine-tuned on them ({mesh[best]:.1f} %)"
            if mesh[best] < gp
            else f"the GP ({gp:.1f} % against the {best}'s {mesh[best]:.1f} %)"
        )
        out.append(f"- {key}, {n} runs: median peak-stress error is lowest for {winner}.")
    zero = {name: v for name, got in models.items() if (v := _avg(got["zero"], "peak")) is not None}
    if zero:
        best = min(zero, key=zero.get)
        can = rows.get(f"gp_{key}_zero", {}).get("designs")
        out.append(
            f"- {key}, no run of the family: the {best} answers zero-shot with a {zero[best]:.1f} % median "
            "peak error; the response surface of the training families "
            + (
                "cannot answer at all (the new parameters were fixed in all its designs)."
                if not can
                else f"answers with {rows[f'gp_{key}_zero']['peak']['median_abs']:.1f} %."
            )
        )
    return out


def transfer(lines: list[str], r: dict | None) -> None:
    """The section "Panel families: transfer": the models trained here from scratch (the summary of ``run.py``
    without ``--base``)."""
    lines += ["## Panel families: transfer", ""]
    if r is None:
        lines += ["Not run yet: `python benchmarks/transfer/run.py` (its docstring has the data commands).", ""]
        return
    shots, base = _shots(r), _fitted(r)
    lines += [
        'The data (docs/solver.md, "Panel families"):',
        "",
        "```bash",
        DATA,
        "```",
        "",
        "```bash",
        command(r),
        "```",
        "",
        f"Trained on the families {', '.join(r['train_families'])} ({base} runs, the ball); judged on designs "
        f"of those families and of {', '.join(r['new_families'])}, never trained on. Device: {r['device']}. "
        "Critical location: the distance at rest between the nodes of the model's and the solver's peak "
        "plate stress.",
        "",
    ]
    lines += held_out(r["rows"], [(name, f"{base}", _seeds(r["rows"], m, "_base")) for m, name in MODELS], base)
    for key in r["new_families"]:
        lines += table(
            r,
            key,
            f"{key}, a family never trained on",
            shots,
            _scratch(r["rows"], key, shots),
            f"0 (trained on {base} of other families)",
        )
        lines += verdicts(r, key, shots) + [""]
    lines += analysis(r, shots)


def _number(x: float) -> str:
    """``x`` in short scientific form: 1e-4, 2.5e-4."""
    mantissa, exponent = f"{x:e}".split("e")
    return f"{float(mantissa):g}e{int(exponent)}"


def _lowest(quantity: str, name: str, mine: float | None, gp: float | None) -> str:
    """Who of the fine-tuned given model (median error ``mine``) and the GP has the lower median error, as printed."""
    if mine is None or gp is None:
        return ""
    a, b = round(mine, 1), round(gp, 1)
    if a == b:
        return f"the median {quantity} error is the same for both ({a:.1f} %)"
    won, lost = (f"{name} fine-tuned", "the GP's") if a < b else ("the GP", f"{name} fine-tuned's")
    return f"the lowest median {quantity} error is {won}'s ({min(a, b):.1f} % against {lost} {max(a, b):.1f} %)"


def given_verdicts(rows: dict, key: str, shots: list[int], mesh: dict[str, dict]) -> list[str]:
    """The given model's fine-tuning bullet on family ``key`` (:func:`_tuning`) and, per budget, who of it and the
    GP has the lowest median peak plate stress and deflection error."""
    [(name, got)] = mesh.items()
    out = _tuning(name, key, got, shots)
    for n in shots:
        parts = [
            s
            for what, quantity in (("peak", "peak plate stress"), ("deflection", "deflection"))
            if (
                s := _lowest(
                    quantity, name, _avg(got[n], what), rows.get(f"gp_{key}_{n}", {}).get(what, {}).get("median_abs")
                )
            )
        ]
        if parts:
            out.append(f"- {key}, {n} runs: " + "; ".join(parts) + ".")
    return out


def _given_intro(r: dict, name: str, run: str, shots: list[int], base) -> list[str]:
    """The command, the given model, the fine-tuning's learning rate, the families and the device."""
    lr = f"{_number(r['ft_lr'])}, decaying to {_number(r['ft_lr'] / 10)}" if r.get("ft_lr") is not None else LR
    return [
        "```bash",
        command(r),
        "```",
        "",
        f"The base is the given model **{name}** (`{run}`), not trained here. It is judged as it is on the "
        f"held-out designs of the training families {', '.join(r['train_families'])} (the GP: fitted on their "
        f"{base} runs) and zero-shot on the new families {', '.join(r['new_families'])}, then fine-tuned once per "
        f"seed on the first {' or '.join(map(str, shots))} runs of each new family at a learning rate of {lr} "
        f"over {_flag(r['command'], 'ft-steps')} steps, the normalizers kept. Device: {r['device']}.",
        "",
    ]


def transfer_given(lines: list[str], r: dict | None) -> None:
    """The section "Panel families: transfer from a given model" (the summary of ``run.py --base NAME=RUN``): the
    given model on the training families' held-out designs, then per new family its zero-shot and fine-tuned lines
    against the GP and the solver, and the verdicts; one line where it was not run."""
    lines += ["## Panel families: transfer from a given model", ""]
    if r is None:
        lines += [f"Not run yet: `{GIVEN}`.", ""]
        return
    (name, run), rows, shots, base = r["base"].split("=", 1), r["rows"], _shots(r), _fitted(r)
    lines += _given_intro(r, name, run, shots, base)
    lines += held_out(rows, [(name, "- (given model)", _one(rows, f"{name}_base"))], base)
    for key in r["new_families"]:
        mesh = _given(rows, name, key, shots)
        lines += table(r, key, f"{key}, a new family", shots, mesh, "0 (given model)")
        lines += given_verdicts(rows, key, shots, mesh) + [""]


def analysis(r: dict, shots: list[int]) -> list[str]:
    """The section's reading: where a mesh model earned its place in this benchmark and where it did not."""
    rows, out = r["rows"], ["**Reading it.**", ""]
    zero = {k: _mean(rows, "hcmt", f"_{k}_zero", "peak") for k in r["new_families"]}
    fams = [k for k in r["new_families"] if zero[k] is not None and _peak(rows, k, shots[0]) is not None]
    if fams:
        out.append("- " + zero_shot(rows, fams, zero, shots[0]))
    wins = [
        (k, n)
        for k in fams
        for n in shots
        if _peak(rows, k, n) is not None
        and all(v is None or _peak(rows, k, n) < v for v in (_mean(rows, m, f"_{k}_{n}", "peak") for m, _ in MODELS))
    ]
    base = _mean(rows, "hcmt", "_base", "deflection")
    if base is not None:
        out.append("- " + deflection(r, fams, shots, base, wins))
    tuned = [
        (m, k, n)
        for m, _ in MODELS
        for k in fams
        for n in shots
        if _mean(rows, m, f"_{k}_{n}", "peak") is not None and _mean(rows, m, f"_{k}_zero", "peak") is not None
    ]
    rose = [
        t for t in tuned if _mean(rows, t[0], f"_{t[1]}_{t[2]}", "peak") > _mean(rows, t[0], f"_{t[1]}_zero", "peak")
    ]
    if tuned:
        out.append(
            "- "
            + sentences(
                f"**Fine-tuning as run here**: in {len(rose)} of {len(tuned)} (model, family, runs) cases the median "
                "peak error after fine-tuning is above the zero-shot one.",
                f"Each fine-tune restarts the schedule at the config's learning rate ({LR} over its "
                f"{_flag(r['command'], 'ft-steps')} steps) on {' or '.join(map(str, shots))} trajectories with the "
                "normalizers frozen.",
                NEXT if 2 * len(rose) > len(tuned) else "",
            )
        )
    steps = int(_flag(r["command"], "steps"))
    seeds = len(_seeds(rows, "hcmt", "_base"))
    out.append(
        "- "
        + sentences(
            f"**The budget**: every mesh model here trained {steps} steps on one CPU thread, "
            f"{seeds} seeds (the shipped model: {SHIPPED_STEPS:,} steps).",
            "The numbers bound what this budget buys, not what the architecture can do."
            if steps < SHIPPED_STEPS
            else "",
        )
    )
    return out + [""]


def zero_shot(rows: dict, fams: list[str], zero: dict, few: int) -> str:
    """A family with no solver runs: the mesh model answers zero-shot, the response surface of the training families
    cannot take a parameter they never varied."""
    silent = [k for k in fams if not rows.get(f"gp_{k}_zero", {}).get("designs")]
    reach = [k for k in fams if zero[k] <= _peak(rows, k, few)]
    rest = [k for k in fams if k not in reach]
    return sentences(
        "Where a mesh model earned its place here: a family with **no solver runs at all**." if silent else "",
        f"The response surface of the training families gives no answer on {said(silent)}: it was "
        "fitted on designs that never varied their parameters."
        if silent
        else "",
        "HCMT answers zero-shot with a median peak plate stress error of "
        + ", ".join(f"{zero[k]:.1f} % on {k}" for k in fams)
        + ".",
        f"The GP's, once {few} runs of the family exist: "
        + ", ".join(f"{_peak(rows, k, few):.1f} % on {k}" for k in fams)
        + ".",
        f"Zero-shot is as good as those runs on {said(reach) if reach else 'none of them'} and worse on "
        f"{said(rest) if rest else 'none'}.",
    )


def deflection(r: dict, fams: list[str], shots: list[int], base: float, wins: list) -> str:
    """Where a mesh model did not earn its place: deflection, and peak stress once the family has runs."""
    rows, most = r["rows"], shots[-1]
    mesh = {k: _mean(rows, "hcmt", f"_{k}_zero", "deflection") for k in fams}
    gp = {k: rows.get(f"gp_{k}_{most}", {}).get("deflection", {}).get("median_abs") for k in fams}
    both = [k for k in fams if mesh[k] is not None and gp[k] is not None]
    lost = (["**deflection**"] if both and all(gp[k] < min(mesh[k], base) for k in both) else []) + (
        ["**peak stress once the family has runs**"] if 2 * len(wins) > len(fams) * len(shots) else []
    )
    return sentences(
        f"Where it did not: {said(lost)}." if lost else "",
        f"HCMT's median deflection error is {base:.1f} % even on its training families' held-out designs, "
        + ", ".join(f"{mesh[k]:.1f} % zero-shot on {k}" for k in both)
        + ".",
        f"The GP's on {most} runs: " + ", ".join(f"{gp[k]:.1f} % on {k}" for k in both) + ".",
        f"On peak stress once the family has runs, the GP's median error is the lowest in {len(wins)} of "
        f"the {len(fams) * len(shots)} (family, runs) cases.",
    )
