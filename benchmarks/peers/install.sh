#!/usr/bin/env bash
# Creates the peers' venvs under ${PEERS:-$HCMT_WORK/peers} (HCMT_WORK: default benchmarks/work; skipped when
# present). See README.md.
set -euo pipefail
PEERS=${PEERS:-${HCMT_WORK:-benchmarks/work}/peers}
PY=${PYTHON:-python3}
WHICH=${1:-all}   # tf | physicsnemo | all
mkdir -p "$PEERS"
if [ "$WHICH" != physicsnemo ] && { [ ! -x "$PEERS/tf/bin/python" ] || ! "$PEERS/tf/bin/python" -c "import sonnet, tensorflow" 2>/dev/null; }; then
  "$PY" -m venv "$PEERS/tf"
  "$PEERS/tf/bin/pip" install -q tensorflow-cpu "dm-sonnet==2.0.2" tf-keras
fi
P="$PEERS/physicsnemo/bin/pip"
if [ "$WHICH" != tf ] && { [ ! -x "$PEERS/physicsnemo/bin/python" ] || ! "$PEERS/physicsnemo/bin/python" -c "import torch_geometric, importlib.metadata as m; m.version('nvidia-physicsnemo')" 2>/dev/null; }; then
  "$PY" -m venv "$PEERS/physicsnemo"
  "$P" install -q torch==2.13.0              # first, or pip pulls the CUDA build
  "$P" install -q --no-deps "nvidia-physicsnemo==2.2.2"
  "$P" install -q warp-lang jaxtyping torch_geometric packaging s3fs einops numpy
  "$P" install -q --no-deps tensordict pyvers cloudpickle timm nvtx omegaconf pyyaml treelib termcolor
  "$P" install -q setuptools wheel
  # builds from source (many minutes on a loaded core); SCATTER=0 skips it: the worker then stands in
  # torch_geometric.utils.scatter for torch_scatter.scatter (see worker_physicsnemo.py)
  if [ "${SCATTER:-1}" = 1 ]; then MAX_JOBS=2 "$P" install -q --no-build-isolation "torch-scatter==2.1.2"; fi
fi
echo "peers installed under $PEERS"
