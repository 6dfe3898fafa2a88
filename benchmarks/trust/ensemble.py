"""The mesh model's interval from an ensemble: several members fine-tuned from the shipped weights on one
dataset (different seeds or data orders), measured against the solver on the designs ``run.py`` draws, relative to
the members' training ranges.

    python benchmarks/trust/ensemble.py --members RUN RUN [RUN ...] --work WORK [--which best]
        [--also pretrained:impact_plate_small] [--calibration-seed 5201] [--eval-seeds 5202 5203] [--inside 60]
        [--per-cell 24] [--cells thickness+ drop_height+ drop_height+,thickness+] [--distances 0.2 0.4] [--batch 8]
        [--threads 1] [--cost-designs 8] [--json trust_ensemble.json]

A member is a run folder, ``RUN@CHECKPOINT`` for another checkpoint than ``--which`` (best, checkpoint, step_N);
members must share their training ranges (one dataset) and differ in their weights. ``--also MODEL``: one more model
(e.g. the shipped one) measured on the same designs, its cells relative to the members' ranges too; its solver
settings must be the members'.

Designs, caching and measures are ``run.py``'s (imported, not copied): the designs of each seed, cell and distance as
it draws them from the members' ranges, named with a tag of those ranges in front (``r1a2b3c4d_s5202_inside_07``) so
that neither the solver's cache (``WORK/solver/``) nor a model's (``WORK/model/LABEL/``, LABEL a member's folder name,
``_CHECKPOINT`` when not best) ever holds two designs under one name. Measured:

1. **Ensemble mean**: per answer the exp of the members' mean log, the history their per-frame mean. Its errors
   (peak: median and worst absolute, signed median; deflection: median and worst absolute; history: median of the
   largest per-frame error as a share of the solver's peak) on all designs (calibration and evaluation seeds), inside
   the ranges and per outside region, beside each member's and ``--also``'s; the check inside the ranges:
   peak <= 3 % median and <= 10 % worst, deflection <= 3 % median, and no worse than ``--also``.
2. **Intervals**, calibrated on the calibration seed, measured on the evaluation seeds (coverage of peak, deflection,
   the whole history; median relative width of the peak's interval; per cell and region, as ``run.py``):
   ``raw`` mean_log +- 1.96 std_log over the members (std with ddof 1), the history the members' per-frame
   min..max, uncalibrated; ``scaled``: per cell, k = conformal quantile (``conformal_half_width``) of
   ``|log solver - mean_log| / std_log`` on the calibration seed, the interval mean_log +- k std_log; its history the
   members' min..max widened by ``BAND_FRAMES`` frames of timing (``envelope``) and by ``w_h`` x the ensemble peak,
   ``w_h`` the conformal quantile of how far the solver's history leaves that envelope (as ``history_score``);
   ``mean``: ``model_interval.fit`` applied to the ensemble mean as if it were the model; ``first``: the same applied
   to the first member alone (one model, no ensemble); ``also``: the same applied to ``--also``.
3. **Disagreement note**: scores std_log of the members' peaks and (max - min) / mean of them; the threshold is the
   largest score that still flags >= 80 % of the calibration seed's designs whose peak error (ensemble mean) is over
   10 % (none: the 90th percentile of the score); on the evaluation seeds, the > 10 % errors, the share of them
   flagged and the false alarms among the other designs; the same for the first member's error.
4. **Calls** at yield = the solver's peak x ``run.FACTORS`` (``run.calls``, the interval alone: ``model``) for the
   intervals ``scaled``, ``mean``, ``first`` (and ``also``).
5. **Cost**: ``--cost-designs`` evaluation designs predicted afresh by each member in turn (each batched over the
   designs; one thread by default): seconds per design for one member and for all, beside the solver's median per
   design from the cache, and whether the ensemble stays >= 1.5x faster than the solver.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import sys
import time
import zlib
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))  # benchmarks/trust/: run (it puts benchmarks/ on the path)
import run as trust  # noqa: E402

from common import portable  # noqa: E402
from hcmt.config import VERSION  # noqa: E402
from hcmt.config.threads import set_threads  # noqa: E402
from hcmt.design.model_interval import (  # noqa: E402
    ANSWERS,
    DISTANCE_STEP,
    LEVEL,
    MIN_DESIGNS,
    Calibration,
    ModelInterval,
    cell_of,
    conformal_half_width,
    covers,
    envelope,
    fit,
)
from hcmt.design.prediction import predict  # noqa: E402
from hcmt.design.surrogate_use import run_name  # noqa: E402
from hcmt.errors import InputError  # noqa: E402
from hcmt.files import atomic_path  # noqa: E402
from hcmt.inference.run import Run  # noqa: E402

PEAK, HISTORY, DEFL = trust.PEAK, trust.HISTORY, "max_deflection_mm"
#: the raw interval's z (95 %, normal)
Z = 1.96
#: the disagreement note: an error "large" over this (percent), the share of them it must flag on the calibration
#: seed, the score's quantile used when the calibration seed has no large error
BIG_ERROR_PCT, CATCH, FALLBACK_QUANTILE = 10.0, 0.80, 0.90
#: the requirement on the ensemble mean inside the ranges (percent): peak median, peak worst, deflection median
CHECK = {"peak_median": 3.0, "peak_worst": 10.0, "deflection_median": 3.0}
#: the speed the ensemble must keep over the solver per design
SPEEDUP = 1.5
TINY = 1e-12  # a floor of std_log: members that agree exactly on a design


# -- members ---------------------------------------------------------------------------------------------------------
def label_of(run, which: str) -> str:
    """A model's cache label, no machine path: its folder name (``pretrained_NAME``), ``_CHECKPOINT`` if not best."""
    return run_name(run).replace(":", "_") + ("" if which == "best" else f"_{which}")


