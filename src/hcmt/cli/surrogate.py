"""``hcmt surrogate fit DATA --out FILE``: a Gaussian-process response surface on a dataset's training designs
(:mod:`hcmt.design.surrogate`); printing only (its arguments: :mod:`hcmt.cli.parsers`)."""
from __future__ import annotations

import argparse

from hcmt.design.surrogate import Surrogate


def main(args: argparse.Namespace) -> int:
    s = Surrogate.fit_dataset(args.data, args.split, limit=args.limit, restarts=args.restarts, seed=args.seed,
                              stress_field=args.stress_field)
    if args.label:
        s.source = args.label
    path = s.save(args.out)
    print(f"fitted on {s.source}: {len(s.parameters)} parameters ({', '.join(s.parameters)}); held fixed: "
          + (", ".join(f"{k}={v:g}" for k, v in s.fixed.items()) or "none"))
    for q, k in s.kernels.items():
        ls = ", ".join(f"{p}={v:.3g}" for p, v in zip(s.parameters, k["length_scales"]))
        print(f"  {q}: c^2 {k['constant']:.3g}, noise {k['noise']:.2g}, length scales {ls}")
    print(f"wrote {path}")
    return 0
