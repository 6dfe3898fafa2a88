"""The `hcmt` command.

Every subcommand is registered in :data:`COMMANDS` below, and nowhere else: name -> (module, one-line help).
Each command's arguments and first checks are in :mod:`hcmt.cli.parsers` (``configure_NAME(parser)``,
``check_NAME(args)``: light, no torch), its work in its module (``main_NAME(args) -> int``, or ``main``), imported
only once the command line has parsed and passed those checks: ``hcmt --help`` and a mistake in the command line
(``hcmt predict MODEL --threads 0``) are answered in a fraction of a second, in one line.

Errors: a user's mistake is one line and exit 2: a :class:`CommandError` raised here, or the library's
:class:`hcmt.errors.InputError` (its parameter printed as the command's flag: ``batch`` -> ``--batch``), a missing
file, a full disk; so is a model that diverged on the input (:class:`hcmt.errors.RolloutError`). Any other exception
is a bug and shows its traceback. A value a user gave is echoed cut to 60 characters ("…"), so that a line stays
under :data:`LINE` characters but for its paths, and no line exceeds :data:`GUARD`. Ctrl-C exits 130, SIGTERM 143
(128 + the signal's number).
"""

from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys
from pathlib import Path

# auto_threads and set_threads (``--threads``) live in hcmt.config, shared with the Python API; here for the commands
from hcmt.config import VERSION, auto_threads, machine_cores, set_threads  # noqa: F401
from hcmt.errors import InputError, RolloutError

COMMANDS: dict[str, tuple[str, str]] = {
    "generate": ("hcmt.cli.data", "generate a dataset with the built-in FEM solvers (impact-plate, deforming-plate)"),
    "simulate": ("hcmt.cli.data", "simulate one Impact Plate design with explicit parameters (solver baseline)"),
    "convert": (
        "hcmt.cli.data",
        "convert a MeshGraphNets/HCMT TFRecord or Deformable Plate pickle dataset to native HDF5",
    ),
    "info": ("hcmt.cli.data", "summarize a native dataset: splits, trajectories, nodes, fields, design parameters"),
    "hierarchy": ("hcmt.cli.data", "build the HCMT mesh hierarchy of a dataset and report its quality per level"),
    "train": ("hcmt.cli.train", "train HCMT, MeshGraphNets or Graph Transformer on a dataset"),
    "rollout": ("hcmt.cli.train", "roll a trained model out over a dataset split (writes HDF5 predictions)"),
    "evaluate": (
        "hcmt.cli.train",
        "compute the paper's RMSE metrics of a run on a split (writes RUN/metrics_<split>.json)",
    ),
    "compare": ("hcmt.cli.train", "aggregate several runs into the paper's Table 2 layout (mean +- std)"),
    "predict": (
        "hcmt.cli.design",
        "peak stress and deflection of new Impact Plate designs from a trained model, "
        "no solver run (--verify compares with the solver)",
    ),
    "sweep": (
        "hcmt.cli.design",
        "one design parameter varied over a range, predicted in batches of --batch points: "
        "trend, limit for a yield stress, and with --verify the solver's",
    ),
    "models": ("hcmt.cli.design", "list the trained models shipped with hcmt (pretrained:NAME)"),
    "surrogate": (
        "hcmt.cli.surrogate",
        "fit a Gaussian-process response surface on a dataset's solver runs "
        "(the scalar answers an engineer would fit instead of a mesh model)",
    ),
    "plot": ("hcmt.cli.viz", "draw stress contours, animations, error curves and training curves of a run"),
    "export": ("hcmt.cli.viz", "export a rollout to ParaView (VTU or XDMF time series)"),
    "demo": (
        "hcmt.cli.demo",
        "quickstart: the shipped HCMT model beside the solver on three new designs (--train: the whole pipeline)",
    ),
}


#: commands that compute with torch: they take ``--threads``
THREADED = (
    "generate",
    "simulate",
    "convert",
    "info",
    "hierarchy",
    "train",
    "rollout",
    "evaluate",
    "compare",
    "predict",
    "sweep",
    "plot",
    "export",
    "demo",
)
#: the longest error line with its values cut (``hcmt.errors.clip``), paths aside; and the longest any may print
LINE, GUARD = 300, 600


class CommandError(Exception):
    """An error the user can fix in the command line; printed as one line, exit status 2."""


