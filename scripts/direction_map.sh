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
# The diagonals are given already normalised, as the float that SimulationConfig's normalisation keeps
# (h = 0.7071067811865476): that normalisation is not idempotent at the last bit (1,1,0 gives
# 0.7071067811865475; normalising that again gives ...476), and a run records its config after a round trip
# through params.json (...476). Given as 1,1,0, a later rerun of the sweep would see another config and
# call every finished diagonal point stale (delete and redo it), which is what happened on a fresh machine
# on 2026-12-07. With h the config equals the recorded one and the points are reused. The physics is the
# same to 1 ulp of the direction.
h=0.7071067811865476
declare -A dirs=(
  [y]="0,1,0" [z]="0,0,1" [x]="1,0,0" [ext]="$h,$h,0" [comp]="$h,-$h,0" [yz]="0,$h,$h"
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
