#!/usr/bin/env bash
# The trained rows of the thickening-control study (issue 21), in order: PPO and SAC on
# ThickeningControl-v2, then PPO with 4 frames of history on the stress-only id; 5 seeds each, trained with
# the displacement bound doubled (docs/thickening_control.md#coarse-training). Every stage resumes from
# its folders' checkpoints, so the script is rerun as is after an interruption (a finished seed returns at
# once). Stop it with `pkill -TERM -f agents.train` (the run saves a checkpoint at the step it reached and
# the script ends) and commit the result folders (small files).
#
#     scripts/thickening_training.sh [OUT]   # default OUT: results/thickening_control/v2/rl
#
# Seeds 0-2 of every row run before seeds 3-4. Uses the project's interpreter (.venv/bin/python, or $PYTHON). On the 2-core machine one seed of 10^4
# steps takes about 1.5 h with both cores (two environments per run).
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-results/thickening_control/v2/rl}
PY=${PYTHON:-.venv/bin/python}
COARSE='"simulation_overrides": {"max_displacement": 0.008}'
# Seeds 0-2 of all three first, then 3-4 of all three: an interrupted study has every row early.
for SEEDS in 0-2 3-4; do
    train() {
        "$PY" -m agents.train --seeds "$SEEDS" --workers 1 --no-progress "$@"
    }
    train --env dipenv/ThickeningControl-v2 --algo ppo --env-kwargs "{$COARSE}" --out "$OUT/ppo"
    train --env dipenv/ThickeningControl-v2 --algo sac --env-kwargs "{$COARSE}" --out "$OUT/sac"
    train --env dipenv/ThickeningControlStressOnly-v2 --algo ppo \
        --env-kwargs "{\"history_length\": 4, $COARSE}" --out "$OUT/ppo_stress_only_history"
done
