#!/usr/bin/env bash
# The measured steps that ship the successor once its training (train_successor.sh) has finished, in order,
# unattended: average the last kept steps, choose on the validation split, the long run's test rows, ship the chosen
# checkpoint as pretrained:impact_plate_small, judge it against the model goals on seeds no study used, the design
# check beside its response surface on the card's designs, the transfer again, the report. Each step leaves a mark in
# WORK when it finishes and is skipped on a rerun, so an interrupted finish resumes (the judge and the transfer also
# cache their own groups). The docs' rewriting stays a person's job.
#
#     bash benchmarks/release/finish_successor.sh        # from the repository root's checkout that is to ship it
#
# RUN, DATA (train_successor.sh's), STACK3 and PEN (the panel families of benchmarks/transfer/report.py's commands)
# and WORK default to folders of $HCMT_WORK (default benchmarks/work, which git ignores; docs/RESULTS.md, "Folders");
# PY is the Python with this checkout's hcmt (e.g. PYTHONPATH=src PY=.venv/bin/python).
set -euo pipefail
cd "$(dirname "$0")/../.."  # the checkout: ship_model.py writes src/hcmt/pretrained/ and benchmarks/results/ here
PY=${PY:-python}
W=${HCMT_WORK:-benchmarks/work}  # the work folder outside git (docs/RESULTS.md, "Folders")
RUN=${RUN:-$W/runs/ship480}
DATA=${DATA:-$W/data/ip480}
STACK3=${STACK3:-$W/data/fam_stack3}
PEN=${PEN:-$W/data/fam_pen}
WORK=${WORK:-$W/finish}
LAST=${LAST:-"360000 380000 400000"}  # the kept steps averaged (the schedule's last three)
export OMP_NUM_THREADS=1

die() { echo "finish_successor: $*" >&2; exit 2; }
[ -f "$RUN/train_stats.json" ] || die "$RUN/train_stats.json: missing: the run has not finished its steps (train_successor.sh)"
for d in "$DATA" "$STACK3" "$PEN"; do
    [ -f "$d/meta.json" ] || die "$d/meta.json: missing: generate it first (train_successor.sh; benchmarks/transfer/report.py's commands)"
done
mkdir -p "$WORK"
step() {  # step NAME COMMAND...: run COMMAND unless NAME is marked done; marked only when it succeeded
    local name=$1; shift
    if [ -f "$WORK/$name.done" ]; then echo "== $name: done before, skipped"; return 0; fi
    echo "== $name: $*"
    if "$@" 2>&1 | tee "$WORK/$name.log"; then
        touch "$WORK/$name.done"
    else
        echo "finish_successor: step $name failed (its log: $WORK/$name.log); rerun to resume" >&2
        return 1
    fi
}

step average "$PY" benchmarks/release/average_checkpoints.py "$RUN" --steps $LAST
step choose "$PY" benchmarks/release/choose_checkpoint.py "$RUN" --data "$DATA" --json successor_choice.json \
    --cache "$WORK/choose_cache"  # kept steps judged before (e.g. while the run trained) are read, not rolled out
CHOSEN=$("$PY" -c "import json; print(json.load(open('benchmarks/results/successor_choice.json'))['chosen'])")
echo "== chosen on the validation split: $CHOSEN"
for s in $LAST; do
    step "long_run_$s" "$PY" benchmarks/scaling/long_run.py "$RUN" --data "$DATA" --checkpoint "step_$s" --label "second run"
done
GENERATE=$(sed -n '/generate impact-plate/{N;p}' benchmarks/release/train_successor.sh | tr '\\\n' '  ' | tr -s ' ' \
    | sed -e 's/^.*generate impact-plate/hcmt generate impact-plate/' -e "s|\"\$DATA\"|$DATA|" -e 's/ *$//')
step ship "$PY" benchmarks/release/ship_model.py "$RUN" --data "$DATA" --name impact_plate_small --checkpoint "$CHOSEN" \
    --command "bash benchmarks/release/train_successor.sh" --data-command "$GENERATE"
# the judge and the design check on one core, the transfer on the other (independent; each one thread)
(step judge "$PY" benchmarks/surrogate/run.py --data "$DATA" --work "$WORK/judge" --model pretrained:impact_plate_small \
    --seed-in 8101 --seed-out 8102 --json model_judge.json \
    && step surrogate "$PY" benchmarks/surrogate/run.py --data "$DATA" --work "$WORK/surrogate" \
        --model pretrained:impact_plate_small) > "$WORK/judge_and_surrogate.log" 2>&1 &
side=$!  # surrogate: the design check beside its response surface on the card's designs (docs/MODELS.md's table)
step transfer "$PY" benchmarks/transfer/run.py --work "$WORK/transfer" --train-data "$DATA" --new "stack3=$STACK3" \
    --new "pen=$PEN" --base new=pretrained:impact_plate_small --ft-lr 1e-4 --seeds 0 1 --shots 5 20 --eval 8 \
    --json transfer_shipped.json
wait "$side" || die "the judge or the design check failed: $WORK/judge_and_surrogate.log; rerun to resume"
step report "$PY" benchmarks/report.py
echo "finish_successor: every measured step done (marks in $WORK); now rewrite docs/MODELS.md's card, the low-confidence"
echo "note, the region table and the README's division of labour from these results"
