#!/usr/bin/env bash
# Installs the runtime from the build tree into a scratch prefix, builds tests/consumer against it with
# find_package(nrad), and runs it on the golden asset. Usage: run.sh BUILD_DIR SOURCE_DIR SCRATCH_DIR
set -euo pipefail
build=$1 src=$2 scratch=$3
rm -rf "$scratch"
cmake --install "$build" --prefix "$scratch/install" > "$scratch.install.log" 2>&1 || { cat "$scratch.install.log"; exit 1; }
cmake -S "$src/tests/consumer" -B "$scratch/build" -DCMAKE_PREFIX_PATH="$scratch/install" -DCMAKE_BUILD_TYPE=Release > /dev/null
cmake --build "$scratch/build"
# Only the runtime was installed: no baker library or header may be in the prefix.
if find "$scratch/install" -name '*embree*' -o -name '*tbb*' -o -name 'baker*' | grep -q .; then
  echo "the install prefix holds more than the runtime" >&2; exit 1
fi
"$scratch/build/consumer" "$src/tests/data/golden/tiny.nrad"
