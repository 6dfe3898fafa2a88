"""The parsers' shared pieces: bounded counts (one rule: a value outside the bound is refused in one line),
options several commands take, and the cheap checks of a run folder, a folder or a dataset split."""

from __future__ import annotations

import argparse
from pathlib import Path

from hcmt.cli import CommandError
from hcmt.config import INFERENCE_COMPILE_MODES, MAX_BATCH, available_pretrained, machine_cores
from hcmt.design.basics import DEFAULT_READOUT, READOUTS
from hcmt.errors import clip

#: the largest count of a few options without a natural bound: training steps, frames a picture shows per second,
#: optimizer restarts, hierarchy levels, a picture's frame stride
MAX_STEPS, MAX_FPS, MAX_RESTARTS, MAX_LEVELS, MAX_STRIDE = 10**9, 100, 100, 64, 10_000


# -- counts --------------------------------------------------------------------------------------------------------
def count(lo: int, hi: int, what: str = ""):
    """An argparse type: a whole number from ``lo`` to ``hi`` (``what``: why that bound), else one line."""

    def parse(text: str) -> int:
        try:
            n = int(text)
        except ValueError:
            n = None
        if n is None or not lo <= n <= hi:
            raise argparse.ArgumentTypeError(f"expected a whole number from {lo} to {hi:,}{what}, got {clip(text)!r}")
        return n

    return parse


def cores_count(text: str) -> int:
    return count(1, machine_cores(), " (this machine's cores)")(text)


def threads_arg(text: str) -> int | str:
    return text if text == "auto" else count(1, machine_cores(), " (this machine's cores) or auto")(text)


def span(lo: int, hi: int) -> str:
    """How a count's help states its bound: ``1 to 1,024``."""
    return f"{lo} to {hi:,}"


# -- shared options ------------------------------------------------------------------------------------------------
class Once(argparse.Action):
    """An option given at most once: a second one is refused in one line (``why``: what to do) where argparse
    would keep the last silently."""

    def __init__(self, *args, why: str = "give it once", **kwargs):
        super().__init__(*args, **kwargs)
        self.why = why

    def __call__(self, parser, namespace, values, option_string=None):
        given = f"_{self.dest}_given"
        if getattr(namespace, given, False):
            parser.error(
                f"{option_string}: given twice ({clip(getattr(namespace, self.dest), 40)}, "
                f"{clip(values, 40)}); {self.why}"
            )
        setattr(namespace, given, True)
        setattr(namespace, self.dest, values)


def compile_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--compile",
        default="auto",
        choices=INFERENCE_COMPILE_MODES,
        help="torch.compile the model: default compiles once for every mesh (symbolic sizes; about 25 s, "
        "65 s the first time on a machine), reduce-overhead (CUDA graphs) and max-autotune on padded "
        "graphs; aot exports the forward once per machine and model (about a minute), and later calls "
        "load it instead of compiling (default where the export fails); auto (default): on the CPU aot "
        "where this model's package is already built, or for at least 2,000 model steps in all (about "
        "23 designs of the small preset); elsewhere default for at least 2,000 steps where a compiler "
        "exists; else none",
    )


def batch_arg(p: argparse.ArgumentParser, what: str, default: int | None, default_text: str) -> None:
    p.add_argument(
        "--batch",
        type=count(1, MAX_BATCH),
        default=default,
        metavar="N",
        help=f"{what} together, {span(1, MAX_BATCH)} (default {default_text})",
    )


def verify_arg(p: argparse.ArgumentParser, what: str) -> None:
    p.add_argument(
        "--verify",
        nargs="?",
        const="all",
        metavar="auto",
        help=f"also run the built-in solver on every design and {what}; `--verify auto` (with "
        "--yield-mpa) runs it only on the designs whose call is undecided, and their final call is "
        "the solver's",
    )


