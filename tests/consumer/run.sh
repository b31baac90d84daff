#!/usr/bin/env bash
# Builds the runtime on its own (cmake -S runtime: no Embree, OpenEXR, TBB or json involved), static and
# shared, installs each into a scratch prefix, builds the C-only tests/consumer against it with
# find_package(nrad), and runs it on the golden asset. Usage: run.sh SOURCE_DIR SCRATCH_DIR
set -euo pipefail
src=$1 scratch=$2
rm -rf "$scratch"
mkdir -p "$scratch"
# Static (the default) and shared builds, each installed and consumed by the C-only project.
for kind in static shared; do
  shared=OFF; [ "$kind" = shared ] && shared=ON
  dir="$scratch/$kind"
  log="$scratch/$kind.log"
  cmake -S "$src/runtime" -B "$dir/runtime" -DCMAKE_BUILD_TYPE=Release -DBUILD_SHARED_LIBS=$shared > "$log" 2>&1 || { cat "$log"; exit 1; }
  cmake --build "$dir/runtime" >> "$log" 2>&1 || { cat "$log"; exit 1; }
  cmake --install "$dir/runtime" --prefix "$dir/install" >> "$log" 2>&1 || { cat "$log"; exit 1; }
  # The runtime's build must not have looked for any of the baker's dependencies.
  if grep -qiE "embree|openexr|tbb|nlohmann|tinygltf" "$dir/runtime/CMakeCache.txt"; then
    echo "the standalone runtime build refers to a baker dependency" >&2; exit 1
  fi
  cmake -S "$src/tests/consumer" -B "$dir/build" -DCMAKE_PREFIX_PATH="$dir/install" -DCMAKE_BUILD_TYPE=Release >> "$log" 2>&1 || { cat "$log"; exit 1; }
  cmake --build "$dir/build" >> "$log" 2>&1 || { cat "$log"; exit 1; }
  ls "$dir/install/lib"*/cmake/nrad/nradConfigVersion.cmake > /dev/null
  ls "$dir/install/include/nrad/version.h" > /dev/null
  shaders="$dir/install/share/nrad/shaders"
  ls "$shaders/nrad.glsl" "$shaders/nrad_gpu_layout.h" "$shaders/nrad_evaluate.comp" > /dev/null
  # The installed shaders compile from their own folder: nrad.glsl finds nrad_gpu_layout.h beside it.
  if command -v glslangValidator > /dev/null; then
    glslangValidator -V --target-env vulkan1.0 -o "$dir/nrad_evaluate.spv" "$shaders/nrad_evaluate.comp" >> "$log" 2>&1 \
      || { cat "$log"; echo "the installed shaders do not compile on their own" >&2; exit 1; }
  fi
  # The runtime's test hooks (runtime/src/testing.h) belong to its test build only, not to the installed library.
  lib=$(ls "$dir/install/lib"*/libnrad.* | head -1)
  if nm -C "$lib" 2>/dev/null | grep -q "rt::testing::"; then echo "$lib carries the runtime's test hooks" >&2; exit 1; fi
  if [ "$kind" = shared ]; then
    lib=$(ls "$dir/install/lib"*/libnrad.so.*.*.* | head -1)
    # Hidden visibility: the C API is all a shared libnrad exports.
    exported=$(nm -D --defined-only "$lib" | awk '{print $3}' | grep -v '^nrad' || true)
    if [ -n "$exported" ]; then echo "libnrad.so exports more than the C API:" >&2; echo "$exported" | head >&2; exit 1; fi
    # (Through a file: grep -q stops reading at the first match, and ldd, cut off, fails the pipe under pipefail.)
    ldd "$dir/build/consumer" > "$scratch/consumer.ldd"
    grep -q "libnrad.so" "$scratch/consumer.ldd" || { echo "the consumer is not linked to the shared libnrad" >&2; exit 1; }
  fi
  "$dir/build/consumer" "$src/tests/data/golden/tiny.nrad"
done