def check_outputs(files: dict[str, str | None], folders: dict[str, str | None] | None = None) -> None:
    """Check every output of a command before the first is written (``files``: option -> file path, ``folders``:
    option -> folder; None: not asked for): a file path that is empty, an existing folder, a symlink, a file of a
    dataset (its meta.json or a split file beside it), or under a file; a folder that is an existing file; a place
    this user cannot write; two outputs on one path. One line each."""
    seen: dict[Path, str] = {}
    for kind, items in (("file", files), ("folder", folders or {})):
        for option, value in items.items():
            if value is None:
                continue
            if not str(value).strip():
                raise CommandError(f"{option}: an empty path; name a {kind}")
            path = Path(value)
            if kind == "file" and path.is_dir():
                raise CommandError(f"{option} {value}: is a folder; name a file")
            if kind == "file" and path.is_symlink():  # the output would replace the link, not what it points to
                raise CommandError(
                    f"{option} {value}: is a symlink (to {os.readlink(path)}); name the file itself or a new path"
                )
            if (
                kind == "file"
                and path.is_file()
                and (
                    (path.suffix == ".h5" and (path.parent / "meta.json").is_file())
                    or (path.name == "meta.json" and any(path.parent.glob("*.h5")))
                )
            ):  # part of a dataset
                raise CommandError(
                    f"{option} {value}: a file of the dataset {path.parent} (meta.json and its split "
                    "files); write the output elsewhere"
                )
            if kind == "folder" and path.exists() and not path.is_dir():
                raise CommandError(f"{option} {value}: is a file; name a folder")
            parent = path.parent if kind == "file" else path
            while not parent.exists() and parent != parent.parent:
                parent = parent.parent
            if not parent.is_dir():
                raise CommandError(f"{option} {value}: {parent} is a file, not a folder")
            if not os.access(parent, os.W_OK | os.X_OK):
                raise CommandError(f"{option} {value}: {parent} is not writable")
            try:
                key = path.resolve()
            except (RuntimeError, OSError) as exc:  # a symlink loop
                raise CommandError(f"{option} {value}: {exc}") from None
            if key in seen:
                raise CommandError(f"{option} {value}: the same path as {seen[key]}; give each output its own")
            seen[key] = option


class Parser(argparse.ArgumentParser):
    """argparse's parser, its mistakes one line (``hcmt predict: error: argument --threads: ...; see 'hcmt predict
    --help'``) and exit 2 instead of the usage block."""

    def error(self, message: str):
        print(one_line(f"{self.prog}: error: {message}", f"; see '{self.prog} --help'"), file=sys.stderr)
        raise SystemExit(2)


def one_line(text: str, tail: str = "") -> str:
    """``text + tail`` on one line, a last guard behind the values cut where they are echoed (``clip``: a line
    stays under :data:`LINE` characters but for its paths): a word over 100 characters (a path, a value) is cut in
    its middle, keeping its start and its end (the file's name), and a line still over :data:`GUARD` characters
    is cut in its own middle, keeping its start (the command and the flag) and its end (what was expected)."""
    text = " ".join(w if len(w) <= 100 else w[:30] + "…" + w[-69:] for w in str(text).split())
    room = GUARD - len(tail)
    if len(text) > room:
        head = room * 2 // 3
        text = text[: head - 1] + "…" + text[len(text) - (room - head) :]
    return text + tail


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(
        prog="hcmt",
        description="Learned simulation of flexible bodies in contact: the Hierarchical Contact Mesh "
        "Transformer (ICLR 2024), its baselines, and a built-in FEM generator of ground truth.",
        epilog="`hcmt COMMAND --help` gives each command's options.",
    )
    parser.add_argument("--version", action="version", version=f"hcmt {VERSION}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", title="commands")
    requested = _requested_command(sys.argv[1:])
    for name, (module, help_text) in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        if name == requested:  # only the command that will run gets its arguments (light: hcmt.cli.parsers)
            getattr(importlib.import_module("hcmt.cli.parsers"), f"configure_{name}")(p)
            if name in THREADED and not any(a.dest == "no_progress" for a in p._actions):
                p.add_argument("--no-progress", action="store_true", help="no progress bars")
            if name in THREADED:
                threads_arg = importlib.import_module("hcmt.cli.parsers").threads_arg
                p.add_argument(
                    "--threads",
                    type=threads_arg,
                    default="auto",
                    metavar="N",
                    help=f"CPU threads for torch, 1 to this machine's cores ({machine_cores()}), or auto "
                    "(default: the cores not busy with other work, from the 1-minute load average, "
                    "at least 1)",
                )
            p.set_defaults(_module=module)
            parser.command_parser = p
    return parser