def load_members(specs: list[str], which: str, p: argparse.ArgumentParser) -> list[dict]:
    """Each ``RUN[@CHECKPOINT]``: {run, label, which, name}; refused unless 2+, one set of ranges and settings, and
    different weights."""
    if len(specs) < 2:
        p.error("--members: an ensemble needs at least two runs")
    out = []
    for spec in specs:
        path, _, own = spec.partition("@") if "@" in spec and not Path(spec).exists() else (spec, "", "")
        w = own or which
        try:
            run = Run.load(path, "cpu", which=w)
        except InputError as e:
            p.error(f"--members: {spec}: {e}")
        if str(run.source).startswith("pretrained:"):
            p.error(f"--members: {spec}: members are run folders fine-tuned from the shipped weights")
        out.append({"run": run, "which": w, "label": label_of(run, w), "name": Path(path).name})
    first = out[0]["run"]
    for m in out[1:]:
        if m["run"].ranges != first.ranges:
            diff = sorted(
                k for k in set(m["run"].ranges) | set(first.ranges) if m["run"].ranges.get(k) != first.ranges.get(k)
            )
            p.error(
                f"--members: {m['name']}'s training ranges differ from {out[0]['name']}'s ({', '.join(diff)}): "
                "the members must be runs of one dataset"
            )
    keys = [
        (str(Path(str(m["run"].source)).resolve()), m["run"].info.checkpoint.file, m["run"].checkpoint_step)
        for m in out
    ]
    labels = [m["label"] for m in out]
    if len(set(keys)) < len(keys) or len(set(labels)) < len(labels):
        p.error(
            "--members: two members load the same weights (run folder, checkpoint file and step): an ensemble "
            "needs different ones (a missing best.pt falls back to checkpoint.pt)"
        )
    return out


def init_of(run) -> str | None:
    """What a member was fine-tuned from, no machine path: ``pretrained:NAME`` or a run folder's name."""
    got = (run.info.init or {}).get("from")
    return None if got is None else str(got) if str(got).startswith("pretrained:") else Path(str(got)).name


def ranges_tag(ranges: dict) -> str:
    """A short tag of the training ranges: the designs' name prefix."""
    text = json.dumps({k: [float(v) for v in ranges[k]] for k in sorted(ranges)})
    return f"r{zlib.crc32(text.encode()):08x}"


def portable_command(argv: list[str], members: list[dict]) -> str:
    """The command line with each member's path as ``$HCMT_WORK/...`` when it lies there, else its folder name."""
    specs = {}
    for m in members:
        src = str(m["run"].source)
        text = portable(src)
        specs[src] = text if text.startswith("$HCMT_WORK") else m["name"]
    out, in_members = [], False
    for tok in argv:
        if tok.startswith("--"):
            in_members = tok == "--members"
            out.append(tok)
            continue
        if in_members:
            path, _, own = tok.partition("@") if "@" in tok and not Path(tok).exists() else (tok, "", "")
            key = next((s for s in specs if Path(s).resolve() == Path(path).resolve()), None)
            out.append((specs[key] if key else Path(path).name) + (f"@{own}" if own else ""))
        else:
            out.append(portable(tok))
    return "python benchmarks/trust/ensemble.py " + " ".join(out)


