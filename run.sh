#!/usr/bin/env bash
# nrad quick start: installs what is missing (Debian 12, as root), configures, builds, and runs.
#   ./run.sh demo   bake the bundled Cornell box and validate the asset against a path-traced reference:
#                   prints bake time, asset bytes, relMSE of the asset and of the SH-probe baseline, the
#                   equal-error time ratio, and the path of report.html (the reference is cached, so a
#                   second run only re-bakes and re-renders the fast parts)
#   ./run.sh test   build everything and run the whole test suite (CTest)
#   ./run.sh build  only install, configure and build
# Environment: BUILD_DIR (default build), NRAD_WERROR=ON to treat warnings as errors (CI).
set -euo pipefail
cd "$(dirname "$0")"

PACKAGES=(cmake ninja-build g++ pkg-config python3
  libembree-dev libtinygltf-dev libdraco-dev libopenexr-dev libglm-dev nlohmann-json3-dev
  libtbb-dev libcli11-dev libstb-dev libgtest-dev libgmock-dev libbenchmark-dev
  clang libclang-rt-14-dev chromium
  libvulkan-dev glslang-tools mesa-vulkan-drivers
  g++-aarch64-linux-gnu qemu-user file
  libopenmpi-dev openmpi-bin)

install_packages() {
  local missing=()
  for p in "${PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  [ ${#missing[@]} -eq 0 ] && return 0
  echo "== installing: ${missing[*]}" >&2
  if [ "$(id -u)" -ne 0 ]; then
    echo "run.sh: packages missing (${missing[*]}); run as root or install them first" >&2
    exit 1
  fi
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
}

BUILD_DIR=${BUILD_DIR:-build}
build() {
  install_packages
  cmake -S . -B "$BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE=Release -DNRAD_WERROR="${NRAD_WERROR:-OFF}" -DNRAD_BUILD_TESTS=ON -DNRAD_BUILD_BENCHMARKS=ON >/dev/null
  cmake --build "$BUILD_DIR" --parallel "$(nproc)"
}

case "${1:-}" in
  demo)
    build
    mkdir -p out
    "$BUILD_DIR/baker/nrad" bake scenes/cornell-box/cornell-box.gltf -o out/cornell-box.nrad --stats out/cornell-box-bake.json -q
    "$BUILD_DIR/baker/nrad" validate scenes/cornell-box/cornell-box.gltf out/cornell-box.nrad -o out/cornell-box-report \
      --bake-stats out/cornell-box-bake.json -q
    ;;
  test)
    build
    # lavapipe (mesa-vulkan-drivers, installed above) is a Vulkan device on the CPU: the GPU tests must run,
    # never skip.
    NRAD_REQUIRE_VULKAN=${NRAD_REQUIRE_VULKAN:-1} \
      ctest --test-dir "$BUILD_DIR" --output-on-failure --parallel "$(nproc)" ${CTEST_ARGS:-}
    ;;
  build)
    build
    ;;
  *)
    echo "usage: ./run.sh demo|test|build" >&2
    exit 2
    ;;
esac