def surrogate_args(p: argparse.ArgumentParser) -> None:
    g = p.add_mutually_exclusive_group()
    g.add_argument(
        "--surrogate",
        metavar="FILE.json",
        help="the response surface to report beside the model (made "
        "by `hcmt surrogate fit`; default: the model's own, shipped with it or RUN/surrogate.json)",
    )
    g.add_argument("--no-surrogate", action="store_true", help="no response surface: the mesh model alone")
    m = p.add_mutually_exclusive_group()
    m.add_argument(
        "--model-interval",
        metavar="FILE.json",
        help="the mesh model's own calibrated 95 %% interval "
        "(peak plate stress, max deflection, a band on the plate stress history; calibrated on held-out "
        "solver runs by benchmarks/trust/run.py; default: the model's own, shipped with it or "
        "RUN/interval.json); the calls trust it, and decide outside the training ranges only where it "
        "was calibrated",
    )
    m.add_argument(
        "--no-model-interval",
        action="store_true",
        help="no interval of the mesh model's own: the calls fall back to its answer and the response surface",
    )


def readout_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--readout",
        choices=READOUTS,
        default=DEFAULT_READOUT,
        help="raw (default): the mesh model's answer is its own outputs (stress field and positions) in "
        "every frame, whatever the response surface; contact: also report (as contact_*) the peak "
        "from the frames the ball touches the plate, the window ending at the response surface's "
        "bound of when the ball leaves, and a bending formula after it; element: also report (as "
        "element_*) the solver's element law on the predicted positions. The calls and trends use "
        "the chosen read-out; the JSON records it",
    )


def model_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "model", nargs="?", help="run folder made by `hcmt train`, or pretrained:NAME (`hcmt models` lists them)"
    )
    same_as(p, path="MODEL")


def same_as(p: argparse.ArgumentParser, **flags: str) -> None:
    """Name library parameters that this command calls otherwise (``path="MODEL"``: ``Run.load``'s ``path`` is
    ``hcmt predict``'s MODEL), so that their errors name the flag (:func:`hcmt.cli.flag_of`)."""
    p.param_flags = {**getattr(p, "param_flags", {}), **flags}


def check_run(name: str, text: str) -> None:
    """A run folder (``NAME``: the argument's name) that exists, or ``pretrained:NAME`` of a shipped model: one line
    before the model loads."""
    if text.startswith("pretrained:"):
        if text.split(":", 1)[1] not in available_pretrained():
            raise CommandError(f"{name} {clip(text)}: no such shipped model; `hcmt models` lists them")
        return
    path = Path(text)
    if not (path / "run.yaml").is_file():
        hint = f"; the shipped model is pretrained:{text}" if text in available_pretrained() else ""
        what = "no such folder" if not path.exists() else "not a run folder (no run.yaml)"
        raise CommandError(
            f"{name} {text}: {what}; expected a folder made by `hcmt train --out RUN`, or pretrained:NAME{hint}"
        )


def check_folder(name: str, text: str, what: str) -> None:
    if not Path(text).is_dir():
        raise CommandError(f"{name} {text}: no such folder; expected {what}")


def check_split(data: str, split: str) -> None:
    """A dataset folder's ``meta.json`` and ``<split>.h5`` exist (a cheap look before torch loads; the reader checks
    the contents). A folder with meta.json and no split file at all is left to the reader, which says whether a
    ``hcmt generate`` is writing it or was interrupted."""
    folder = Path(data)
    if not (folder / "meta.json").is_file():
        raise CommandError(
            f"--data {clip(data)}: no meta.json; expected a native dataset folder (meta.json + <split>.h5)"
        )
    have = sorted(f.stem for f in folder.glob("*.h5"))
    if have and split not in have:
        raise CommandError(
            f"--split {clip(split)}: {clip(data)} has no {clip(split)}.h5; splits there: {', '.join(have)}"
        )


def cores() -> int:
    """This machine's cores (:func:`hcmt.config.machine_cores`), looked up when a help text is written:
    ``scripts/gen_cli_docs.py`` replaces ``machine_cores`` here to write the help without this machine's count."""
    return machine_cores()
