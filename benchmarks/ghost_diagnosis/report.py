"""docs/RESULTS.md's section on where the mesh model's stress after the ball leaves comes from
(benchmarks/ghost_diagnosis/run.py)."""

from __future__ import annotations

from report_common import load, opened, sentences


def ghost_diagnosis(lines):
    d = opened(lines, "### Where the stress after the ball leaves comes from", "ghost_diagnosis.json")
    if d is None:
        return
    g = d["ghost_difference_median"]
    lines += [
        f"Command: `{d['command']}` ({d['trajectories']} trajectories of the `{d['split']}` split, the model "
        f"{d['run']}). Medians over trajectories:",
        "",
        "| stress history | ghost ratio | ghost difference from the solver |",
        "|---|---|---|",
        f"| solver | {d['solver_ghost_ratio_median']:.3f} | |",
        f"| rollout (what `hcmt predict` reports) | {d['rollout_ghost_ratio_median']:.3f} | {g['rollout']:.3f} |",
        f"| teacher-forced (the solver's state at every frame) | {d['teacher_forced_ghost_ratio_median']:.3f} | "
        f"{g['teacher_forced']:.3f} |",
    ]
    if "perturbed" in g:
        lines.append(f"| rollout from first frames moved by {d['perturb_mm']:g} mm | | {g['perturbed']:.3f} |")
    lines += [
        "",
        f"The rollout's ball leaves {d['contact_end_frames_late_median']:+.0f} frames from the solver's (median).",
    ]
    if "amplification_median" in d:
        lines.append(
            f"A perturbation of {d['perturb_mm']:g} mm at the first frames is {d['amplification_median']:.1e} "
            f"times larger at the last frame (median) and moves the ghost ratio by "
            f"{d['perturbed_ghost_shift_median']:.3f} (median), against the rollout's ghost difference of "
            f"{g['rollout']:.3f}: the learned dynamics amplify a small error by orders of magnitude over a "
            "rollout, and the model's own one-step errors, far larger than this perturbation, are amplified "
            "the same way. With the teacher-forced stress letting go (the stress head is right given the "
            "right state), the stress that stays comes from the rollout's drifted state; the remedy is "
            "stability in training (noise, pushforward, budget), which the long run and the scaling study "
            "measure."
        )
    lines.append("")


#: what each arm of benchmarks/ghost_diagnosis/ablate.py changes, in words
ARM_WORDS = {
    "start": "none: the run itself, before the arms' steps",
    "control": "nothing (the run's recipe)",
    "control-seed1": "nothing, another seed",
    "no-pushforward": "train.pushforward=0",
    "noise-x10": "train.noise_std=0.003 (10x)",
    "contact-free-x4": "train.contact_free_weight=4",
}


def ghost_ablations(lines):
    d = opened(lines, "### The stress that stays: measured ablations (validation split)", "ghost_ablations.json")
    if d is not None:
        ablation_text(lines, d, load("ghost_diagnosis.json"))


def ablation_text(lines: list[str], d: dict, shipped: dict | None) -> None:
    """The section's body from ghost_ablations.json (``d``) and the shipped model's diagnosis (``shipped``)."""
    arms = d["arms"]
    lines += [
        f"Command: `{d['command']}`. Every arm continues the run `{d['init']}` for {d['steps']:,} steps "
        f"({', '.join(d['common'])}; normalizers frozen) with one option changed, then "
        "`benchmarks/ghost_diagnosis/run.py`'s reading of the validation split (medians over its "
        f"{len(next(iter(arms.values()))['rows'])} "
        "trajectories).",
        "",
        "| arm | change | ghost difference, rollout | ghost difference, teacher-forced | peak plate stress error "
        "| max deflection error | a 1e-6 mm perturbation grows |",
        "|---|---|---|---|---|---|---|",
    ]

    def pct(v):
        return "—" if v is None else f"{100 * v:.1f} %"

    for name, a in arms.items():
        g = a["ghost_difference_median"]
        lines.append(
            f"| {name} | {ARM_WORDS.get(name, ', '.join(a['sets']))} | {g['rollout']:.3f} | "
            f"{g['teacher_forced']:.3f} | {pct(a.get('peak_error_median'))} | "
            f"{pct(a.get('deflection_error_median'))} | {a['amplification_median']:.1e}x |"
        )
    if shipped:
        g = shipped["ghost_difference_median"]
        lines.append(
            f"| shipped model ({shipped['run']}) | another run: 36,000 steps on 120 designs | "
            f"{g['rollout']:.3f} | {g['teacher_forced']:.3f} | {pct(shipped.get('peak_error_median'))} | "
            f"{pct(shipped.get('deflection_error_median'))} | {shipped['amplification_median']:.1e}x |"
        )
    lines += [
        "",
        sentences(
            "Compare the arms with `control`, not with `start`: `start` is the run's best.pt, the checkpoint whose "
            "validation position RMSE-all was the lowest on these same validation trajectories (a choice that favours "
            "it on them), and every arm starts Adam afresh (`--init` takes the weights, not the optimizer's moments) "
            "and is read at its last step."
        ),
        "",
    ]
    if "control" in arms and "control-seed1" in arms:
        ghost = {k: a["ghost_difference_median"]["rollout"] for k, a in arms.items()}
        spread = abs(ghost["control"] - ghost["control-seed1"])
        said = [f"The protocol's own spread (control against control-seed1) is {spread:.3f} in the ghost difference."]
        c = arms["control"]
        options = [n for n in arms if n not in ("start", "control", "control-seed1")]
        for name in options:
            a, delta = arms[name], ghost[name] - ghost["control"]
            said.append(
                f"{name}: ghost difference {delta:+.3f} against control ("
                + (
                    "within that spread"
                    if abs(delta) <= spread
                    else "lower, beyond that spread"
                    if delta < 0
                    else "higher, beyond that spread"
                )
                + f"); peak plate stress error {100 * a['peak_error_median']:.1f} % against "
                f"{100 * c['peak_error_median']:.1f} %, max deflection error "
                f"{100 * a['deflection_error_median']:.1f} % against {100 * c['deflection_error_median']:.1f} %"
                f"; a 1e-6 mm perturbation grows {a['amplification_median']:.0f}× against "
                f"{c['amplification_median']:.0f}×; teacher-forced ghost difference "
                f"{a['ghost_difference_median']['teacher_forced']:.3f} against "
                f"{c['ghost_difference_median']['teacher_forced']:.3f}."
            )
        lines += [" ".join(said), ""]
        beyond = [n for n in options if abs(ghost[n] - ghost["control"]) > spread]
        verdict = (
            f"Beyond the protocol's spread: {', '.join(beyond)}."
            if beyond
            else "No training option tried moves the ghost difference beyond the protocol's spread at this budget."
        )
        if shipped and "start" in arms:
            verdict += (
                f" The budget does: the shipped model's ghost difference on the same trajectories is "
                f"{shipped['ghost_difference_median']['rollout']:.3f}, the long run's {ghost['start']:.3f} at "
                f"its checkpoint ({min(ghost['control'], ghost['control-seed1']):.3f}-"
                f"{max(ghost['control'], ghost['control-seed1']):.3f} in the two controls, read without "
                "that choice), and a 1e-6 mm perturbation grows "
                f"{shipped['amplification_median']:.0f}× against {arms['start']['amplification_median']:.0f}×."
            )
        lines += [verdict, ""]
