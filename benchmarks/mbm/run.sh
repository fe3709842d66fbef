#!/usr/bin/env bash
# MotionBenchMaker Panda problems (4 scenarios x 100): our RRT-Connect vs OMPL's RRT-Connect with
# our sphere checker, 5 s search budget per problem and planner, seed 0, one numba thread.
# First with MBM's spheres padded to cover the meshes (the default), then with them as they are.
# Writes benchmarks/results/mbm_panda.json and mbm_panda_unpadded.json and prints the tables.
# Usage: benchmarks/mbm/run.sh [LIMIT]   (LIMIT problems per scenario, default all; needs ../shared)
set -euo pipefail
cd "$(dirname "$0")/../.."
P=${PREHENSILE:-.venv/bin/prehensile}
MBM=../shared/bench/mbm/panda
export NUMBA_NUM_THREADS=1
COMMON=(--robot "$MBM/panda.urdf" --srdf "$MBM/panda.srdf" --spheres "$MBM/panda_spherized.urdf"
        --compare-ompl --budget 5 --seed 0 --limit "${1:-0}")
"$P" bench mbm "$MBM/problems.tar.bz2" "${COMMON[@]}" --json benchmarks/results/mbm_panda.json
"$P" bench mbm "$MBM/problems.tar.bz2" "${COMMON[@]}" --no-pad --json benchmarks/results/mbm_panda_unpadded.json