# -- records ---------------------------------------------------------------------------------------------------------
def rows_of(solver: trust.Runner, runners: dict[str, trust.Runner], designs: list, seed: int, tag: str) -> list:
    """Each design's record: the solver's summary, each model's (``runners``: label -> Runner)."""
    named = [(f"{tag}_{n}", d, cell) for n, d, cell in designs]
    pairs = [(n, d) for n, d, _ in named]
    truth = solver.solver(pairs, f"solver, seed {seed}")
    models = {}
    for label, r in runners.items():
        print(f"  {label}, seed {seed}", flush=True)
        models[label] = r.model(pairs)
    return [
        {
            "name": n,
            "seed": seed,
            "design": d,
            "cell": cell,
            "direction": trust.direction_of(cell),
            "solver": truth[n],
            "models": {k: v[n] for k, v in models.items()},
        }
        for n, d, cell in named
    ]


def ensemble_of(members: list[dict]) -> dict:
    """The members' mean (per answer exp of the mean log, the history their per-frame mean) with what the intervals
    read: mean_log, std_log (ddof 1), the per-frame min and max of the histories, the peaks."""
    logs = {a: np.log([float(m[a]) for m in members]) for a in ANSWERS}
    n = min(len(m[HISTORY]) for m in members)
    hist = np.array([m[HISTORY][:n] for m in members], float)
    return {
        **{a: float(np.exp(logs[a].mean())) for a in ANSWERS},
        HISTORY: [float(v) for v in hist.mean(0)],
        "mean_log": {a: float(logs[a].mean()) for a in ANSWERS},
        "std_log": {a: float(logs[a].std(ddof=1)) for a in ANSWERS},
        "hist_min": hist.min(0),
        "hist_max": hist.max(0),
        "peaks": [float(m[PEAK]) for m in members],
    }


def view(rows: list[dict], model) -> list[dict]:
    """``run.py``'s rows with ``model`` (a function of a row) as the model: what its judge, coverage and calls read."""
    return [
        {
            "name": r["name"],
            "seed": r["seed"],
            "design": r["design"],
            "cell": r["cell"],
            "direction": r["direction"],
            "model": model(r),
            "solver": r["solver"],
            "gp": None,
            "src": r,
        }
        for r in rows
    ]


NO_CALIBRATION = Calibration("none", LEVEL, {}, {})


def attach(r: dict, iv: ModelInterval | None, band: float | None) -> None:
    """A row's own interval in ``run.judge``'s fields (the rest as judge set them)."""
    r["interval"] = iv
    r["covers"] = covers(iv, trust.as_summary(r["solver"])) if iv is not None else None
    r["width"] = (iv.bounds[PEAK][1] - iv.bounds[PEAK][0]) / r["model"][PEAK] if iv is not None else None
    r["band"] = band if iv is not None else None


# -- the ensemble's intervals ----------------------------------------------------------------------------------------
def raw_interval(e: dict, cell: str, k: float, lo_h, hi_h) -> ModelInterval:
    bounds = {
        a: (
            float(math.exp(e["mean_log"][a] - k * e["std_log"][a])),
            float(math.exp(e["mean_log"][a] + k * e["std_log"][a])),
        )
        for a in ANSWERS
    }
    return ModelInterval(cell, 0, LEVEL, bounds, [float(v) for v in np.maximum(lo_h, 0.0)], [float(v) for v in hi_h])


def members_envelope(e: dict) -> tuple[np.ndarray, np.ndarray]:
    """The members' per-frame min..max widened by BAND_FRAMES frames of timing (``model_interval.envelope``)."""
    return envelope(e["hist_min"])[0], envelope(e["hist_max"])[1]


def envelope_score(e: dict, solver: dict) -> float:
    """How far the solver's history leaves the members' envelope, at most, as a share of the ensemble's peak."""
    low, high = members_envelope(e)
    s = np.asarray(solver[HISTORY], float)
    n = min(len(low), len(s))
    return float(max(np.max(np.maximum(low[:n] - s[:n], s[:n] - high[:n])), 0.0) / e[PEAK])


