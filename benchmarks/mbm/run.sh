#!/usr/bin/env bash
# MotionBenchMaker Panda problems (4 scenarios x 100): our RRT-Connect vs OMPL's RRT-Connect with
# our sphere checker, 5 s search budget per problem and planner, seed 0, one numba thread.
# Both plan on MBM's balls as they are; ours certifies every path on the exact meshes and, when
# one fails, plans again with the balls of the links that collided padded to cover the meshes.
# Writes benchmarks/results/mbm_panda.json and prints the table.
# Usage: benchmarks/mbm/run.sh [LIMIT] [extra options, e.g. --pad]   (LIMIT problems per scenario,
# default all; needs ../shared)
set -euo pipefail
cd "$(dirname "$0")/../.."
P=${PREHENSILE:-.venv/bin/prehensile}
MBM=../shared/bench/mbm/panda
export NUMBA_NUM_THREADS=1
"$P" bench mbm "$MBM/problems.tar.bz2" --robot "$MBM/panda.urdf" --srdf "$MBM/panda.srdf" \
    --spheres "$MBM/panda_spherized.urdf" --compare-ompl --budget 5 --seed 0 --limit "${1:-0}" \
    --json benchmarks/results/mbm_panda.json "${@:2}"
