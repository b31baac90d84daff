#!/usr/bin/env bash
# Builds the runtime on its own (cmake -S runtime: no Embree, OpenEXR, TBB or json involved), installs it
# into a scratch prefix, builds tests/consumer against it with find_package(nrad), and runs it on the
# golden asset. Usage: run.sh SOURCE_DIR SCRATCH_DIR
set -euo pipefail
src=$1 scratch=$2
rm -rf "$scratch"
cmake -S "$src/runtime" -B "$scratch/runtime" -DCMAKE_BUILD_TYPE=Release > "$scratch.log" 2>&1 || { cat "$scratch.log"; exit 1; }
cmake --build "$scratch/runtime" >> "$scratch.log" 2>&1 || { cat "$scratch.log"; exit 1; }
cmake --install "$scratch/runtime" --prefix "$scratch/install" >> "$scratch.log" 2>&1 || { cat "$scratch.log"; exit 1; }
# The runtime's build must not have looked for any of the baker's dependencies.
if grep -qiE "embree|openexr|tbb|nlohmann|tinygltf" "$scratch/runtime/CMakeCache.txt"; then
  echo "the standalone runtime build refers to a baker dependency" >&2; exit 1
fi
cmake -S "$src/tests/consumer" -B "$scratch/build" -DCMAKE_PREFIX_PATH="$scratch/install" -DCMAKE_BUILD_TYPE=Release > /dev/null
cmake --build "$scratch/build" > /dev/null
ls "$scratch/install/lib"*/cmake/nrad/nradConfigVersion.cmake > /dev/null
ls "$scratch/install/share/nrad/shaders/nrad.glsl" "$scratch/install/share/nrad/shaders/nrad_evaluate.comp" > /dev/null
"$scratch/build/consumer" "$src/tests/data/golden/tiny.nrad"
