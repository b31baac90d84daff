#!/bin/bash
# Error against bytes (issue 15): uniform grids, then the adaptive kd-tree (nrad bake --budget) at each grid
# asset's exact size, on both Cornell boxes and Sauerbraten zdm2 (plus zdm2 under 1 MB); every asset validated
# at 256 px with its SH-probe baseline of equal bytes. One line per asset in OUT/sweep.txt (resumable: done
# lines are skipped); tests/bench/error_bytes_plot.py draws the SVG.
# Usage: tests/bench/partition_sweep.sh OUT_DIR [NRAD_BINARY]   (about 1.5 hours on 2 cores)
#        tests/bench/partition_sweep.sh --own-error OUT_DIR [NRAD_BINARY]
# --own-error: the two Cornell boxes only, grids 3, 4, 6 and the kd-tree at each grid's bytes with the same
# training points (160,000 x (G/3)^3), validated at 512 px with 64 primary samples against 4,096-spp references:
# the assets' own error, without the light's anti-aliased edge and the reference noise that the paper's 4
# samples and a 512-spp reference add to both (about 2.5 hours on 2 cores, the references included).
set -u
OWN=0
if [ "${1:-}" = "--own-error" ]; then OWN=1; shift; fi
OUT=$1
BIN=${2:-$(cd "$(dirname "$0")/../.." && pwd)/build/baker/nrad}
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
mkdir -p "$OUT" && cd "$OUT"
touch sweep.txt
run() {  # name scene viewflags -- bakeflags
    local name=$1 scene=$2 view=$3; shift 3
    grep -q "^$name " sweep.txt && return
    /usr/bin/time -v $BIN bake $scene -o sw_$name.nrad -q --stats sw_$name.json "$@" > sw_$name.bake.txt 2>&1
    if [ $OWN = 1 ]; then
        $BIN validate $scene sw_$name.nrad -o vsw_$name --reference-spp 4096 --spp 64 --curve-max-spp 1 -q --bake-stats sw_$name.json > sw_$name.val.txt 2>&1
    else
        $BIN validate $scene sw_$name.nrad -o vsw_$name --width 256 --curve-max-spp 16 -q $view --bake-stats sw_$name.json > sw_$name.val.txt 2>&1
    fi
    local sh=$(grep -o 'SH probe baseline ([0-9]* bytes, neural [0-9]* bytes): relMSE [0-9.e-]*' sw_$name.val.txt)
    local wall=$(grep -o 'Elapsed (wall clock) time.*' sw_$name.bake.txt | awk '{print $NF}')
    local rss=$(grep -o 'Maximum resident set size.*' sw_$name.bake.txt | awk '{print $NF}')
    echo "$name bytes=$(stat -c %s sw_$name.nrad) $(grep -o 'neural relMSE [0-9.e-]*' sw_$name.val.txt) | $sh | bake_wall=$wall rss_kb=$rss | $(grep -o 'time:.*' sw_$name.bake.txt)" >> sweep.txt
}
CB=$ROOT/scenes/cornell-box/cornell-box.gltf
GB=$ROOT/scenes/cornell-box-glossy/cornell-box-glossy.gltf
ZS=$ROOT/../shared/scenes-external/Sauerbraten_zdm2/zdm2.glb
ZV="--look-from -25,25,35 --look-at 10,-8,0 --fov 60"
if [ $OWN = 1 ]; then
  for scene in CB GB; do
    for g in 3 4 6; do
      P=$((160000 * g * g * g / 27))
      run ${scene}_grid$g ${!scene} "" --grid $g --points $P
      run ${scene}_kd$g ${!scene} "" --budget $(stat -c %s sw_${scene}_grid$g.nrad) --points $P
    done
  done
  echo done >> sweep.txt
  exit 0
fi
run Z_grid3 $ZS "$ZV" --grid 3
run Z_kd3 $ZS "$ZV" --budget $(stat -c %s sw_Z_grid3.nrad)
run Z_kd1M $ZS "$ZV" --budget 1M
for scene in CB GB; do
  for g in 2 3 4 6; do
    run ${scene}_grid$g ${!scene} "" --grid $g
    run ${scene}_kd$g ${!scene} "" --budget $(stat -c %s sw_${scene}_grid$g.nrad)
  done
done
run Z_grid6 $ZS "$ZV" --grid 6
run Z_kd6 $ZS "$ZV" --budget $(stat -c %s sw_Z_grid6.nrad)
echo done >> sweep.txt
