#!/usr/bin/env bash
# Issue 44: the bulk map of the field's direction (N = 500, 30 strains, averaged over 10-30).
#
# Runs from a worktree pinned at the commit below, so that the sweep's stale-source check keeps the
# finished points across sessions while sim/ changes on main (as the box-size study did):
#     git worktree add /work/map_wt ddb5d18
#     bash scripts/direction_map.sh /work/map_wt /work/runs/direction_map [SEEDS] [PHIS]
# Every sweep resumes: rerun the same command to continue. Order: seed by seed, phi 0.45 first, so the
# map fills in the order that matters (one seed of every direction at phi 0.45 before anything else).
# Directions: x (flow), y (gradient), z (vorticity), the extensional (x+y) and compressional (x-y)
# diagonals of the shear plane, and y-z at 45 degrees.
set -euo pipefail
tree=${1:?pinned worktree}
out=${2:?output root}
seeds=${3:-"1 2 3"}
phis=${4:-"0.45 0.30"}
python=${PYTHON:-/work/main/.venv/bin/python}
declare -A dirs=(
  [y]="0,1,0" [z]="0,0,1" [x]="1,0,0" [ext]="1,1,0" [comp]="1,-1,0" [yz]="0,1,1"
)
order="y z x ext comp yz"
cd "$tree"
for seed in $seeds; do
  for phi in $phis; do
    for d in $order; do
      "$python" -m sim sweep --phi "$phi" --n-particles 500 --mason 0.2,0.5,1,2,5,10 \
        --field-direction "${dirs[$d]}" --seeds "$seed-$seed" --strain 30 --transient 10 \
        --workers 1 --quiet --out "$out/phi${phi}_$d" || echo "sweep phi=$phi dir=$d seed=$seed failed: $?"
    done
  done
done
