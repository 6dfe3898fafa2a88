"""The `hcmt` command.

Every subcommand is registered in :data:`COMMANDS` below, and nowhere else: name -> (module, one-line help).
Each module defines ``configure(parser)`` (adds its arguments) and ``main(args) -> int``. Modules are imported
only when their command runs, so ``hcmt --help`` stays fast (no torch import).
"""
from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys

from hcmt.config import VERSION
from hcmt.data.errors import DatasetError

COMMANDS: dict[str, tuple[str, str]] = {
    "generate": ("hcmt.sim.generate", "generate a dataset with the built-in FEM solver (impact-plate)"),
    "simulate": ("hcmt.sim.generate", "simulate one Impact Plate design with explicit parameters (solver baseline)"),
    "convert": ("hcmt.data.convert", "convert a MeshGraphNets/HCMT TFRecord or Deformable Plate pickle dataset to native HDF5"),
    "info": ("hcmt.data.info", "summarize a native dataset: splits, trajectories, nodes, fields, design parameters"),
    "hierarchy": ("hcmt.graph.report", "build the HCMT mesh hierarchy of a dataset and report its quality per level"),
    "train": ("hcmt.cli.train", "train HCMT, MeshGraphNets or Graph Transformer on a dataset"),
    "rollout": ("hcmt.cli.train", "roll a trained model out over a dataset split (writes HDF5 predictions)"),
    "evaluate": ("hcmt.cli.train", "compute the paper's RMSE metrics of a run on a split (writes RUN/metrics_<split>.json)"),
    "compare": ("hcmt.cli.train", "aggregate several runs into the paper's Table 2 layout (mean +- std)"),
    "predict": ("hcmt.cli.design", "peak stress and deflection of new Impact Plate designs from a trained model, "
                "no solver run (--verify compares with the solver)"),
    "sweep": ("hcmt.cli.design", "one design parameter varied over a range, predicted in one batch: trend, limit "
              "for a yield stress, and with --verify the solver's"),
    "models": ("hcmt.cli.design", "list the trained models shipped with hcmt (pretrained:NAME)"),
    "surrogate": ("hcmt.cli.surrogate", "fit a Gaussian-process response surface on a dataset's solver runs "
                  "(the scalar answers an engineer would fit instead of a mesh model)"),
    "plot": ("hcmt.cli.viz", "draw stress contours, animations, error curves and training curves of a run"),
    "export": ("hcmt.cli.viz", "export a rollout to ParaView (VTU or XDMF time series)"),
    "demo": ("hcmt.cli.demo", "quickstart: the shipped HCMT model beside the solver on three new designs "
             "(--train: the whole pipeline)"),
}


#: commands that compute with torch: they take ``--threads``
THREADED = ("generate", "simulate", "hierarchy", "train", "rollout", "evaluate", "predict", "sweep", "plot", "export",
            "demo")


def threads_arg(text: str) -> int | str:
    if text == "auto":
        return text
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1 or auto, got {text!r}")
    return n


def auto_threads() -> int:
    """The CPU cores not already busy: cores minus the 1-minute load average (at least 1). On a machine whose other
    cores run another job this is 1 thread, never the oversubscribed default that made a design take 10x longer
    (docs/RESULTS.md, "Threads")."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    try:
        busy = os.getloadavg()[0]
    except OSError:  # no load average on this platform
        busy = 0.0
    return max(1, min(cores, int(cores - busy + 0.5)))


def set_threads(threads: int | str) -> int:
    """Apply ``--threads`` to torch's intra-op pool; returns the number set."""
    import torch  # heavy: loaded only by commands that compute, so `hcmt --help` stays fast

    n = auto_threads() if threads == "auto" else int(threads)
    torch.set_num_threads(n)
    return n


class CommandError(Exception):
    """An error the user can fix; printed as one line, exit status 2."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="hcmt", description="Learned simulation of flexible bodies in contact: the Hierarchical Contact Mesh "
        "Transformer (ICLR 2024), its baselines, and a built-in FEM generator of ground truth.",
        epilog="`hcmt COMMAND --help` gives each command's options.")
    parser.add_argument("--version", action="version", version=f"hcmt {VERSION}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", title="commands")
    requested = _requested_command(sys.argv[1:])
    for name, (module, help_text) in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        if name == requested:  # import only the module that will run
            mod = importlib.import_module(module)
            configure = getattr(mod, f"configure_{name}", None) or mod.configure
            configure(p)
            if name in THREADED:
                p.add_argument("--threads", type=threads_arg, default="auto", metavar="N",
                               help="CPU threads for torch (default auto: the cores not busy with other work, "
                                    "from the load average)")
            p.set_defaults(_run=getattr(mod, f"main_{name}", None) or mod.main)
    return parser


def _requested_command(argv: list[str]) -> str | None:
    for a in argv:
        if not a.startswith("-"):
            return a
    return None


def main(argv: list[str] | None = None) -> int:
    if argv is not None:
        sys.argv = [sys.argv[0], *argv]
    parser = build_parser()
    args = parser.parse_args(sys.argv[1:])
    if not getattr(args, "_run", None):
        parser.print_help()
        return 0 if args.command is None else 2

    previous = signal.signal(signal.SIGTERM, _terminate)  # SIGTERM ends a command as Ctrl-C does
    try:
        if getattr(args, "threads", None) is not None:
            set_threads(args.threads)
        return int(args._run(args) or 0)
    except (DatasetError, CommandError, FileNotFoundError, ValueError) as exc:
        print(f"hcmt {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # disk full, permissions, ...: the path and the system's reason
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        print(f"hcmt {args.command}: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        print(f"hcmt {args.command}: {str(exc) or 'interrupted'}; {_resume_hint(args.command)}",
              file=sys.stderr)
        return 130
    finally:
        signal.signal(signal.SIGTERM, previous)


def _terminate(signum, frame):
    raise KeyboardInterrupt


def _resume_hint(command: str) -> str:
    """What an interrupted command kept and how to go on."""
    argv = " ".join(sys.argv[1:])
    if command == "train":
        return "continue with: hcmt " + (argv if "--resume" in sys.argv else argv + " --resume")
    if command == "generate":
        return "finished trajectories are kept; the same command continues with the missing ones: hcmt " + argv
    return "nothing half-written was left; run the command again: hcmt " + argv
