"""docs/RESULTS.md's section on where the mesh model's stress after the ball leaves comes from
(benchmarks/ghost_diagnosis/run.py)."""
from __future__ import annotations

from report_common import opened


def ghost_diagnosis(lines):
    d = opened(lines, "### Where the stress after the ball leaves comes from", "ghost_diagnosis.json")
    if d is None:
        return
    g = d["ghost_difference_median"]
    lines += [f"Command: `{d['command']}` ({d['trajectories']} trajectories of the `{d['split']}` split, the model "
              f"{d['run']}). Medians over trajectories:", "",
              "| stress history | ghost ratio | ghost difference from the solver |", "|---|---|---|",
              f"| solver | {d['solver_ghost_ratio_median']:.3f} | |",
              f"| rollout (what `hcmt predict` reports) | {d['rollout_ghost_ratio_median']:.3f} | "
              f"{g['rollout']:.3f} |",
              f"| teacher-forced (the solver's state at every frame) | {d['teacher_forced_ghost_ratio_median']:.3f} | "
              f"{g['teacher_forced']:.3f} |"]
    if "perturbed" in g:
        lines.append(f"| rollout from first frames moved by {d['perturb_mm']:g} mm | | {g['perturbed']:.3f} |")
    lines += ["", f"The rollout's ball leaves {d['contact_end_frames_late_median']:+.0f} frames from the solver's "
              "(median)."]
    if "amplification_median" in d:
        lines.append(f"A perturbation of {d['perturb_mm']:g} mm at the first frames is {d['amplification_median']:.1e} "
                     f"times larger at the last frame (median) and moves the ghost ratio by "
                     f"{d['perturbed_ghost_shift_median']:.3f} (median), against the rollout's ghost difference of "
                     f"{g['rollout']:.3f}: the learned dynamics amplify a small error by orders of magnitude over a "
                     "rollout, and the model's own one-step errors, far larger than this perturbation, are amplified "
                     "the same way. With the teacher-forced stress letting go (the stress head is right given the "
                     "right state), the stress that stays comes from the rollout's drifted state; the remedy is "
                     "stability in training (noise, pushforward, budget), which the long run and the scaling study "
                     "measure.")
    lines.append("")
