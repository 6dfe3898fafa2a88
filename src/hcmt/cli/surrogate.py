"""``hcmt surrogate fit DATA --out FILE``: a Gaussian-process response surface on a dataset's training designs
(:mod:`hcmt.design.surrogate`); printing only (its arguments: :mod:`hcmt.cli.parsers`)."""

from __future__ import annotations

import argparse
import sys

from hcmt.design.surrogate import Surrogate
from hcmt.files import check_apart


def main(args: argparse.Namespace) -> int:
    check_apart({"--out": args.out}, {"DATA": args.data})
    s = Surrogate.fit_dataset(
        args.data, args.split, limit=args.limit, restarts=args.restarts, seed=args.seed, stress_field=args.stress_field
    )
    if args.label:
        s.source = args.label
    if s.censored:
        print(
            f"hcmt surrogate: warning: {args.data}: in {s.censored} of its {len(s)} runs the window "
            f"({s.dataset['frames']} frames) ends before the ball leaves the plate: contact_end_ms is the window's "
            "end there"
            + (
                "; in all, so peaks may be missed and predict will not use that bound (generate with more --frames)"
                if s.censored >= len(s)
                else ""
            ),
            file=sys.stderr,
        )
    path = s.save(args.out)
    print(
        f"fitted on {s.source}: {len(s.parameters)} parameters ({', '.join(s.parameters)}); held fixed: "
        + (", ".join(f"{k}={v:g}" for k, v in s.fixed.items()) or "none")
    )
    for q, k in s.kernels.items():
        ls = ", ".join(f"{p}={v:.3g}" for p, v in zip(s.parameters, k["length_scales"]))
        print(f"  {q}: c^2 {k['constant']:.3g}, noise {k['noise']:.2g}, length scales {ls}")
    print(f"wrote {path}")
    return 0
