#!/usr/bin/env bash
# Builds the runtime and the glTF importer with clang under ASan + UBSan, replays the deterministic checks,
# then fuzzes the runtime's loader and evaluator for NRAD_FUZZ_SECONDS (default 60) from tests/fuzz/corpus,
# and the glTF import for NRAD_GLTF_FUZZ_SECONDS (default 60) from tests/fuzz/gltf-corpus, tests/data and the
# bundled scenes (all copied: the committed corpora are never modified). Usage: run.sh SOURCE_DIR SCRATCH_DIR
set -euo pipefail
src=$1 scratch=$2 seconds=${NRAD_FUZZ_SECONDS:-60} gltf_seconds=${NRAD_GLTF_FUZZ_SECONDS:-60}
command -v clang++ > /dev/null || { echo "clang++ not found (./run.sh installs clang and libclang-rt-14-dev)" >&2; exit 1; }
mkdir -p "$scratch"
cmake -S "$src/tests/fuzz" -B "$scratch/build" -G Ninja -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ > "$scratch/configure.log" 2>&1 \
  || { cat "$scratch/configure.log"; exit 1; }
cmake --build "$scratch/build" > "$scratch/build.log" 2>&1 || { cat "$scratch/build.log"; exit 1; }
"$scratch/build/sanitized_driver" "$src"/tests/fuzz/corpus/*
rm -rf "$scratch/corpus" && cp -r "$src/tests/fuzz/corpus" "$scratch/corpus"
status=0
"$scratch/build/runtime_fuzz" -max_total_time="$seconds" -print_final_stats=1 -rss_limit_mb=2048 \
  -artifact_prefix="$scratch/" "$scratch/corpus" > "$scratch/fuzz.log" 2>&1 || status=$?
grep -E "^(stat::number_of_executed_units|stat::new_units_added|Done)|ERROR|SUMMARY" "$scratch/fuzz.log" || true
if [ "$status" -ne 0 ]; then
  echo "runtime_fuzz failed (exit $status); the input is in $scratch/crash-*; log: $scratch/fuzz.log" >&2
  tail -40 "$scratch/fuzz.log" >&2
  exit 1
fi

# The glTF importer. Seeds: the hostile inputs kept in gltf-corpus, the malformed and valid test files and the
# bundled scenes (files under 1 MB: libFuzzer's -max_len).
rm -rf "$scratch/gltf-corpus" && mkdir -p "$scratch/gltf-corpus"
cp "$src"/tests/fuzz/gltf-corpus/* "$src"/tests/data/malformed/*.gltf "$src"/tests/data/valid/*.gltf "$scratch/gltf-corpus/"
find "$src/scenes" -name '*.gltf' -size -1024k -exec cp {} "$scratch/gltf-corpus/" \;
# A real Draco stream, embedded (the fuzzer reads no external files), where the external scenes are present.
external="$src/../shared/scenes-external"
if [ -f "$external/BoxDraco/glTF-Draco/Box.gltf" ]; then
  python3 "$src/tests/fuzz/embed_glb.py" "$external/BoxDraco/glTF-Draco/Box.gltf" "$scratch/gltf-corpus/box-draco.glb"
fi
status=0
"$scratch/build/gltf_fuzz" -max_total_time="$gltf_seconds" -print_final_stats=1 -rss_limit_mb=2048 -max_len=1048576 \
  -dict="$src/tests/fuzz/gltf.dict" -artifact_prefix="$scratch/gltf-" "$scratch/gltf-corpus" > "$scratch/gltf-fuzz.log" 2>&1 || status=$?
grep -E "^(stat::number_of_executed_units|stat::new_units_added|Done)|ERROR|SUMMARY" "$scratch/gltf-fuzz.log" || true
if [ "$status" -ne 0 ]; then
  echo "gltf_fuzz failed (exit $status); the input is in $scratch/gltf-crash-*; log: $scratch/gltf-fuzz.log" >&2
  tail -40 "$scratch/gltf-fuzz.log" >&2
  exit 1
fi
