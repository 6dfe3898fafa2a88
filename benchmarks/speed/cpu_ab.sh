#!/bin/bash
# CPU regression check (the CPU path must not get slower while the GPU path is tuned): the eager paper-size train
# step and inference of two checkouts, alternately, twice, each on one thread under the same load.
#     bash benchmarks/speed/cpu_ab.sh OLD_CHECKOUT NEW_CHECKOUT   (e.g. a `git worktree add --detach ../old REV`)
# writes benchmarks/results/cpu_ab_{old,new}_{1,2}.json (micro/bench_models.py's format); speed/report.py compares them.
# Each checkout runs its own bench_models.py: benchmarks/micro/ since the layout by kind, benchmarks/ before.
set -e
old=$(realpath "$1"); new=$(realpath "$2"); results=$(realpath "$(dirname "$0")/..")/results
python=${PYTHON:-python}
for i in 1 2; do
  for side in old new; do
    tree=$old; [ $side = new ] && tree=$new
    bench=benchmarks/micro/bench_models.py; [ -f "$tree/$bench" ] || bench=benchmarks/bench_models.py
    (cd "$tree" && OMP_NUM_THREADS=1 PYTHONPATH="$tree/src" $python $bench --device cpu \
        --threads 1 --steps 5 --json "$results/cpu_ab_${side}_$i.json")
  done
done
