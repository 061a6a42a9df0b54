#!/usr/bin/env bash
# The estimation tick's time by stage, on paper-size networks with random
# weights (Table I's SCNN, Table II's MLP): the trained models are not in
# yet, and a network's time does not depend on its weights.
#   tools/estimation_bench.sh        (needs .venv: make venv)
set -euo pipefail
cd "$(dirname "$0")/.."
out=target/bench-models
.venv/bin/python tools/make_test_models.py --paper-size "$out"
KFLEX_BENCH_MODELS="$PWD/$out" cargo bench -p kflex-estimate --features onnx,index --bench estimation -- "$@"
