#!/usr/bin/env bash
# IK benchmarks: our solvers vs a pinocchio DLS with random restarts vs ikpy, 10 000 reachable
# targets per chain, 5 ms per target, seed 0. Writes benchmarks/results/ik_*.json.
# Usage: benchmarks/ik/run.sh [N]   (from anywhere; PREHENSILE=path/to/prehensile to override)
set -euo pipefail
cd "$(dirname "$0")/../.."
P=${PREHENSILE:-.venv/bin/prehensile}
N=${1:-10000}
OUT=benchmarks/results
export NUMBA_NUM_THREADS=1
COMMON=(--n "$N" --seed 0 --budget 0.005 --peers pinocchio,ikpy --ikpy-targets 200)

"$P" bench ik --robot panda --base panda_link0 --tip panda_hand_tcp --method dls,pinv,transpose,fabrik \
    "${COMMON[@]}" --json "$OUT/ik_panda.json"
"$P" bench ik --robot armar3 --base Platform --tip TCP_R --method dls,pinv,transpose,fabrik \
    "${COMMON[@]}" --json "$OUT/ik_armar3.json"
"$P" bench ik --robot nao --base torso --tip l_arm_tip --method dls,pinv,transpose,fabrik,analytic \
    "${COMMON[@]}" --json "$OUT/ik_nao_left_arm.json"
"$P" bench ik --robot nao --base torso --tip l_gripper --method dls,pinv,transpose,fabrik,analytic \
    "${COMMON[@]}" --json "$OUT/ik_nao_left_arm_wrist.json"
