"""The design check's light pieces: what the command's parsers and its first checks need before torch, scikit-learn
or the solver load (a refused ``--designs`` file or ``--vary`` in a fraction of a second): the surrogate's answers
and restarts, the read-outs' names, design names, the table of a designs CSV and a sweep's range."""
from __future__ import annotations

import csv
import math
from pathlib import Path

from hcmt.config import MAX_DESIGNS
from hcmt.errors import InputError, clip
from hcmt.sim.params import DESIGN_KEYS

#: the scalar answers a surrogate predicts (keys of a design's summary)
QUANTITIES = ("peak_plate_stress_mpa", "peak_ball_stress_mpa", "max_deflection_mm", "peak_plate_t95_ms",
              "contact_end_ms")
RESTARTS = 3  # optimizer restarts of the marginal likelihood (the comparison used 3)
#: the design check's read-outs (:mod:`hcmt.design.readout`): ``raw``, the model's own outputs alone (the default);
#: the others add a derived read-out under their own names
READOUTS = ("raw", "contact", "element")
DEFAULT_READOUT = "raw"
#: designs per model call, the same default for ``predict``, ``sweep`` and the library: on one quiet CPU thread with
#: the ahead-of-time compiled forward, one design at a time was measured fastest against the solver interleaved
#: (2.22x and 2.46x the solver, against 2.09x / 2.30x in pairs, 1.72x / 1.97x in fours, 1.66x / 2.05x in eights, two
#: runs in opposite orders: benchmarks/results/design_speed_cpu.json, design_speed_cpu_reversed.json); on a GPU a
#: larger batch may pay
DESIGN_BATCH = 1


def check_name(name, where: str) -> str:
    """A design name that is safe as a folder name under ``--out`` (pictures are written to ``OUT/NAME/``): a
    string, not empty, no path separator, not ``.`` or ``..``, no control character, at most 200 characters; else
    one line naming ``where`` (the name itself shortened to 60 characters)."""
    bad = None
    if not isinstance(name, str):
        bad = f"is a {type(name).__name__}, not text"
    elif not name:
        bad = "is empty"
    elif any(c in name for c in "/\\") or name in (".", ".."):
        bad = "would be a path outside its own folder (no '/', '\\', '.' or '..')"
    elif any(ord(c) < 32 or ord(c) == 127 for c in name):
        bad = "holds a control character"
    elif len(name) > 200:
        bad = f"is {len(name):,} characters long; expected at most 200"
    if bad:
        raise InputError(f"{where}: the design name {clip(name)!r} {bad}; names become folder names under --out")
    return name


def read_table(path: Path) -> tuple[int, list[str], list[tuple[int, list[str]]]]:
    """(header line, header, numbered body rows) of a designs CSV: a UTF-8 text file (a BOM and CRLF line ends
    are fine; blank lines skipped) whose header names known parameters (or ``name``), each once, safe names
    (:func:`check_name`) and at most :data:`hcmt.config.MAX_DESIGNS` rows; anything else one line naming the file,
    line and column."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such designs file" + (" (a folder)" if path.is_dir() else ""))
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not a UTF-8 text file ({exc.reason} at byte {exc.start})") from None
    try:
        rows = [(n, r) for n, r in enumerate(csv.reader(text.splitlines()), start=1) if any(c.strip() for c in r)]
    except csv.Error as exc:
        raise InputError(f"{path}: not a readable CSV file ({clip(exc, 120)})") from None
    if not rows:
        raise InputError(f"{path}: no designs (expected a header line of parameter names and one row per design)")
    (head_line, head), body = rows[0], rows[1:]
    header = [h.strip().replace("-", "_") for h in head]
    seen: dict[str, int] = {}
    for col, h in enumerate(header, start=1):
        if h != "name" and h not in DESIGN_KEYS:
            raise InputError(f"{path} line {head_line}, column {col}: unknown column {clip(h)!r} in the header; "
                             "expected `name` or a design parameter (`hcmt models` lists them)")
        if h in seen:
            raise InputError(f"{path} line {head_line}, column {col}: the column {h!r} appears twice (columns "
                             f"{seen[h]} and {col}) in the header; give each parameter once")
        seen[h] = col
    if "name" in header:  # names checked here, before any model loads (read_designs_csv: distinct ones)
        col = header.index("name")
        for n, row in body:
            if col < len(row):
                check_name(row[col].strip(), f"{path} line {n}, column {col + 1} (name)")
    if len(body) > MAX_DESIGNS:
        raise InputError(f"{path}: {len(body):,} designs; expected at most {MAX_DESIGNS:,} in one file")
    return head_line, header, body


def parse_vary(text: str) -> tuple[str, float, float, int]:
    """``PARAM=LO:HI:N`` -> (param, lo, hi, n); one line naming what is wrong otherwise."""
    key, sep, spec = text.partition("=")
    key = key.strip().replace("-", "_")
    parts = spec.split(":")
    shown = clip(text)
    if not sep or len(parts) != 3:
        raise InputError(f"{shown!r}: expected PARAM=LO:HI:N, e.g. thickness=0.5:1.0:6", param="vary")
    if key not in DESIGN_KEYS:
        raise InputError(f"{shown!r}: unknown parameter {clip(key)!r}; expected a design parameter (`hcmt models` "
                         "lists them)", param="vary")
    try:
        lo, hi = float(parts[0]), float(parts[1])
    except ValueError:
        raise InputError(f"{shown!r}: LO and HI must be numbers", param="vary") from None
    if not (math.isfinite(lo) and math.isfinite(hi)) or not lo < hi:
        raise InputError(f"{shown!r}: expected finite LO < HI, got {clip(parts[0])} and {clip(parts[1])}",
                         param="vary")
    try:
        n = int(parts[2])
    except ValueError:
        raise InputError(f"{shown!r}: N must be a whole number, got {clip(parts[2])!r}", param="vary") from None
    if not 2 <= n <= 256:
        raise InputError(f"{shown!r}: N must be between 2 and 256, got {n}", param="vary")
    return key, lo, hi, n
