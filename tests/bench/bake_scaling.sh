#!/bin/bash
# Bake scaling with cores (issue 16): the same bakes with --threads 1 and --threads 2 (the assets are
# byte-identical; checked), each phase's seconds from --stats, the faster of two runs each. Prints a markdown
# table. Usage: tests/bench/bake_scaling.sh OUT_DIR [NRAD_BINARY]
set -eu
OUT=$1
BIN=${2:-$(cd "$(dirname "$0")/../.." && pwd)/build/baker/nrad}
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
mkdir -p "$OUT" && cd "$OUT"
CB=$ROOT/scenes/cornell-box/cornell-box.gltf
Z=$ROOT/../shared/scenes-external/Sauerbraten_zdm2/zdm2.glb
echo "| bake | phase | 1 thread (s) | 2 threads (s) | speed-up |"
echo "|---|---|---|---|---|"
row() {  # label scene -- bakeflags
    local label=$1 scene=$2; shift 2
    for t in 1 2; do
        for rep in a b; do $BIN bake $scene -o sc_$t$rep.nrad -q --threads $t --stats sc_$t$rep.json "$@" > /dev/null; done
    done
    cmp -s sc_1a.nrad sc_2a.nrad || echo "| $label | ASSETS DIFFER between 1 and 2 threads | | | |"
    python3 - "$label" <<'PY'
import json, sys
def best(t):
    runs = [json.load(open(f"sc_{t}{r}.json"))["seconds"] for r in "ab"]
    return min(runs, key=lambda s: sum(s.values()))
one, two = best(1), best(2)
for phase in ["sampling", "partition", "training", "total"]:
    a = sum(one.values()) if phase == "total" else one[phase]
    b = sum(two.values()) if phase == "total" else two[phase]
    if a < 0.01: continue
    print(f"| {sys.argv[1]} | {phase} | {a:.2f} | {b:.2f} | {a / b:.2f}x |")
PY
}
row "cornell-box, Monte Carlo, 10,000 x 512 paths (the paper's)" $CB --max-depth 0 --points 10000 --paths 512
row "cornell-box, Monte Carlo, the defaults (160,000 x 32)" $CB
row "cornell-box, integral, the defaults" $CB --training integral
row "zdm2, integral, the defaults" $Z --training integral
row "zdm2, kd-tree --budget 64K, Monte Carlo" $Z --budget 64K --points 200000
