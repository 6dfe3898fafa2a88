"""One-off: rewrite the absolute folders that the committed result files recorded on the machines that ran them as
the portable names the benchmarks record now (benchmarks/common.py, ``portable``): the work folders
(``/work/persist``, ``/root/persist``, ``/work``) as ``$HCMT_WORK``, the checkout (``/work/main``) as ``.``.

    python scripts/portable_results.py [FILE ...]   # default: benchmarks/results/*.json, src/hcmt/pretrained/*.json

The files are edited as text, so every number keeps its exact spelling; a file is checked to hold the same JSON
apart from the rewritten strings."""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
#: (pattern, replacement), applied in order; the checkout before the work folders that hold it
RULES = (
    (re.compile(r"(?<![\w.-])/work/main(?=[/\"\s]|$)/?"), lambda m: "" if m.group(0).endswith("/") else "."),
    (re.compile(r"(?<![\w.-])/(?:work|root)/persist(?=[/\"\s}]|$)"), lambda m: "$HCMT_WORK"),
    (re.compile(r"(?<![\w.-])/work(?=/)"), lambda m: "$HCMT_WORK"),
)


def rewrite(text: str) -> str:
    for pattern, repl in RULES:
        text = pattern.sub(repl, text)
    return text


def numbers(obj) -> list:
    """Every non-string leaf of a JSON value, in order (what the rewrite must leave alone)."""
    if isinstance(obj, dict):
        return [x for v in obj.values() for x in numbers(v)]
    if isinstance(obj, list):
        return [x for v in obj for x in numbers(v)]
    return [] if isinstance(obj, str) else [obj]


def main(paths: list[str]) -> None:
    files = [Path(p) for p in paths] or [
        *sorted((ROOT / "benchmarks" / "results").glob("*.json")),
        *sorted((ROOT / "src" / "hcmt" / "pretrained").glob("*.json")),
    ]
    for path in files:
        old = path.read_text()
        new = rewrite(old)
        if new == old:
            continue
        assert numbers(json.loads(old)) == numbers(json.loads(new)), path
        path.write_text(new)
        print(f"rewrote {path.relative_to(ROOT)}")


if __name__ == "__main__":
    main(sys.argv[1:])
