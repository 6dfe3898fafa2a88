#!/usr/bin/env bash
# The shipped model's successor (issue 35 item 4): HCMT with the shipped recipe (config impact_plate_shipped) on the
# 480 training designs of the scaling study's data, 400,000 steps (11x the shipped model's 36,000 at the same graph
# size), one CPU thread, validated every 10,000 steps on 6 designs, step_<N>.pt kept every 20,000 steps so the
# checkpoint can be chosen on peak, deflection and ghost errors (benchmarks/scaling/long_run.py, ship_model.py).
#
#     bash benchmarks/release/train_successor.sh          # start, or continue where it stopped (both resume)
#
# DATA and RUN (defaults below) live outside the work tree; run it from a frozen worktree with its own venv
# (HCMT=path/to/venv/bin/hcmt), in the background: `setsid nohup bash ... > LOG 2>&1 < /dev/null &`.
set -euo pipefail
HCMT=${HCMT:-hcmt}
DATA=${DATA:-/work/persist/data/ip480}
RUN=${RUN:-/work/persist/runs/ship480}
export OMP_NUM_THREADS=1

# the data: the scaling study's command (benchmarks/scaling/README.md); an interrupted generation resumes in place
if [ ! -f "$DATA/test_thicker_higher.h5" ]; then
    "$HCMT" generate impact-plate "$DATA" --preset small --train 480 --valid 12 --test 24 --variants \
        --variant-count 8 --seed 3035 --frames 90 --edge-fraction 0.35 --peak-stress --workers 1 --no-progress
fi

# a snapshot of the run kept in the repository (benchmarks/release/successor/README.md): the machine's disk did not
# survive between sessions once, so the run's latest checkpoint travels with the code; restored where RUN has none
SNAP="$(cd "$(dirname "$0")" && pwd)/successor"
if [ ! -f "$RUN/checkpoint.pt" ] && [ -f "$SNAP/checkpoint.pt" ]; then
    mkdir -p "$RUN"
    cp "$SNAP/checkpoint.pt" "$SNAP/run.yaml" "$SNAP/data.json" "$SNAP/log.jsonl" "$RUN/"
    echo "restored $RUN from $SNAP (step $(tail -1 "$SNAP/log.jsonl"))"
fi

if [ -f "$RUN/run.yaml" ]; then
    exec "$HCMT" train --resume --out "$RUN" --threads 1 --no-progress
fi
exec "$HCMT" train --config impact_plate_shipped --data "$DATA" --model hcmt --out "$RUN" --steps 400000 \
    --set train.valid_every=10000 --set train.keep_every=20000 --set train.checkpoint_every=1000 \
    --set train.log_every=1000 --set data.in_memory=true --threads 1 --no-progress
