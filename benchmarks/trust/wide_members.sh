#!/usr/bin/env bash
# Members of the shipped model fine-tuned on wider ranges: the data (thickness 0.5-1.25 mm, drop height 500-1250 mm,
# `generate --range`, seed 5252, 480 / 12 / 24 designs), then MEMBERS (default 1 2 3) fine-tuned from the shipped
# weights for 12,000 steps each (learning rate 2e-4 decaying to 1e-5, seed = the member's number), then the judge
# (benchmarks/surrogate/run.py, seeds 8101 in / 8102 outside, the shipped model's judge seeds) on the first member
# and the ensemble study (benchmarks/trust/ensemble.py) on all of them beside the shipped model.
#
#     bash benchmarks/trust/wide_members.sh      # start, or continue where it stopped (each step resumes)
#
# Folders under $HCMT_WORK (default benchmarks/work; docs/RESULTS.md, "Folders"); HCMT: the hcmt command to use.
set -euo pipefail
HCMT=${HCMT:-hcmt}
PY=${PY:-python}
W=${HCMT_WORK:-benchmarks/work}
DATA=$W/data/ipwide
export OMP_NUM_THREADS=1
"$HCMT" generate impact-plate "$DATA" --preset small --train 480 --valid 12 --test 24 --seed 5252 --frames 90 \
    --edge-fraction 0.35 --peak-stress --range thickness=0.5:1.25 --range drop_height=500:1250 --workers 1 --no-progress
RUNS=()
for m in ${MEMBERS:-1 2 3}; do
    RUN=$W/runs/wide_m$m
    RUNS+=("$RUN")
    if [ -f "$RUN/run.yaml" ]; then
        "$HCMT" train --resume --out "$RUN" --threads 1 --no-progress
    else
        "$HCMT" train --init pretrained:impact_plate_small --data "$DATA" --out "$RUN" --steps 12000 --seed "$m" \
            --threads 1 --no-progress --set train.lr=0.0002 --set train.lr_final=0.00001 \
            --set train.valid_every=4000 --set train.keep_every=4000 --set train.checkpoint_every=500
    fi
done
"$PY" benchmarks/surrogate/run.py --data "$DATA" --work "$W/judge_wide_m1" --model "${RUNS[0]}" --seed-in 8101 \
    --seed-out 8102 --threads 1 --json judge_wide_m1.json
"$PY" benchmarks/trust/ensemble.py --members "${RUNS[@]}" --also pretrained:impact_plate_small \
    --work "$W/trust_ensemble" --calibration-seed 5301 --eval-seeds 5302 --inside 40 --per-cell 20 \
    --cells thickness+ drop_height+ --distances 0.2
