"""``hcmt surrogate fit DATA --out FILE``: a Gaussian-process response surface on a dataset's training designs
(:mod:`hcmt.design.surrogate`); argument parsing and printing only."""
from __future__ import annotations

import argparse
import sys

from hcmt.cli import CommandError
from hcmt.design.surrogate import QUANTITIES, RESTARTS, Surrogate
from hcmt.files import check_apart


def configure(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="action", metavar="ACTION", required=True)
    f = sub.add_parser("fit", help="fit the response surface on a dataset's solver runs and write it as JSON",
                       description="Fit one Gaussian process per scalar answer (" + ", ".join(QUANTITIES) + ") on "
                       "the design parameters of an hcmt-generated Impact Plate dataset's split; written as JSON "
                       "(no pickle). Use it with `hcmt predict/sweep --surrogate FILE`, or save it as "
                       "RUN/surrogate.json to make it the run's own.")
    f.add_argument("data", help="an hcmt-generated Impact Plate dataset (`hcmt generate impact-plate`)")
    f.add_argument("--out", required=True, help="the surrogate file to write (JSON)")
    f.add_argument("--split", default="train", help="the split whose designs it is fitted on (default train)")
    f.add_argument("--limit", type=int, help="fit on the first N trajectories only")
    f.add_argument("--restarts", type=int, default=RESTARTS,
                   help=f"optimizer restarts of the marginal likelihood (default {RESTARTS})")
    f.add_argument("--seed", type=int, default=0, help="seed of the optimizer restarts")
    f.add_argument("--stress-field", choices=("stress", "stress_max"), default="stress",
                   help="the stress the model learned (default stress; stress_max: `generate --peak-stress` data and "
                        "a model trained with --set data.stress_field=stress_max)")
    f.add_argument("--label", help="what the training designs are, recorded in the file (default: the dataset's "
                   "path and split)")


def main(args: argparse.Namespace) -> int:
    if args.limit is not None and args.limit < 1:
        raise CommandError(f"--limit must be >= 1, got {args.limit}")
    if args.restarts < 0:
        raise CommandError(f"--restarts must be >= 0, got {args.restarts}")
    check_apart({"--out": args.out}, {"DATA": args.data})
    s = Surrogate.fit_dataset(args.data, args.split, limit=args.limit, restarts=args.restarts, seed=args.seed,
                              stress_field=args.stress_field)
    if args.label:
        s.source = args.label
    if s.censored:
        print(f"hcmt surrogate: warning: {args.data}: in {s.censored} of its {len(s)} runs the window "
              f"({s.dataset['frames']} frames) ends before the ball leaves the plate: contact_end_ms is the window's "
              "end there" + ("; in all, so peaks may be missed and predict will not use that bound (generate with "
                             "more --frames)" if s.censored >= len(s) else ""), file=sys.stderr)
    path = s.save(args.out)
    print(f"fitted on {s.source}: {len(s.parameters)} parameters ({', '.join(s.parameters)}); held fixed: "
          + (", ".join(f"{k}={v:g}" for k, v in s.fixed.items()) or "none"))
    for q, k in s.kernels.items():
        ls = ", ".join(f"{p}={v:.3g}" for p, v in zip(s.parameters, k["length_scales"]))
        print(f"  {q}: c^2 {k['constant']:.3g}, noise {k['noise']:.2g}, length scales {ls}")
    print(f"wrote {path}")
    return 0
