#!/usr/bin/env bash
# The shipped model pretrained:impact_plate_small (shipped 2026-12-04; it replaced a model of 36,000
# steps on 120 designs): HCMT with the shipped recipe (config impact_plate_shipped, which holds every setting below)
# on the 480 training designs of the scaling study's data, 400,000 steps (11x its predecessor's at the same graph
# size), one CPU thread, validated every 10,000 steps on 6 designs, step_<N>.pt kept every 20,000 steps so the
# checkpoint can be chosen on peak, deflection and ghost errors; finish_successor.sh then averages, chooses, ships and
# judges it (docs/MODELS.md).
#
#     bash benchmarks/release/train_successor.sh          # start, or continue where it stopped (both resume)
#
# DATA and RUN default to folders of $HCMT_WORK (default benchmarks/work, relative to where it runs, which git
# ignores; docs/RESULTS.md, "Folders"); run it from a frozen worktree with its own venv
# (HCMT=path/to/venv/bin/hcmt), in the background: `setsid nohup bash ... > LOG 2>&1 < /dev/null &`.
set -euo pipefail
HCMT=${HCMT:-hcmt}
W=${HCMT_WORK:-benchmarks/work}  # the work folder outside git (docs/RESULTS.md, "Folders")
DATA=${DATA:-$W/data/ip480}
RUN=${RUN:-$W/runs/ship480}
export OMP_NUM_THREADS=1

# the data: the scaling study's command (benchmarks/scaling/README.md); an interrupted generation resumes in place
if [ ! -f "$DATA/test_thicker_higher.h5" ]; then
    "$HCMT" generate impact-plate "$DATA" --preset small --train 480 --valid 12 --test 24 --variants \
        --variant-count 8 --seed 3035 --frames 90 --edge-fraction 0.35 --peak-stress --workers 1 --no-progress
fi

if [ -f "$RUN/run.yaml" ]; then
    exec "$HCMT" train --resume --out "$RUN" --threads 1 --no-progress
fi
# (it ran with these settings spelled out as --steps/--set; the config now holds them: tests/training/test_config.py)
exec "$HCMT" train --config impact_plate_shipped --data "$DATA" --model hcmt --out "$RUN" --threads 1 --no-progress
