#!/usr/bin/env bash
# Builds the runtime with clang under ASan + UBSan, replays the deterministic checks, then fuzzes the
# loader and evaluator for NRAD_FUZZ_SECONDS (default 60) from tests/fuzz/corpus (copied: the committed
# corpus is never modified). Usage: run.sh SOURCE_DIR SCRATCH_DIR
set -euo pipefail
src=$1 scratch=$2 seconds=${NRAD_FUZZ_SECONDS:-60}
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