def fit_scaled(rows: list[dict]) -> dict[str, dict]:
    """Per cell with MIN_DESIGNS calibration designs: k per answer and the history's w_h (module docstring)."""
    out = {}
    for cell in sorted({r["cell"] for r in rows}):
        group = [r for r in rows if r["cell"] == cell]
        if len(group) < MIN_DESIGNS:
            continue
        k = {
            a: conformal_half_width(
                [
                    abs(math.log(r["solver"][a]) - r["ens"]["mean_log"][a]) / max(r["ens"]["std_log"][a], TINY)
                    for r in group
                ]
            )
            for a in ANSWERS
        }
        band = conformal_half_width([envelope_score(r["ens"], r["solver"]) for r in group])
        out[cell] = {"designs": len(group), "k": k, "band": band}
    return out


def scaled_interval(e: dict, cell: str, c: dict) -> ModelInterval:
    bounds = {
        a: (
            float(math.exp(e["mean_log"][a] - c["k"][a] * max(e["std_log"][a], TINY))),
            float(math.exp(e["mean_log"][a] + c["k"][a] * max(e["std_log"][a], TINY))),
        )
        for a in ANSWERS
    }
    low, high = members_envelope(e)
    half = c["band"] * e[PEAK]
    return ModelInterval(
        cell,
        c["designs"],
        LEVEL,
        bounds,
        [float(v) for v in np.maximum(low - half, 0.0)],
        [float(v) for v in high + half],
    )


def intervals(
    cal_rows: list[dict], evals: dict[int, list[dict]], ranges: dict, first: str, also: str | None
) -> tuple[dict[str, dict[int, list[dict]]], dict]:
    """Each method's judged rows per seed (the calibration seed's in sample under key ``None``) and its fit."""
    seeds = {None: cal_rows, **evals}
    out, fits = {}, {}
    # raw: uncalibrated
    out["raw"] = {}
    for s, rows in seeds.items():
        v = view(rows, lambda r: r["ens"])
        trust.judge(v, NO_CALIBRATION, ranges)
        for r in v:
            e = r["src"]["ens"]
            attach(r, raw_interval(e, r["cell"], Z, e["hist_min"], e["hist_max"]), 0.0)
        out["raw"][s] = v
    # scaled: per cell conformal k on std_log
    cells = fit_scaled(cal_rows)
    fits["scaled"] = {"cells": cells}
    out["scaled"] = {}
    for s, rows in seeds.items():
        v = view(rows, lambda r: r["ens"])
        trust.judge(v, NO_CALIBRATION, ranges)
        for r in v:
            c = cells.get(r["cell"])
            attach(r, scaled_interval(r["src"]["ens"], r["cell"], c) if c else None, c["band"] if c else None)
        out["scaled"][s] = v
    # the cell-conformal interval of model_interval.fit on one answer per design
    models = {"mean": lambda r: r["ens"], "first": lambda r: r["models"][first]}
    if also is not None:
        models["also"] = lambda r: r["models"][also]
    for key, model in models.items():
        cal = fit(
            [(r["design"], trust.as_summary(model(r)), trust.as_summary(r["solver"])) for r in cal_rows], ranges, key
        )
        fits[key] = cal.to_json()
        out[key] = {}
        for s, rows in seeds.items():
            v = view(rows, model)
            trust.judge(v, cal, ranges)
            out[key][s] = v
    return out, fits


# -- measures --------------------------------------------------------------------------------------------------------
def errors(rows: list[dict]) -> dict:
    """Peak, deflection and history errors of ``view`` rows, per region."""

    def one(group):
        if not group:
            return None
        peak = [100 * (r["model"][PEAK] - r["solver"][PEAK]) / r["solver"][PEAK] for r in group]
        defl = [100 * (r["model"][DEFL] - r["solver"][DEFL]) / r["solver"][DEFL] for r in group]
        hist = []
        for r in group:
            m, s = np.asarray(r["model"][HISTORY], float), np.asarray(r["solver"][HISTORY], float)
            n = min(len(m), len(s))
            hist.append(100 * float(np.max(np.abs(m[:n] - s[:n]))) / r["solver"][PEAK])
        return {
            "designs": len(group),
            "peak_median_abs_pct": float(np.median(np.abs(peak))),
            "peak_worst_abs_pct": float(np.max(np.abs(peak))),
            "peak_signed_median_pct": float(np.median(peak)),
            "deflection_median_abs_pct": float(np.median(np.abs(defl))),
            "deflection_worst_abs_pct": float(np.max(np.abs(defl))),
            "history_median_max_err_pct_of_peak": float(np.median(hist)),
        }

    return {k: one(v) for k, v in trust.regions(rows).items()}


