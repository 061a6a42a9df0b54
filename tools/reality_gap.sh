#!/usr/bin/env bash
# The reality gap between the simulated robot's frames (as-built instrument
# and camera) and the nominal model IBJAE's database is rendered from,
# measured with the plainest retrieval: the nearest raw 48×48 silhouette.
# Usage: tools/reality_gap.sh [FRAMES [SCALE]]   (defaults: 500 frames, tolerances ×1)
set -euo pipefail
cd "$(dirname "$0")/.."
exec cargo run --release -q -p kflex-estimate --example reality_gap -- "$@"
