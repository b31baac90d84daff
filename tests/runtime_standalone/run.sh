#!/usr/bin/env bash
# Builds and runs tests/runtime_standalone: the runtime's and the format's tests with the runtime alone.
#   run.sh SOURCE_DIR SCRATCH_DIR native    the host's compiler and CPU
#   run.sh SOURCE_DIR SCRATCH_DIR aarch64   cross-compiled with g++-aarch64-linux-gnu, run under qemu-aarch64
#                                           (the NEON kernels: the runtime's, and the baker's lockstep
#                                           training, nn_lockstep_tests); ./run.sh installs both
set -euo pipefail
src=$1 scratch=$2 target=${3:-native}
rm -rf "$scratch"
mkdir -p "$scratch"
args=()
if [ "$target" = aarch64 ]; then
  command -v aarch64-linux-gnu-g++ > /dev/null || { echo "aarch64-linux-gnu-g++ not found (./run.sh installs g++-aarch64-linux-gnu)" >&2; exit 1; }
  command -v qemu-aarch64 > /dev/null || { echo "qemu-aarch64 not found (./run.sh installs qemu-user)" >&2; exit 1; }
  # glm is header-only: a folder holding only it, so the cross compiler sees no other host header.
  mkdir -p "$scratch/glm-include"
  ln -s /usr/include/glm "$scratch/glm-include/glm"
  args=(-DCMAKE_TOOLCHAIN_FILE="$src/tests/runtime_standalone/aarch64-linux-gnu.cmake" -DNRAD_GLM_INCLUDE="$scratch/glm-include")
fi
cmake -S "$src/tests/runtime_standalone" -B "$scratch/build" -G Ninja -DCMAKE_BUILD_TYPE=Release "${args[@]}" > "$scratch/configure.log" 2>&1 \
  || { cat "$scratch/configure.log"; exit 1; }
cmake --build "$scratch/build" > "$scratch/build.log" 2>&1 || { cat "$scratch/build.log"; exit 1; }
# The build must not have looked for any of the baker's dependencies.
if grep -qiE "embree|openexr|tbb|nlohmann|tinygltf" "$scratch/build/CMakeCache.txt"; then
  echo "the standalone runtime tests refer to a baker dependency" >&2; exit 1
fi
if [ "$target" = aarch64 ]; then
  file "$scratch/build/runtime_standalone_tests" | grep -q "ARM aarch64" || { echo "not an aarch64 executable" >&2; exit 1; }
  qemu-aarch64 -L /usr/aarch64-linux-gnu "$scratch/build/runtime_standalone_tests"
  qemu-aarch64 -L /usr/aarch64-linux-gnu "$scratch/build/nn_lockstep_tests"
else
  "$scratch/build/runtime_standalone_tests"
fi
