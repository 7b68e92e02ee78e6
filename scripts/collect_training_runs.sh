#!/bin/bash
# Copy the small files of a PPO study and its evaluation into a results folder (run from the repository
# root; OUT defaults to results/ppo/FieldMagnitude-v0):
#   scripts/collect_training_runs.sh runs/ppo_d3 runs/evaluation_d3 [OUT]
# Per seed: config, command, result, final model and its normalisation, the validation log, the
# TensorBoard logs (learning curves) and the Monitor files; checkpoints and the evaluation's per-run
# traces stay out (megabytes; rerun the commands in docs/agents.md to get them).
set -euo pipefail
study=$1
evaluation=$2
here=${3:-"$(dirname "$0")/../results/ppo/FieldMagnitude-v0"}
for run in "$study"/seed*/; do
    seed=$(basename "$run")
    [ -f "$run/model.zip" ] || continue
    mkdir -p "$here/$seed/eval"
    cp "$run"/{config.yml,command.txt,result.json,model.zip,vecnormalize.pkl} "$here/$seed/"
    cp "$run/eval/evaluations.npz" "$here/$seed/eval/"
    rm -rf "$here/$seed/tb" "$here/$seed/monitor"
    cp -r "$run/tb" "$run/monitor" "$here/$seed/"
done
mkdir -p "$here/evaluation"
cp "$evaluation"/{command.txt,table.md,verdict.md,results.json,pareto.png,traces.png,learning.png} "$here/evaluation/"
