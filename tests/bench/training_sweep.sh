#!/bin/bash
# Error against bake time (issue 16): Monte Carlo targets (nrad bake --training monte-carlo, the paper's
# 10,000 points x 512 paths and cheaper and dearer points x paths) against training within the integral
# equation (--training integral, 1 to 32 rounds), on both Cornell boxes and Sauerbraten zdm2. Every bake is
# unbounded in path length (the integral's fixed point has every bounce), its time the sum of the phases in
# its --stats (the faster of two runs: the bake is deterministic), and its asset validated at 256 px
# against a 512 spp reference of unbounded length. One line per bake in OUT/sweep.txt (resumable);
# tests/bench/error_time_plot.py draws the SVG and the table.
# Usage: tests/bench/training_sweep.sh OUT_DIR [NRAD_BINARY] [SCENES]   (about 40 minutes on 2 cores)
set -u
OUT=$1
BIN=${2:-$(cd "$(dirname "$0")/../.." && pwd)/build/baker/nrad}
SCENES=${3:-"CB GB Z"}
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
mkdir -p "$OUT" && cd "$OUT"
touch sweep.txt
seconds() { python3 -c "import json,sys; print(sum(json.load(open(sys.argv[1]))['seconds'].values()))" "$1"; }
run() {  # name scene viewflags -- bakeflags
    local name=$1 scene=$2 view=$3; shift 3
    grep -q "^$name " sweep.txt && return
    $BIN bake $scene -o tr_$name.nrad -q --stats tr_$name.json "$@" > tr_$name.bake.txt 2>&1 || { echo "$name bake failed" >> sweep.txt; return; }
    $BIN bake $scene -o tr_$name.2.nrad -q --stats tr_$name.2.json "$@" > /dev/null 2>&1
    cmp -s tr_$name.nrad tr_$name.2.nrad || echo "$name: the two bakes differ" >> sweep.txt
    local t=$(python3 -c "print(min($(seconds tr_$name.json), $(seconds tr_$name.2.json)))")
    $BIN validate $scene tr_$name.nrad -o vtr_$name --width 256 --max-depth 0 --curve-max-spp 1 --no-baseline -q $view > tr_$name.val.txt 2>&1
    echo "$name seconds=$t $(grep -o 'neural relMSE [0-9.e-]*' tr_$name.val.txt) | $(grep -o 'time:.*' tr_$name.bake.txt) | $*" >> sweep.txt
}
CB=$ROOT/scenes/cornell-box/cornell-box.gltf
GB=$ROOT/scenes/cornell-box-glossy/cornell-box-glossy.gltf
Z=$ROOT/../shared/scenes-external/Sauerbraten_zdm2/zdm2.glb
ZV="--look-from -25,25,35 --look-at 10,-8,0 --fov 60"
for scene in $SCENES; do
  view=""; [ $scene = Z ] && view=$ZV
  for pp in "10000 512" "2500 32" "5000 32" "10000 32" "20000 32" "40000 32" "10000 128" "20000 128" "40000 64"; do
    set -- $pp
    run ${scene}_mc_$1x$2 ${!scene} "$view" --max-depth 0 --points $1 --paths $2
  done
  for g in 1 2 4 8 16 32; do
    run ${scene}_int_g$g ${!scene} "$view" --training integral --generations $g
  done
done
echo done >> sweep.txt
