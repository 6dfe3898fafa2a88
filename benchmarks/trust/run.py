"""The mesh model's own interval (:mod:`hcmt.design.model_interval`): split-conformal bounds of its peak plate
stress, max deflection and whole plate stress history, calibrated per cell (inside the training ranges, or beyond
them in these parameters, this far) on the solver's runs of designs of one seed, then measured on designs of other
seeds; the limit calls it makes alone and with the response surface; and a fuzzer far outside the ranges.

    python benchmarks/trust/run.py --work WORK [--model pretrained:impact_plate_small] [--checkpoint best]
        [--calibration-seed 5201] [--eval-seeds 5202 5203] [--inside 60] [--per-cell 24]
        [--cells thickness+ drop_height+ drop_height+,thickness+] [--distances 0.2 0.4] [--batch 8] [--threads 1]
        [--fuzz 0] [--fuzz-seed 5299] [--write] [--json trust.json]

The full run, which writes the shipped model's calibration (``src/hcmt/pretrained/impact_plate_small.interval.json``,
with the coverage it measured) and benchmarks/results/trust.json (docs/RESULTS.md, "The mesh model's own interval"):

    python benchmarks/trust/run.py --work $HCMT_WORK/trust --fuzz 200 --write

Designs (per seed and group, ``numpy.random.default_rng([seed, crc32(group)])``, so a group's first n designs are the
same whatever the other groups' counts: a larger run extends the cache of a smaller one): ``inside``, every parameter
whose training range (``run.ranges``, min and max over the training designs) is not a single value uniform inside it,
the others at :func:`hcmt.sim.sampling.middle_design`; an outside cell (``--cells``: parameters with their side, at each
``--distances`` d), the same draw with each named parameter beyond its side by an excess uniform in
((d - 0.2) width, d width], so the design's cell (:func:`hcmt.design.model_interval.cell_of`) is ``CELL:d`` (checked).
A draw that :meth:`hcmt.sim.params.Design.validate` refuses is drawn again (counted). Names:
``s5202_inside_07``, ``s5202_thickness+_0.4_07``. The calibration is fitted on the ``--calibration-seed``'s designs
only and measured on the ``--eval-seeds``' (other seeds: the two sets never share a design; the script refuses a
calibration seed among the evaluation seeds).

Measured per evaluation seed and pooled, per cell and per region (inside, each outside direction, all outside): the
share of designs whose solver value lies inside the interval (peak plate stress, max deflection, the whole plate
stress history), the median relative width of the peak's interval ((hi - lo) / model), the designs without an
interval; beside it on the same designs, the response surface's 95 % interval of the peak
(:func:`hcmt.design.surrogate_use.for_run`) and the fallback band the calls used before (model ± 60 %,
:data:`hcmt.design.calls.MODEL_BAND`). Limit calls: at yield stresses of the solver's peak x :data:`FACTORS` per
design, each trust's calls (:func:`hcmt.design.calls.trusted_bounds`, :func:`hcmt.design.calls.call_of`; a design in
an uncalibrated cell outside the ranges undecided, :func:`hcmt.design.calls.outside_reason`): passes the solver fails
(unsafe), fails it passes, and the undecided share (where ``--verify auto`` runs the solver). ``--fuzz N``: N valid
designs with 1-3 parameters beyond their range either side by 0.01 to 10 widths (log-uniform: about half the excesses
within half a width, where the calibrated cells lie), through the design check
(:func:`hcmt.design.check.check_designs`, ``verify="auto"``, the fitted interval, the run's response surface) at a
yield stress drawn from 300-3000 MPa; the solver checks every final pass it did not verify; designs estimated at over
60 s of solver time (:func:`hcmt.sim.cost.estimate`) are counted and left out.

Every run is cached under WORK as JSON, one file per design: the solver's under ``WORK/solver/``, the model's under
``WORK/model/LABEL/`` (LABEL: the model's name, no machine path), the fuzzer's checks under ``WORK/fuzz/LABEL/``; an
interrupted run continues where it stopped. Cost (the development machine, one thread, the other core busy): about
3 s of solver and 3 s of model per design at --batch 8, so the default 204 designs per seed x 3 seeds take about
1-1.5 h, the fuzzer about 5 s per design (the model alone at batch 1, the solver where the call is undecided).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
import zlib
from dataclasses import asdict, replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/: common
from common import RESULTS, portable  # noqa: E402
from hcmt.config import VERSION  # noqa: E402
from hcmt.config.threads import set_threads  # noqa: E402
from hcmt.design.calls import MODEL_BAND, call_of, outside_reason, trust_for, trusted_bounds  # noqa: E402
from hcmt.design.check import check_designs  # noqa: E402
from hcmt.design.inputs import settings_of  # noqa: E402
from hcmt.design.model_interval import (  # noqa: E402
    ANSWERS,
    DISTANCE_STEP,
    LEVEL,
    MIN_DESIGNS,
    Calibration,
    cell_of,
    covers,
    fit,
    interval_path,
)
from hcmt.design.prediction import predict  # noqa: E402
from hcmt.design.surrogate_use import for_run as surrogate_for_run, run_name  # noqa: E402
from hcmt.design.verification import solve, verify_settings  # noqa: E402
from hcmt.errors import InputError  # noqa: E402
from hcmt.files import atomic_path  # noqa: E402
from hcmt.inference.run import Run  # noqa: E402
from hcmt.sim.cost import check_size, estimate  # noqa: E402
from hcmt.sim.params import DESIGN_KEYS, Design  # noqa: E402
from hcmt.sim.sampling import middle_design  # noqa: E402

PEAK = "peak_plate_stress_mpa"
HISTORY = "plate_stress_history_mpa"
#: the yield stresses of the limit calls, as multiples of each design's solver peak
FACTORS = (0.8, 0.9, 0.95, 1.05, 1.1, 1.2)
#: the calls measured: the calibrated interval alone, with the response surface, and the calls before it existed
#: (no interval: the model ± MODEL_BAND, or the response surface widened to hold the model's answer; a design outside
#: the training ranges undecided)
CALLS = {
    "model": ("model", True),
    "union": ("union", True),
    "intersection": ("intersection", True),
    "model_before": ("model", False),
    "union_before": ("union", False),
}
#: the requirement on the calibrated interval alone: no unsafe call, the solver on at most this share of points
SOLVER_SHARE = 0.30
#: the fuzzer: how far beyond a range (widths, log-uniform between the two), the yield stresses drawn (MPa), the
#: solver's cost it pays (s)
FUZZ_NEAR, FUZZ_WIDTHS, FUZZ_YIELD, FUZZ_MAX_SOLVER_S = 0.01, 10.0, (300.0, 3000.0), 60.0
TRIES = 1000  # redraws of one design before the script gives up


# -- designs ---------------------------------------------------------------------------------------------------------
def varied(ranges: dict) -> list[str]:
    """The design parameters whose training range is not a single value, sorted."""
    return sorted(k for k, (lo, hi) in ranges.items() if k in DESIGN_KEYS and hi > lo)


def parse_cell(text: str, keys: list[str]) -> list[tuple[str, str]]:
    """``drop_height+,thickness+`` as [(key, side)], sorted by key as :func:`cell_of` names them."""
    out = []
    for part in text.split(","):
        key, side = part.strip()[:-1], part.strip()[-1:]
        if side not in "+-" or not side or key not in keys:
            raise SystemExit(
                f"--cells: {part!r} is not a varied parameter with its side (+ or -): "
                f"one of {', '.join(keys)}, e.g. thickness+"
            )
        out.append((key, side))
    if len({k for k, _ in out}) != len(out):
        raise SystemExit(f"--cells: {text!r} names a parameter twice")
    return sorted(out)


def cell_label(sides: list[tuple[str, str]], distance: float | None = None) -> str:
    """``drop_height+,thickness+`` (a direction), with ``:0.4`` (a cell) when a distance is given."""
    name = ",".join(f"{k}{s}" for k, s in sides)
    return name if distance is None else f"{name}:{distance:.1f}"


def direction_of(cell: str) -> str:
    return cell.split(":", 1)[0]


def group_rng(seed: int, group: str) -> np.random.Generator:
    return np.random.default_rng([seed, zlib.crc32(group.encode())])


def draw_inside(rng, ranges: dict, keys: list[str]) -> dict[str, float]:
    return {k: float(rng.uniform(*ranges[k])) for k in keys}


def beyond(ranges: dict, key: str, side: str, excess: float) -> float:
    lo, hi = ranges[key]
    return float(hi + excess if side == "+" else lo - excess)


def group_designs(
    run, seed: int, sides: list[tuple[str, str]] | None, distance: float | None, count: int, skipped: dict
) -> list[tuple[str, Design, str]]:
    """``count`` designs of a group: (name, design, cell); ``sides`` None: inside."""
    ranges, keys = run.ranges, varied(run.ranges)
    base = middle_design(run.meta, run.ranges)
    group = "inside" if sides is None else cell_label(sides, distance)
    rng = group_rng(seed, group)
    out = []
    while len(out) < count:
        for _ in range(TRIES):
            values = draw_inside(rng, ranges, keys)
            for key, side in sides or []:
                width = ranges[key][1] - ranges[key][0]
                values[key] = beyond(ranges, key, side, (distance - DISTANCE_STEP * rng.random()) * width)
            d = replace(base, **values)
            try:
                d.validate()
            except InputError:
                skipped[group] = skipped.get(group, 0) + 1
                continue
            break
        else:
            raise SystemExit(f"{group}: no valid design in {TRIES} draws")
        cell = cell_of(d, ranges)
        assert cell == group, f"{group}: drew a design of cell {cell}"
        name = (
            f"s{seed}_inside_{len(out):02d}"
            if sides is None
            else f"s{seed}_{cell_label(sides)}_{distance:.1f}_{len(out):02d}"
        )
        out.append((name, d, cell))
    return out


def seed_designs(run, seed: int, a, cells: list[list[tuple[str, str]]], skipped: dict) -> list:
    out = group_designs(run, seed, None, None, a.inside, skipped)
    for sides in cells:
        for dist in a.distances:
            out += group_designs(run, seed, sides, dist, a.per_cell, skipped)
    return out


# -- cached runs -----------------------------------------------------------------------------------------------------
def read_json(path: Path) -> dict | None:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def write(path: Path, obj) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(obj))


def as_summary(block: dict) -> SimpleNamespace:
    """What :func:`fit` and :func:`covers` read of a summary."""
    return SimpleNamespace(**{k: block[k] for k in (*ANSWERS, HISTORY)})


class Runner:
    """The solver's and the model's runs of designs, one JSON file per design under ``work``: a file whose design,
    solver settings or model checkpoint is not the one asked for is run again."""

    def __init__(self, run, work: Path, label: str, batch: int):
        self.run, self.work, self.label, self.batch = run, work, label, batch
        settings = settings_of(run.meta)
        self.field = run.adapter.stress_field  # stress_max: the solver records the between-frame peaks it learned
        self.settings = verify_settings(settings, self.field)  # else the solver as `hcmt simulate` runs it
        self.solver_runs = self.model_runs = 0

    def solver_path(self, name: str) -> Path:
        return self.work / "solver" / f"{name}.json"

    def model_path(self, name: str) -> Path:
        return self.work / "model" / self.label / f"{name}.json"

    def solver_key(self, d: Design) -> dict:
        return {"design": asdict(d), "settings": asdict(self.settings), "stress_field": self.field}

    def solver_cached(self, name: str, d: Design) -> dict | None:
        """The cached solver run of ``d``; between-frame peak recording changes no frame answer, only the wall time
        (tests/sim/test_sim_generate.py), so for a model of the frame stress a run cached with or without it counts
        (its ``wall_s`` then is the recording solver's)."""
        got = read_json(self.solver_path(name))
        if got is None:
            return None

        def same(k, v):
            if k == "settings" and self.field != "stress_max" and isinstance(got.get(k), dict):
                return {**got[k], "peak_stress": v["peak_stress"]} == v
            return got.get(k) == v

        return got if all(same(k, v) for k, v in self.solver_key(d).items()) else None

    def save_solver(self, name: str, d: Design, summary, wall_s: float) -> dict:
        rec = {
            **self.solver_key(d),
            PEAK: float(summary.peak_plate_stress_mpa),
            "max_deflection_mm": float(summary.max_deflection_mm),
            HISTORY: [float(v) for v in summary.plate_stress_history_mpa],
            "wall_s": float(wall_s),
        }
        write(self.solver_path(name), rec)
        return rec

    def solver(self, designs: list[tuple[str, Design]], say: str = "solver") -> dict[str, dict]:
        out = {n: self.solver_cached(n, d) for n, d in designs}
        todo = [(n, d) for n, d in designs if out[n] is None]
        t0 = time.perf_counter()
        for i, (n, d) in enumerate(todo):
            t = solve([(n, d)], self.settings, self.field)[0]
            out[n] = self.save_solver(n, d, t.summary, t.wall_s)
            self.solver_runs += 1
            if (i + 1) % 10 == 0 or i + 1 == len(todo):
                print(
                    f"  {say}: {i + 1} / {len(todo)} designs run ({len(designs) - len(todo)} cached), "
                    f"{time.perf_counter() - t0:.0f} s",
                    flush=True,
                )
        return out

    def model_key(self, d: Design) -> dict:
        return {"design": asdict(d), "model": self.label, "checkpoint_step": self.run.checkpoint_step}

    def model(self, designs: list[tuple[str, Design]]) -> dict[str, dict]:
        out = {}
        for n, d in designs:
            got = read_json(self.model_path(n))
            out[n] = got if got is not None and all(got.get(k) == v for k, v in self.model_key(d).items()) else None
        todo = [(n, d) for n, d in designs if out[n] is None]
        t0 = time.perf_counter()
        for first in range(0, len(todo), self.batch):  # one batch at a time, each saved: a rerun resumes
            chunk = todo[first : first + self.batch]
            for p in predict(self.run, chunk, batch=self.batch, progress=False):
                s = p.summary
                rec = {
                    **self.model_key(p.design),
                    PEAK: float(s.peak_plate_stress_mpa),
                    "max_deflection_mm": float(s.max_deflection_mm),
                    HISTORY: [float(v) for v in s.plate_stress_history_mpa],
                    "readout": s.readout,
                    "wall_s": float(p.wall_s),
                    "summary": s.to_json(),
                }
                write(self.model_path(p.name), rec)
                out[p.name] = rec
                self.model_runs += 1
            print(
                f"  model: {min(first + self.batch, len(todo))} / {len(todo)} designs run "
                f"({len(designs) - len(todo)} cached), {time.perf_counter() - t0:.0f} s",
                flush=True,
            )
        return out


# -- measures --------------------------------------------------------------------------------------------------------
def rows_of(runner: Runner, designs: list, seed: int, gp) -> list[dict]:
    """Each design's record: its model and solver summaries, the response surface's interval of its peak."""
    pairs = [(n, d) for n, d, _ in designs]
    solver, model = runner.solver(pairs, f"solver, seed {seed}"), runner.model(pairs)
    if gp is not None:
        preds = gp.predict([d for _, d in pairs])
        gps = [None if gp.cannot_take(d) else p[PEAK] for (_, d), p in zip(pairs, preds)]
    else:
        gps = [None] * len(pairs)
    return [
        {
            "name": n,
            "seed": seed,
            "design": d,
            "cell": cell,
            "direction": direction_of(cell),
            "model": model[n],
            "solver": solver[n],
            "gp": g,
        }
        for (n, d, cell), g in zip(designs, gps)
    ]


def judge(rows: list[dict], cal: Calibration, ranges: dict) -> None:
    """Each row's interval (None: its cell is not calibrated), what it covers and its width, and the same for the
    response surface's interval and the ± MODEL_BAND band."""
    for r in rows:
        m, s = r["model"], r["solver"]
        iv = cal.interval(r["design"], ranges, {a: m[a] for a in ANSWERS}, m[HISTORY])
        r["interval"] = iv
        r["covers"] = covers(iv, as_summary(s)) if iv is not None else None
        r["width"] = (iv.bounds[PEAK][1] - iv.bounds[PEAK][0]) / m[PEAK] if iv is not None else None
        r["band"] = cal.cells[iv.cell].band if iv is not None else None  # the history band's half-width / peak
        g = r["gp"]
        r["gp_covers"] = None if g is None else bool(g.lo <= s[PEAK] <= g.hi)
        r["gp_width"] = None if g is None else (g.hi - g.lo) / g.mean
        r["band_covers"] = bool(m[PEAK] * (1 - MODEL_BAND) <= s[PEAK] <= m[PEAK] * (1 + MODEL_BAND))
        r["error_pct"] = 100 * (m[PEAK] - s[PEAK]) / s[PEAK]


def share(flags: list[bool]) -> dict:
    n, k = len(flags), int(sum(flags))
    return {"covered": k, "of": n, "share": k / n if n else None}


def median(values: list[float]) -> float | None:
    return float(np.median(values)) if values else None


def stats(rows: list[dict]) -> dict:
    """One group's coverage and widths (module docstring)."""
    with_iv = [r for r in rows if r["interval"] is not None]
    with_gp = [r for r in rows if r["gp"] is not None]
    return {
        "designs": len(rows),
        "without_interval": len(rows) - len(with_iv),
        "coverage": {k: share([r["covers"][k] for r in with_iv]) for k in (*ANSWERS, HISTORY)},
        "median_rel_width_peak": median([r["width"] for r in with_iv]),
        "median_history_band": median([r["band"] for r in with_iv]),
        "median_abs_peak_error_pct": median([abs(r["error_pct"]) for r in rows]),
        "worst_abs_peak_error_pct": float(max(abs(r["error_pct"]) for r in rows)) if rows else None,
        "surrogate": {
            "designs": len(with_gp),
            "coverage": share([r["gp_covers"] for r in with_gp]),
            "median_rel_width": median([r["gp_width"] for r in with_gp]),
        },
        "model_band": {"coverage": share([r["band_covers"] for r in rows]), "rel_width": 2 * MODEL_BAND},
    }


def regions(rows: list[dict]) -> dict[str, list[dict]]:
    """inside, each outside direction, all outside."""
    out = {"inside": [r for r in rows if r["cell"] == "inside"]}
    for direction in sorted({r["direction"] for r in rows} - {"inside"}):
        out[direction] = [r for r in rows if r["direction"] == direction]
    out["outside"] = [r for r in rows if r["cell"] != "inside"]
    return out


def coverage(rows: list[dict]) -> dict:
    cells = sorted({r["cell"] for r in rows}, key=lambda c: (c != "inside", c))
    return {
        "by_cell": {c: stats([r for r in rows if r["cell"] == c]) for c in cells},
        "by_region": {k: stats(v) for k, v in regions(rows).items()},
    }


def call_row(r: dict, ranges: dict, trust: str, calibrated: bool, yield_mpa: float) -> str:
    """A design's call as :func:`hcmt.design.calls.add_calls` makes it: the trusted interval's, undecided for a
    design outside the ranges without a calibrated interval (:func:`outside_reason`)."""
    iv = r["interval"] if calibrated else None
    bounds = iv.bounds[PEAK] if iv is not None else None
    trust = trust_for(r["design"], ranges, trust)
    lo, hi, _ = trusted_bounds(r["model"][PEAK], r["gp"], trust, bounds)
    p = SimpleNamespace(design=r["design"], summary=SimpleNamespace(model_interval=iv, readout="raw", confidence=None))
    return "undecided" if outside_reason(p, ranges, trust) else call_of(lo, hi, yield_mpa)


def tally(rows: list[dict], ranges: dict, trust: str, calibrated: bool, factors=FACTORS) -> dict:
    points = unsafe = wrong_fail = undecided = 0
    for r in rows:
        for f in factors:
            y = f * r["solver"][PEAK]
            c = call_row(r, ranges, trust, calibrated, y)
            solver_passes = r["solver"][PEAK] < y  # hcmt.design.calls.final_calls' rule
            points += 1
            unsafe += c == "pass" and not solver_passes
            wrong_fail += c == "fail" and solver_passes
            undecided += c == "undecided"
    return {
        "points": points,
        "unsafe": unsafe,
        "wrong_fail": wrong_fail,
        "undecided": undecided,
        "undecided_share": undecided / points if points else None,
    }


def calls(rows: list[dict], ranges: dict) -> dict:
    out = {}
    for name, (trust, calibrated) in CALLS.items():
        out[name] = {
            "all": tally(rows, ranges, trust, calibrated),
            "by_factor": {f"{f:g}": tally(rows, ranges, trust, calibrated, (f,)) for f in FACTORS},
            "by_region": {k: tally(v, ranges, trust, calibrated) for k, v in regions(rows).items()},
        }
    return out


# -- the fuzzer ------------------------------------------------------------------------------------------------------
def fuzz_designs(run, n: int, seed: int, settings) -> tuple[list, list, dict]:
    """``n`` valid designs, each with 1-3 varied parameters beyond their range by up to FUZZ_WIDTHS widths on either
    side and a yield stress: (to check [(name, design, yield)], too costly [record], refused {why: count})."""
    ranges, keys = run.ranges, varied(run.ranges)
    base = middle_design(run.meta, run.ranges)
    rng = group_rng(seed, "fuzz")
    made, costly, refused = [], [], {}
    while len(made) + len(costly) < n:
        values = draw_inside(rng, ranges, keys)
        chosen = rng.choice(keys, size=int(rng.integers(1, 4)), replace=False)
        for key in sorted(str(k) for k in chosen):
            side = "+" if rng.random() < 0.5 else "-"
            width = ranges[key][1] - ranges[key][0]
            # log-uniform from FUZZ_NEAR to FUZZ_WIDTHS widths: as many designs near the ranges (the calibrated
            # cells) as far from them
            widths = FUZZ_NEAR * (FUZZ_WIDTHS / FUZZ_NEAR) ** (1.0 - rng.random())
            values[key] = beyond(ranges, key, side, widths * width)
        y = float(rng.uniform(*FUZZ_YIELD))
        d = replace(base, **values)
        try:
            d.validate()
            check_size(d, settings)
        except InputError as e:
            why = e.param or ("size" if "nodes" in str(e) else "design")
            refused[why] = refused.get(why, 0) + 1
            continue
        name = f"fuzz{seed}_{len(made) + len(costly):03d}"
        est = estimate(d, settings)["estimated_s"]
        if est > FUZZ_MAX_SOLVER_S:
            costly.append({"name": name, "cell": cell_of(d, ranges), "estimated_solver_s": est})
            continue
        made.append((name, d, y))
    return made, costly, refused


def fuzz(run, runner: Runner, cal: Calibration, n: int, seed: int) -> dict:
    made, costly, refused = fuzz_designs(run, n, seed, runner.settings)
    for c in costly:
        c["calibrated"] = c["cell"] in cal.cells
    records = []
    t0 = time.perf_counter()
    for i, (name, d, y) in enumerate(made):
        path = runner.work / "fuzz" / runner.label / f"{name}.json"
        key = {"design": asdict(d), "yield_mpa": y, "calibration": cal.to_json()["cells"]}
        rec = read_json(path)
        if rec is None or any(rec.get(k) != v for k, v in key.items()):
            rec = fuzz_one(run, runner, cal, name, d, y)
            write(path, {**key, **rec})
        records.append(rec)
        if (i + 1) % 10 == 0 or i + 1 == len(made):
            print(f"  fuzz: {i + 1} / {len(made)} designs, {time.perf_counter() - t0:.0f} s", flush=True)
    ok = [r for r in records if "refused" not in r]
    passes = [r for r in ok if r["final_call"] == "pass"]
    return {
        "seed": seed,
        "designs": n,
        "checked": len(ok),
        "refused_by_the_check": len(records) - len(ok),
        "redrawn": refused,
        "too_costly": len(costly),
        "too_costly_in_a_calibrated_cell": sum(c["calibrated"] for c in costly),
        "in_a_calibrated_cell": sum(r["calibrated"] for r in ok),
        "decided": sum(r["call"] != "undecided" for r in ok),
        "final_passes": len(passes),
        "final_passes_verified": sum(r["verified"] for r in passes),
        "final_passes_checked": sum(not r["verified"] for r in passes),
        "unsafe": sum(r["unsafe"] for r in ok),
        "solver_runs_auto": sum(r["verified"] for r in ok),
        "decided_designs": [
            {
                k: r[k]
                for k in (
                    "name",
                    "cell",
                    "yield_mpa",
                    "call",
                    "model_peak_mpa",
                    "call_interval_mpa",
                    "solver_peak_mpa",
                    "unsafe",
                )
            }
            for r in ok
            if r["call"] != "undecided"
        ],
        "costly": costly,
    }


def fuzz_one(run, runner: Runner, cal: Calibration, name: str, d: Design, y: float) -> dict:
    """One design through the design check (``verify="auto"``), the solver run on a final pass it did not verify."""
    cell = cell_of(d, run.ranges)
    base = {"name": name, "cell": cell, "calibrated": cell in cal.cells, "yield_mpa": y}
    try:
        check = check_designs(
            run, [(name, d)], batch=1, yield_mpa=y, verify="auto", surrogate=True, interval=cal, progress=False
        )
    except InputError as e:
        return {**base, "refused": str(e)}
    s, t = check.preds[0].summary, check.truth[0]
    solver = None
    if t is not None:  # undecided: the check ran the solver; keep its run
        solver = runner.save_solver(name, d, t.summary, t.wall_s)
    elif s.final_call == "pass":  # a pass the solver did not verify: check it
        solver = runner.solver([(name, d)], "fuzz solver")[name]
    peak = solver[PEAK] if solver is not None else None
    return {
        **base,
        "call": s.call,
        "final_call": s.final_call,
        "verified": bool(s.verified),
        "model_peak_mpa": float(s.peak_plate_stress_mpa),
        "call_interval_mpa": s.call_interval_mpa.to_json() if s.call_interval_mpa else None,
        "model_interval": s.model_interval.to_json()["peak_plate_stress_mpa"] if s.model_interval else None,
        "solver_peak_mpa": peak,
        "unsafe": bool(s.final_call == "pass" and peak is not None and peak >= y),
    }


# -- the run ---------------------------------------------------------------------------------------------------------
def compact(cov: dict, call: dict) -> dict:
    """The ``measured`` block of the calibration file: pooled coverage per cell and region, the calls' totals."""

    def one(s):
        return {
            "designs": s["designs"],
            "without_interval": s["without_interval"],
            **{k: s["coverage"][k]["share"] for k in (*ANSWERS, HISTORY)},
            "median_rel_width_peak": s["median_rel_width_peak"],
            "median_history_band": s["median_history_band"],
        }

    return {
        "by_cell": {k: one(v) for k, v in cov["by_cell"].items()},
        "by_region": {k: one(v) for k, v in cov["by_region"].items()},
        "calls": {k: call[k]["all"] for k in ("model", "union")},
    }


def print_table(cov: dict, call: dict, fz: dict | None) -> None:
    head = (
        f"{'cell / region':<30} {'n':>4} {'no iv':>5} {'peak':>6} {'defl':>6} {'hist':>6} {'width':>6} "
        f"{'band':>6} "
        f"{'err%':>5} | {'GP cov':>6} {'GP w':>6} | {'±60%':>6}"
    )
    print(head)
    print("-" * len(head))

    def pct(x):
        return "     -" if x is None else f"{100 * x:5.1f}%"

    for part in ("by_cell", "by_region"):
        for k, s in cov[part].items():
            c = s["coverage"]
            print(
                f"{k:<30} {s['designs']:>4} {s['without_interval']:>5} {pct(c[PEAK]['share'])} "
                f"{pct(c['max_deflection_mm']['share'])} {pct(c[HISTORY]['share'])} "
                f"{pct(s['median_rel_width_peak'])} {pct(s['median_history_band'])} "
                f"{s['median_abs_peak_error_pct']:5.1f} | "
                f"{pct(s['surrogate']['coverage']['share'])} {pct(s['surrogate']['median_rel_width'])} | "
                f"{pct(s['model_band']['coverage']['share'])}"
            )
        print("-" * len(head))
    print(f"calls at the solver's peak x {', '.join(f'{f:g}' for f in FACTORS)}:")
    for name, c in call.items():
        a = c["all"]
        print(
            f"  {name:<13} points {a['points']:>5}  unsafe {a['unsafe']:>3}  wrong fail {a['wrong_fail']:>3}  "
            f"undecided {100 * a['undecided_share']:5.1f}%  (by factor: "
            + ", ".join(f"{f} {100 * v['undecided_share']:.0f}%" for f, v in c["by_factor"].items())
            + ")"
        )
    if fz is not None:
        print(
            f"fuzz: {fz['designs']} designs ({fz['too_costly']} too costly, {fz['refused_by_the_check']} refused), "
            f"{fz['in_a_calibrated_cell']} in a calibrated cell, {fz['decided']} decided, {fz['final_passes']} "
            f"final passes ({fz['final_passes_verified']} verified, {fz['final_passes_checked']} checked), "
            f"unsafe {fz['unsafe']}"
        )


def result_path(arg: str) -> Path:
    """``--json``: a bare name lies under benchmarks/results/, anything else is a path."""
    p = Path(arg)
    return RESULTS / p if p.parent == Path(".") else p


def design_arguments(p: argparse.ArgumentParser) -> None:
    """The work folder, seeds, design counts, cells and speed options that run.py and ensemble.py share."""
    p.add_argument("--work", type=Path, required=True)
    p.add_argument("--calibration-seed", type=int, default=5201)
    p.add_argument("--eval-seeds", type=int, nargs="+", default=[5202, 5203])
    p.add_argument("--inside", type=int, default=60, help="designs inside the ranges, per seed")
    p.add_argument("--per-cell", type=int, default=24, help="designs per outside cell and distance, per seed")
    p.add_argument(
        "--cells",
        nargs="+",
        default=["thickness+", "drop_height+", "drop_height+,thickness+"],
        help="outside directions: parameters with their side, joined by ','",
    )
    p.add_argument(
        "--distances",
        type=float,
        nargs="+",
        default=[0.2, 0.4],
        help=f"how far out, in multiples of {DISTANCE_STEP} of a range's width",
    )
    p.add_argument("--batch", type=int, default=8)
    p.add_argument("--threads", type=int, default=1)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model", default="pretrained:impact_plate_small")
    p.add_argument("--checkpoint", default="best", help="with a run folder as --model: best, checkpoint or step_N")
    design_arguments(p)
    p.add_argument(
        "--more-calibration-seeds",
        type=int,
        nargs="*",
        default=[],
        metavar="SEED",
        help="more seeds whose designs join the calibration (a cell's bound is an order statistic: more "
        "designs, less spread from one calibration set to the next)",
    )
    p.add_argument("--fuzz", type=int, default=0, help="designs far outside the ranges through the design check")
    p.add_argument("--fuzz-seed", type=int, default=5299)
    p.add_argument(
        "--write",
        action="store_true",
        help="write the calibration, with its measured block, to the "
        "model's own file (hcmt.design.model_interval.interval_path)",
    )
    p.add_argument("--json", default="trust.json", help="result file: a name under benchmarks/results/, or a path")
    a = p.parse_args()
    calibration_seeds = [a.calibration_seed, *a.more_calibration_seeds]
    seeds = [*calibration_seeds, *a.eval_seeds, *([a.fuzz_seed] if a.fuzz else [])]
    if len(set(seeds)) != len(seeds):
        p.error(
            "--calibration-seed, --eval-seeds and --fuzz-seed must all differ: the calibration is measured on "
            "designs it was not fitted on"
        )
    for d in a.distances:
        if not 0 < d or abs(d / DISTANCE_STEP - round(d / DISTANCE_STEP)) > 1e-9:
            p.error(f"--distances: {d} is not a positive multiple of {DISTANCE_STEP}")
    if min(a.inside, a.per_cell) < MIN_DESIGNS:
        print(f"note: a cell needs {MIN_DESIGNS} designs for a {LEVEL:.0%} bound; smaller ones get no interval")
    if a.checkpoint != "best" and a.model.startswith("pretrained:"):
        p.error("--checkpoint: a shipped model has one; pass a run folder as --model")
    set_threads(a.threads)  # kept by Run.load (torch.set_num_threads alone may be taken for its default)
    t_start = time.perf_counter()
    run = Run.load(a.model, "cpu", which=a.checkpoint)
    name = run_name(run) + ("" if a.checkpoint == "best" else f"@{a.checkpoint}")
    label = name.replace(":", "_").replace("@", "_")
    cells = [parse_cell(c, varied(run.ranges)) for c in a.cells]
    runner = Runner(run, a.work, label, a.batch)
    gp, note, _ = surrogate_for_run(run, True)
    if note:
        print(f"note: {note}")
    command = portable("python benchmarks/trust/run.py " + " ".join(sys.argv[1:]))

    skipped: dict[str, int] = {}
    cal_rows = []
    for seed in calibration_seeds:
        print(f"calibration: seed {seed}", flush=True)
        cal_rows += rows_of(runner, seed_designs(run, seed, a, cells, skipped), seed, gp)
    cal = fit(
        [(r["design"], as_summary(r["model"]), as_summary(r["solver"])) for r in cal_rows],
        run.ranges,
        name,
        source={
            "seed": calibration_seeds if len(calibration_seeds) > 1 else a.calibration_seed,
            "designs": len(cal_rows),
            "command": command,
        },
    )
    print("  cells calibrated: " + ", ".join(f"{k} ({c.designs})" for k, c in sorted(cal.cells.items())))
    judge(cal_rows, cal, run.ranges)
    rows = {}
    for seed in a.eval_seeds:
        print(f"evaluation: seed {seed}", flush=True)
        rows[seed] = rows_of(runner, seed_designs(run, seed, a, cells, skipped), seed, gp)
        judge(rows[seed], cal, run.ranges)
    pooled = [r for seed in a.eval_seeds for r in rows[seed]]
    cov = {
        **{f"seed {s}": coverage(rows[s]) for s in a.eval_seeds},
        "pooled": coverage(pooled),
        "calibration seed (in sample)": coverage(cal_rows),
    }
    call = {**{f"seed {s}": calls(rows[s], run.ranges) for s in a.eval_seeds}, "pooled": calls(pooled, run.ranges)}
    m = call["pooled"]["model"]["all"]
    requirement = {
        "unsafe": m["unsafe"],
        "solver_share": m["undecided_share"],
        "solver_share_at_most": SOLVER_SHARE,
        "met": bool(m["unsafe"] == 0 and m["undecided_share"] <= SOLVER_SHARE),
    }
    fz = None
    if a.fuzz:
        print(f"fuzz: {a.fuzz} designs, seed {a.fuzz_seed}", flush=True)
        fz = fuzz(run, runner, cal, a.fuzz, a.fuzz_seed)

    all_rows = cal_rows + pooled
    result = {
        "command": command,
        "model": a.model,
        "model_label": label,
        "checkpoint_step": run.checkpoint_step,
        "hcmt": VERSION,
        "torch": torch.__version__,
        "device": "cpu",
        "machine": platform.processor() or platform.machine(),
        "cores": os.cpu_count(),
        "threads": a.threads,
        "seeds": {
            "calibration": calibration_seeds if len(calibration_seeds) > 1 else a.calibration_seed,
            "evaluation": a.eval_seeds,
            "fuzz": a.fuzz_seed if a.fuzz else None,
        },
        "designs": {
            "inside": a.inside,
            "per_cell": a.per_cell,
            "cells": [cell_label(c) for c in cells],
            "distances": a.distances,
            "redrawn_invalid": skipped,
            "calibration": len(cal_rows),
            "evaluation": len(pooled),
        },
        "level": LEVEL,
        "min_designs": MIN_DESIGNS,
        "model_band": MODEL_BAND,
        "factors": list(FACTORS),
        "surrogate": gp.label if gp is not None else None,
        "calibration": cal.to_json(),
        "coverage": cov,
        "calls": call,
        "requirement": requirement,
        "fuzz": fz,
        "seconds": {
            "solver_median_per_design": median([r["solver"]["wall_s"] for r in all_rows]),
            "model_median_per_design": median([r["model"]["wall_s"] for r in all_rows]),
            "solver_runs_here": runner.solver_runs,
            "model_runs_here": runner.model_runs,
            "wall_this_process": time.perf_counter() - t_start,
        },
        "wrote_calibration": None,
    }
    if a.write:
        target = interval_path(run)
        if target is None:
            p.error("--write: the model has no folder of its own to hold its calibration")
        measured = {
            "seeds": a.eval_seeds,
            "designs": len(pooled),
            "command": command,
            **compact(cov["pooled"], call["pooled"]),
            "fuzz": None
            if fz is None
            else {k: fz[k] for k in ("designs", "checked", "decided", "final_passes", "unsafe", "too_costly")},
        }
        replace(cal, measured=portable(measured)).save(target)
        result["wrote_calibration"] = str(target)
        print(f"wrote {portable(target)}")
    path = result_path(a.json)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(portable(result), indent=2))
    print(
        f"\npooled over seeds {', '.join(map(str, a.eval_seeds))} (calibrated on seed(s) "
        f"{', '.join(map(str, calibration_seeds))}; "
        f"coverage: share of designs with an interval whose solver value it holds; width: median (hi - lo) / model):"
    )
    print_table(cov["pooled"], call["pooled"], fz)
    print(
        f"requirement (model interval alone): unsafe {requirement['unsafe']}, solver on "
        f"{100 * requirement['solver_share']:.1f} % of points (at most {100 * SOLVER_SHARE:.0f} %): "
        f"{'met' if requirement['met'] else 'not met'}"
    )
    print(f"wrote {portable(path)}")


if __name__ == "__main__":
    main()
