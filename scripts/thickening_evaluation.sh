#!/usr/bin/env bash
# The final evaluation of the thickening-control study (issue 21), after scripts/thickening_training.sh:
# every trained run on the 16 test schedules in the reference physics (the paper's 0.4% displacement
# bound), against the constant fields and the tuned controllers with 4 realisations per state; then SAC's
# sampled actions, the policy SAC optimises (docs/thickening_control.md#status). Both commands reuse
# every episode already stored in their folders (rerun to resume after an interruption).
#
#     scripts/thickening_evaluation.sh [WORKERS]   # default 2; writes results/thickening_control/v2/evaluation_final{,_sac_sampled}
#                                                  # and the summary table evaluation_final/summary.md
#
# Each run's episodes are stored in DIR/runs/ when its 16 are done and reused while the model's contents
# (SHA-256), the states and the play arguments are the same; a run stopped part way keeps its finished
# episodes in DIR/runs/<run>.partial.json and resumes at the next one. So the evaluation runs in chunks
# across sessions: stop it (pkill -TERM -f agents.evaluate), commit both folders (runs/ included), rerun. Uses the project's interpreter
# (.venv/bin/python, or $PYTHON). On the 2-core machine: 15 runs x 16 episodes plus SAC's 5 x 16 sampled,
# ~1.3 min each (48 steps at ~0.6 steps/s), so 3-4 hours on two workers.
set -euo pipefail
cd "$(dirname "$0")/.."
WORKERS=${1:-2}
PY=${PYTHON:-.venv/bin/python}
V1=results/thickening_control/v1
V2=results/thickening_control/v2
REFERENCE='{"simulation_overrides": {}}'
# agents.evaluate plays the finished runs it finds; the final table needs all of them (ALLOW_PARTIAL=1
# evaluates what is there, e.g. for an interim table).
missing=()
for row in ppo sac ppo_stress_only_history; do
    for seed in 0 1 2 3 4; do
        [ -e "$V2/rl/$row/seed$seed/result.json" ] || missing+=("$row/seed$seed")
    done
done
if [ ${#missing[@]} -gt 0 ] && [ "${ALLOW_PARTIAL:-0}" != 1 ]; then
    echo "thickening_evaluation.sh: runs not finished: ${missing[*]} (run scripts/thickening_training.sh," \
        "or set ALLOW_PARTIAL=1)" >&2
    exit 2
fi
"$PY" -m agents.evaluate "$V2/rl/ppo" "$V2/rl/sac" "$V2/rl/ppo_stress_only_history" \
    --play-kwargs "$REFERENCE" --baseline "$V1/open_loop" \
    --controllers "$V2/feedforward" "$V2/pi" "$V2/pi_stress_only" "$V2/pulse" \
    --repeats 4 --policy-repeats 1 --validation-baseline "$V1/open_loop_validation" \
    --workers "$WORKERS" --out "$V2/evaluation_final"
"$PY" -m agents.evaluate "$V2/rl/sac" --actions sampled --play-kwargs "$REFERENCE" \
    --baseline "$V1/open_loop" --controllers "$V2/pulse" \
    --repeats 4 --policy-repeats 1 --validation-baseline "$V1/open_loop_validation" \
    --workers "$WORKERS" --out "$V2/evaluation_final_sac_sampled"
# The README's summary table (agents.evaluate's numbers, selected): every row once, SAC's sampled policy
# with them.
"$PY" scripts/thickening_summary.py "$V2/evaluation_final" "$V2/evaluation_final_sac_sampled" \
    > "$V2/evaluation_final/summary.md"
