#!/bin/bash
# Error against bake time (issue 16): Monte Carlo targets (nrad bake --training monte-carlo, the paper's
# 10,000 points x 512 paths and cheaper and dearer points x paths) against training within the integral
# equation (--training integral, 1 to 32 rounds), on both Cornell boxes and Sauerbraten zdm2. Every bake is
# unbounded in path length (the integral's fixed point has every bounce), its time the sum of the phases in
# its --stats (the first seed baked twice: the faster run, and the two assets compared byte for byte), and
# its asset validated at 256 px against a reference of unbounded length (REFERENCE_SPP samples per pixel,
# default 512; 4,096 keeps the reference's own noise, about 0.00046 of the plain box's relMSE at 512, below
# 0.00006). One line per setting in OUT/sweep.txt (resumable); tests/bench/error_time_plot.py draws the SVG
# and the tables.
# Single bakes vary by seed (the glossy box by up to 40%, and one seed's network can fail): SEEDS="0 1 2" bakes
# each setting with every seed and reports the median relMSE and the mean time (each seed's relMSE on the line).
# Usage: [SEEDS="0 1 2"] [REFERENCE_SPP=4096] tests/bench/training_sweep.sh OUT_DIR [NRAD_BINARY] [SCENES]
#   SCENES: any of CB GB Z (default) and BB (tests/bench/bright_box.py)
#   (about 3 minutes per seed on 2 cores, plus the references once, 75 s each at 4,096 spp)
set -u
OUT=$1
BIN=${2:-$(cd "$(dirname "$0")/../.." && pwd)/build/baker/nrad}
SCENES=${3:-"CB GB Z"}
SEEDS=${SEEDS:-0}  # bake seeds: the line gives the median relMSE and the mean time over them
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
mkdir -p "$OUT" && cd "$OUT"
touch sweep.txt
seconds() { python3 -c "import json,sys; print(sum(json.load(open(sys.argv[1]))['seconds'].values()))" "$1"; }
run() {  # name scene viewflags -- bakeflags
    local name=$1 scene=$2 view=$3; shift 3
    grep -q "^$name " sweep.txt && return
    local times="" errs="" each=""
    for seed in $SEEDS; do
        local tag=tr_${name}_s$seed
        $BIN bake $scene -o $tag.nrad -q --stats $tag.json --seed $seed "$@" > $tag.bake.txt 2>&1 || { echo "$name seed $seed: bake failed" >> sweep.txt; return; }
        local t=$(seconds $tag.json)
        if [ "$seed" = "${SEEDS%% *}" ]; then  # the first seed twice: the faster time, and the bytes compared
            $BIN bake $scene -o $tag.2.nrad -q --stats $tag.2.json --seed $seed "$@" > /dev/null 2>&1
            cmp -s $tag.nrad $tag.2.nrad || echo "$name: the two bakes differ" >> sweep.txt
            t=$(python3 -c "print(min($t, $(seconds $tag.2.json)))")
        fi
        $BIN validate $scene $tag.nrad -o v$tag --width 256 --max-depth 0 --curve-max-spp 1 --no-baseline --reference-spp ${REFERENCE_SPP:-512} -q $view > $tag.val.txt 2>&1
        local e=$(grep -o 'neural relMSE [0-9.e-]*' $tag.val.txt | cut -d' ' -f3)
        times="$times $t"; errs="$errs $e"; each="$each s$seed=$e"
    done
    local mt=$(python3 -c "import sys; v=[float(x) for x in sys.argv[1:]]; print(sum(v)/len(v))" $times)
    local me=$(python3 -c "import sys, statistics; print('%.4g' % statistics.median(float(x) for x in sys.argv[1:]))" $errs)
    echo "$name seconds=$mt neural relMSE $me | seeds:$each | $(grep -o 'time:.*' tr_${name}_s${SEEDS%% *}.bake.txt) | $*" >> sweep.txt
}
CB=$ROOT/scenes/cornell-box/cornell-box.gltf
GB=$ROOT/scenes/cornell-box-glossy/cornell-box-glossy.gltf
Z=$ROOT/../shared/scenes-external/Sauerbraten_zdm2/zdm2.glb
ZV="--look-from -25,25,35 --look-at 10,-8,0 --fov 60"
BB=$PWD/bright-box.gltf  # SCENES="BB": the Cornell box with bright walls (long paths), written here
case " $SCENES " in *" BB "*) "$ROOT/tests/bench/bright_box.py" "$BB" ;; esac
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