SCORES = {
    "std_log": lambda e: float(np.std(np.log(e["peaks"]), ddof=1)),
    "range_over_mean": lambda e: float((max(e["peaks"]) - min(e["peaks"])) / np.mean(e["peaks"])),
}


def peak_error(r: dict, model) -> float:
    return abs(100 * (model(r)[PEAK] - r["solver"][PEAK]) / r["solver"][PEAK])


def note(cal_rows: list[dict], eval_rows: list[dict], score, model) -> dict:
    """The disagreement note for one score and one model's error (module docstring)."""
    cs = np.array([score(r["ens"]) for r in cal_rows])
    big = np.array([peak_error(r, model) > BIG_ERROR_PCT for r in cal_rows], bool)
    if big.any():
        bad = np.sort(cs[big])[::-1]
        threshold, how = (
            float(bad[math.ceil(CATCH * len(bad) - 1e-9) - 1]),
            f"the largest flagging >= {CATCH:.0%} of the calibration seed's {len(bad)} errors over {BIG_ERROR_PCT:g} %",
        )
    else:
        threshold = float(np.quantile(cs, FALLBACK_QUANTILE))
        how = (
            f"the calibration seed has no error over {BIG_ERROR_PCT:g} %: its score's "
            f"{100 * FALLBACK_QUANTILE:.0f}th percentile"
        )

    def measure(rows):
        if not rows:
            return None
        flag = np.array([score(r["ens"]) >= threshold for r in rows], bool)
        bad = np.array([peak_error(r, model) > BIG_ERROR_PCT for r in rows], bool)
        return {
            "designs": len(rows),
            "big_errors": int(bad.sum()),
            "caught": int((flag & bad).sum()),
            "caught_share": float((flag & bad).sum() / bad.sum()) if bad.any() else None,
            "false_alarms": int((flag & ~bad).sum()),
            "false_alarm_share": float((flag & ~bad).sum() / (~bad).sum()) if (~bad).any() else None,
            "flagged_share": float(flag.mean()),
        }

    return {
        "threshold": threshold,
        "threshold_rule": how,
        "calibration_seed": measure(cal_rows),
        "evaluation": {"all": measure(eval_rows), **{k: measure(v) for k, v in trust.regions(eval_rows).items()}},
        "met_on_evaluation": None,
    }


def cost(members: list[dict], designs: list[tuple], batch: int) -> dict:
    """Fresh predictions of ``designs`` by each member in turn, each batched over them: seconds per design."""
    per = {}
    for m in members:
        t0 = time.perf_counter()
        predict(m["run"], designs, batch=batch, progress=False)
        per[m["label"]] = (time.perf_counter() - t0) / len(designs)
    return {
        "designs": len(designs),
        "batch": batch,
        "per_member_s_per_design": per,
        "one_member_s_per_design": per[members[0]["label"]],
        "all_members_s_per_design": float(sum(per.values())),
    }


# -- printing --------------------------------------------------------------------------------------------------------
def pct(x, w=6) -> str:
    return f"{'-':>{w}}" if x is None else f"{100 * x:{w - 1}.1f}%"


def print_errors(errs: dict[str, dict]) -> None:
    print(
        f"{'model':<30} {'region':<26} {'n':>4} {'peak med':>8} {'worst':>6} {'signed':>6} "
        f"{'defl med':>8} {'worst':>6} {'hist':>6}"
    )
    for model, by in errs.items():
        for region, s in by.items():
            if s is None:
                continue
            print(
                f"{model:<30} {region:<26} {s['designs']:>4} {s['peak_median_abs_pct']:8.1f} "
                f"{s['peak_worst_abs_pct']:6.1f} {s['peak_signed_median_pct']:6.1f} "
                f"{s['deflection_median_abs_pct']:8.1f} {s['deflection_worst_abs_pct']:6.1f} "
                f"{s['history_median_max_err_pct_of_peak']:6.1f}"
            )


