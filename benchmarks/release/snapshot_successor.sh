#!/usr/bin/env bash
# Copy the successor run's latest checkpoint into benchmarks/release/successor/ (README.md there says why), to be
# committed at the end of a working session; train_successor.sh restores it into an empty run folder.
#
#     RUN=/work/persist/runs/ship480 bash benchmarks/release/snapshot_successor.sh
set -euo pipefail
RUN=${RUN:-/work/persist/runs/ship480}
SNAP="$(cd "$(dirname "$0")" && pwd)/successor"
for f in checkpoint.pt run.yaml data.json log.jsonl; do
    [ -f "$RUN/$f" ] || { echo "snapshot_successor: $RUN/$f: missing (a run folder made by train_successor.sh?)" >&2; exit 2; }
done
# checkpoint.pt is replaced atomically by the trainer: a copy taken between two saves is whole
for f in checkpoint.pt run.yaml data.json log.jsonl; do
    cp "$RUN/$f" "$SNAP/.$f.tmp" && mv "$SNAP/.$f.tmp" "$SNAP/$f"
done
echo "snapshot of $RUN at $(tail -n 1 "$SNAP/log.jsonl" | cut -c1-40) in $SNAP"