def flag_of(parser: argparse.ArgumentParser | None, param: str | None) -> str | None:
    """The command-line name of the library parameter ``param`` in this command: its option (``--batch``), its
    positional argument's name (``DATA``), the name :func:`hcmt.cli.parsers.same_as` gave it (``path`` ->
    ``MODEL``), or None when the command has no such argument."""
    if parser is None or not param:
        return None
    if param in getattr(parser, "param_flags", {}):
        return parser.param_flags[param]
    for action in parser._actions:
        if action.dest == param.replace("-", "_"):
            return max(action.option_strings, key=len) if action.option_strings else action.dest.upper()
    return None


def _requested_command(argv: list[str]) -> str | None:
    for a in argv:
        if not a.startswith("-"):
            return a
    return None


def main(argv: list[str] | None = None) -> int:
    if argv is not None:
        sys.argv = [sys.argv[0], *argv]
    _stopped_by.clear()
    previous = signal.signal(signal.SIGTERM, _terminate)  # SIGTERM ends a command as Ctrl-C does, from the start
    # Ctrl-C interrupts whatever handler the embedding process left (a caller that ignored SIGINT, for instance)
    previous_int = signal.signal(signal.SIGINT, signal.default_int_handler)
    command, started, parser = _requested_command(sys.argv[1:]) or "", False, None
    try:
        parser = build_parser()
        try:
            args, extra = parser.parse_known_args(sys.argv[1:])
            if extra:  # the command's parser says so, pointing to its own --help (`hcmt predict --help`)
                _parser_of(parser, args).error(f"unrecognized arguments: {' '.join(extra)}")
        except SystemExit as stop:  # --help, --version: 0; a mistake: Parser.error's one line was printed, 2
            if stop.code == 2:
                return 2
            raise
        if not getattr(args, "_module", None):
            parser.print_help()
            return 0 if args.command is None else 2
        command = args.command
        check = getattr(importlib.import_module("hcmt.cli.parsers"), f"check_{command}", None)
        if check is not None:
            check(args)  # the cheap checks: one line before torch loads
        module = importlib.import_module(args._module)  # torch: seconds on a busy machine
        if getattr(args, "threads", None) is not None:
            set_threads(args.threads)
        run = getattr(module, f"main_{command}", None) or module.main
        started = True
        return int(run(args) or 0)
    except BrokenPipeError:  # the reader went away (`hcmt models --json | head`): nothing more to say to it
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except InputError as exc:
        flag = flag_of(getattr(parser, "command_parser", None), exc.param)
        return _error(command, exc.worded(flag))
    except (CommandError, FileNotFoundError, RolloutError) as exc:
        return _error(command, str(exc))
    except OSError as exc:  # disk full, permissions, ...: the path and the system's reason
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        return _error(command, f"{where}{exc.strerror or exc}")
    except KeyboardInterrupt as exc:
        signum = _stopped_by[-1] if _stopped_by else signal.SIGINT
        what = "interrupted" + (" (SIGTERM)" if signum == signal.SIGTERM else "")
        if started:
            print(f"hcmt {command}: {str(exc) or what}; {_resume_hint(command)}", file=sys.stderr)
        else:
            print(f"hcmt {command}: {what} while starting; nothing was written", file=sys.stderr)
        return 128 + int(signum)
    finally:
        signal.signal(signal.SIGTERM, previous)
        signal.signal(signal.SIGINT, previous_int)


def _parser_of(parser: argparse.ArgumentParser, args: argparse.Namespace) -> argparse.ArgumentParser:
    """The parser of the command line's deepest command (``hcmt surrogate fit``'s, ``hcmt predict``'s, else
    ``hcmt``'s): the one whose --help an unknown option points to."""
    p = getattr(parser, "command_parser", parser)
    for action in p._actions:
        if isinstance(action, argparse._SubParsersAction) and getattr(args, action.dest, None) in action.choices:
            return action.choices[getattr(args, action.dest)]
    return p


def _error(command: str, text: str) -> int:
    print(one_line(f"hcmt {command}: error: {text}"), file=sys.stderr)
    return 2


#: the signal that stopped the command (SIGTERM), for its exit status 128 + N
_stopped_by: list[int] = []


def _terminate(signum, frame):
    _stopped_by.append(signum)
    raise KeyboardInterrupt


def _resume_hint(command: str) -> str:
    """What an interrupted command kept and how to go on."""
    argv = " ".join(sys.argv[1:])
    if command == "train":
        return "continue with: hcmt " + (argv if "--resume" in sys.argv else argv + " --resume")
    if command == "generate":
        return "finished trajectories are kept; the same command continues with the missing ones: hcmt " + argv
    return "nothing half-written was left; run the command again: hcmt " + argv