def print_intervals(cov: dict[str, dict]) -> None:
    head = (
        f"{'interval':<8} {'cell / region':<30} {'n':>4} {'no iv':>5} {'peak':>6} {'defl':>6} {'hist':>6} "
        f"{'width':>6} {'band':>6}"
    )
    print(head)
    for method, c in cov.items():
        print("-" * len(head))
        for part in ("by_cell", "by_region"):
            for k, s in c[part].items():
                if part == "by_region" and k in c["by_cell"]:
                    continue
                v = s["coverage"]
                print(
                    f"{method:<8} {k:<30} {s['designs']:>4} {s['without_interval']:>5} {pct(v[PEAK]['share'])} "
                    f"{pct(v[DEFL]['share'])} {pct(v[HISTORY]['share'])} {pct(s['median_rel_width_peak'])} "
                    f"{pct(s['median_history_band'])}"
                )


# -- the run ---------------------------------------------------------------------------------------------------------
def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument(
        "--members",
        nargs="+",
        required=True,
        metavar="RUN[@CHECKPOINT]",
        help="2+ run folders of one dataset (the ensemble's members)",
    )
    p.add_argument("--which", default="best", help="the members' checkpoint: best, checkpoint or step_N")
    p.add_argument("--also", default=None, metavar="MODEL", help="one more model measured on the same designs")
    trust.design_arguments(p)
    p.add_argument("--cost-designs", type=int, default=8, help="evaluation designs timed afresh (0: none)")
    p.add_argument(
        "--json", default="trust_ensemble.json", help="result file: a name under benchmarks/results/, or a path"
    )
    a = p.parse_args()
    if a.calibration_seed in a.eval_seeds or len(set(a.eval_seeds)) != len(a.eval_seeds):
        p.error("--calibration-seed and --eval-seeds must all differ")
    for d in a.distances:
        if not 0 < d or abs(d / DISTANCE_STEP - round(d / DISTANCE_STEP)) > 1e-9:
            p.error(f"--distances: {d} is not a positive multiple of {DISTANCE_STEP}")
    if min(a.inside, a.per_cell) < MIN_DESIGNS:
        print(f"note: a cell needs {MIN_DESIGNS} designs for a {LEVEL:.0%} bound; smaller ones get no interval")
    set_threads(a.threads)  # kept by Run.load (torch.set_num_threads alone may be taken for torch's default)
    t_start = time.perf_counter()
    members = load_members(a.members, a.which, p)
    ref = members[0]["run"]
    ranges, tag = ref.ranges, ranges_tag(ref.ranges)
    runners = {m["label"]: trust.Runner(m["run"], a.work, m["label"], a.batch) for m in members}
    solver = runners[members[0]["label"]]
    for m in members[1:]:
        r = runners[m["label"]]
        if (r.settings, r.field) != (solver.settings, solver.field):
            p.error(f"--members: {m['name']}'s solver settings differ from {members[0]['name']}'s")
    also = None
    if a.also:
        also_run = Run.load(a.also, "cpu")
        also = label_of(also_run, "best")
        if also in runners:
            p.error(f"--also: {a.also} is a member")
        also_runner = trust.Runner(also_run, a.work, also, a.batch)
        if (also_runner.settings, also_runner.field) != (solver.settings, solver.field):
            p.error(
                f"--also: {a.also}'s solver settings differ from the members' ({also_runner.settings}, "
                f"{also_runner.field}): the two would not be measured against one truth"
            )
        runners[also] = also_runner
    cells = [trust.parse_cell(c, trust.varied(ranges)) for c in a.cells]
    command = portable_command(sys.argv[1:], members)
    said = ", ".join(f"{m['label']} (step {m['run'].checkpoint_step})" for m in members)
    print(f"members: {said}; designs tagged {tag}", flush=True)

    skipped: dict[str, int] = {}
    print(f"calibration: seed {a.calibration_seed}", flush=True)
    cal_rows = rows_of(
        solver, runners, trust.seed_designs(ref, a.calibration_seed, a, cells, skipped), a.calibration_seed, tag
    )
    evals = {}
    for seed in a.eval_seeds:
        print(f"evaluation: seed {seed}", flush=True)
        evals[seed] = rows_of(solver, runners, trust.seed_designs(ref, seed, a, cells, skipped), seed, tag)
    labels = [m["label"] for m in members]
    for r in [*cal_rows, *(r for rows in evals.values() for r in rows)]:
        r["ens"] = ensemble_of([r["models"][k] for k in labels])
        assert cell_of(r["design"], ranges) == r["cell"]
    pooled = [r for rows in evals.values() for r in rows]
    every = cal_rows + pooled

    # 1. the ensemble mean's errors beside each member's and --also's
    models = {"ensemble mean": lambda r: r["ens"], **{k: (lambda r, k=k: r["models"][k]) for k in labels}}
    if also:
        models[also] = lambda r: r["models"][also]
    errs = {k: errors(view(every, m)) for k, m in models.items()}
    inside = errs["ensemble mean"]["inside"]
    check = None
    if inside is not None:
        check = {
            "peak_median_pct": inside["peak_median_abs_pct"],
            "peak_worst_pct": inside["peak_worst_abs_pct"],
            "deflection_median_pct": inside["deflection_median_abs_pct"],
            "limits_pct": CHECK,
            "met": bool(
                inside["peak_median_abs_pct"] <= CHECK["peak_median"]
                and inside["peak_worst_abs_pct"] <= CHECK["peak_worst"]
                and inside["deflection_median_abs_pct"] <= CHECK["deflection_median"]
            ),
        }
        if also and errs[also]["inside"] is not None:
            o = errs[also]["inside"]
            check["no_worse_than_also"] = bool(
                inside["peak_median_abs_pct"] <= o["peak_median_abs_pct"]
                and inside["peak_worst_abs_pct"] <= o["peak_worst_abs_pct"]
                and inside["deflection_median_abs_pct"] <= o["deflection_median_abs_pct"]
            )

    # 2. intervals; 4. calls
    judged, fits = intervals(cal_rows, evals, ranges, labels[0], also)
    cov, call = {}, {}
    for method, by_seed in judged.items():
        ev = [r for s in a.eval_seeds for r in by_seed[s]]
        cov[method] = {
            "pooled": trust.coverage(ev),
            **{f"seed {s}": trust.coverage(by_seed[s]) for s in a.eval_seeds},
            "calibration seed (in sample)": trust.coverage(by_seed[None]),
        }
        if method != "raw":
            c = trust.calls(ev, ranges)["model"]
            call[method] = c

    # 3. the disagreement note
    notes = {}
    for sname, score in SCORES.items():
        for who, model in (
            ("ensemble mean", models["ensemble mean"]),
            (f"first member ({labels[0]})", models[labels[0]]),
        ):
            n = note(cal_rows, pooled, score, model)
            e = n["evaluation"]["all"]
            n["met_on_evaluation"] = (
                None
                if e["caught_share"] is None
                else bool(e["caught_share"] >= CATCH and (e["false_alarm_share"] or 0.0) <= 0.15)
            )
            notes[f"{sname} / {who}"] = n

    # 5. cost
    solver_s = trust.median([r["solver"]["wall_s"] for r in every])
    cached = {k: trust.median([r["models"][k]["wall_s"] for r in every]) for k in labels}
    spend = None
    if a.cost_designs > 0:
        timed = [(r["name"], r["design"]) for r in pooled[: a.cost_designs]]
        print(f"cost: {len(timed)} designs predicted afresh by each member", flush=True)
        spend = cost(members, timed, a.batch)
        spend["speedup_vs_solver_all_members"] = solver_s / spend["all_members_s_per_design"]
        spend["speedup_vs_solver_one_member"] = solver_s / spend["one_member_s_per_design"]
        spend["ensemble_at_least_1.5x_faster"] = bool(spend["speedup_vs_solver_all_members"] >= SPEEDUP)
    cached_all = sum(cached.values())

    result = {
        "command": command,
        "members": [
            {
                "run": m["name"],
                "which": m["which"],
                "label": m["label"],
                "checkpoint_step": m["run"].checkpoint_step,
                "seed": m["run"].info.seed,
                "init_from": init_of(m["run"]),
            }
            for m in members
        ],
        "also": None
        if not also
        else {
            "model": a.also if a.also.startswith("pretrained:") else Path(a.also).name,
            "label": also,
            "checkpoint_step": runners[also].run.checkpoint_step,
        },
        "hcmt": VERSION,
        "torch": torch.__version__,
        "device": "cpu",
        "machine": platform.processor() or platform.machine(),
        "cores": os.cpu_count(),
        "threads": a.threads,
        "ranges_tag": tag,
        "ranges": {k: list(v) for k, v in ranges.items() if k in trust.varied(ranges)},
        "seeds": {"calibration": a.calibration_seed, "evaluation": a.eval_seeds},
        "designs": {
            "inside": a.inside,
            "per_cell": a.per_cell,
            "cells": [trust.cell_label(c) for c in cells],
            "distances": a.distances,
            "redrawn_invalid": skipped,
            "calibration": len(cal_rows),
            "evaluation": len(pooled),
        },
        "level": LEVEL,
        "min_designs": MIN_DESIGNS,
        "z_raw": Z,
        "factors": list(trust.FACTORS),
        "errors_all_seeds": errs,
        "check_inside": check,
        "intervals": {"fits": fits, "coverage": cov},
        "calls": call,
        "disagreement": {"big_error_pct": BIG_ERROR_PCT, "catch": CATCH, "false_alarms_at_most": 0.15, "notes": notes},
        "cost": {
            "solver_median_s_per_design": solver_s,
            "members_cached_median_s_per_design": cached,
            "all_members_cached_s_per_design": cached_all,
            "speedup_vs_solver_cached_all_members": solver_s / cached_all if cached_all else None,
            "fresh": spend,
        },
        "seconds": {
            "solver_runs_here": solver.solver_runs,
            "model_runs_here": {k: r.model_runs for k, r in runners.items()},
            "wall_this_process": time.perf_counter() - t_start,
        },
    }
    path = trust.result_path(a.json)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(portable(result), indent=2))

    print(
        f"\n1. errors (percent) on all {len(every)} designs (seeds {a.calibration_seed}, "
        f"{', '.join(map(str, a.eval_seeds))}); hist: median of the largest per-frame error / solver peak"
    )
    print_errors(errs)
    if check is not None:
        print(
            f"check inside (peak <= {CHECK['peak_median']:g} % median, <= {CHECK['peak_worst']:g} % worst; "
            f"deflection <= {CHECK['deflection_median']:g} %): {'met' if check['met'] else 'not met'}"
            + (
                f"; no worse than {also}: {'yes' if check['no_worse_than_also'] else 'no'}"
                if "no_worse_than_also" in check
                else ""
            )
        )
    print(
        f"\n2. intervals, pooled over seeds {', '.join(map(str, a.eval_seeds))} (calibrated on "
        f"{a.calibration_seed}; width: median (hi - lo) / model peak; band: history band +- share of peak)"
    )
    print_intervals({k: v["pooled"] for k, v in cov.items()})
    print(
        "scaled k (peak, defl) per cell: "
        + "; ".join(f"{c} {v['k'][PEAK]:.2f}, {v['k'][DEFL]:.2f}" for c, v in fits["scaled"]["cells"].items())
    )
    print(f"\n3. disagreement note (errors > {BIG_ERROR_PCT:g} %, evaluation seeds):")
    for k, n in notes.items():
        e = n["evaluation"]["all"]
        print(
            f"  {k:<46} threshold {n['threshold']:.4f}: big errors {e['big_errors']:>3}, caught "
            f"{pct(e['caught_share'])}, false alarms {pct(e['false_alarm_share'])} "
            f"(flagged {pct(e['flagged_share'])})"
            f"{'' if n['calibration_seed']['big_errors'] else '  [no big error on the calibration seed]'}"
        )
    print(f"\n4. calls at the solver's peak x {', '.join(f'{f:g}' for f in trust.FACTORS)} (the interval alone):")
    for k, c in call.items():
        x = c["all"]
        print(
            f"  {k:<8} points {x['points']:>5}  unsafe {x['unsafe']:>3}  wrong fail {x['wrong_fail']:>3}  "
            f"undecided {pct(x['undecided_share'])}"
        )
    print(
        "\n5. cost per design (s): solver median (cache) "
        f"{solver_s:.2f}; cached model medians " + ", ".join(f"{k} {v:.2f}" for k, v in cached.items())
    )
    if spend is not None:
        print(
            f"  fresh ({spend['designs']} designs, batch {a.batch}, {a.threads} thread(s)): one member "
            f"{spend['one_member_s_per_design']:.2f}, all {len(members)} {spend['all_members_s_per_design']:.2f}: "
            f"{spend['speedup_vs_solver_all_members']:.2f}x faster than the solver "
            f"({'>=' if spend['ensemble_at_least_1.5x_faster'] else '<'} {SPEEDUP}x)"
        )
    print(f"wrote {portable(path)}")


if __name__ == "__main__":
    main()
