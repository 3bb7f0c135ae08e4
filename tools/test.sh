#!/usr/bin/env bash
# Configure, build and run every test. Used by the README and by CI.
#   EW_BUILD_DIR   build directory (default: build)
#   EW_CMAKE_FLAGS extra CMake flags
#   EW_CTEST_ARGS  extra CTest arguments (e.g. -E 'python|blender')
set -euo pipefail
cd "$(dirname "$0")/.."
dir="${EW_BUILD_DIR:-build}"
# shellcheck disable=SC2086
cmake -S . -B "$dir" ${EW_CMAKE_FLAGS:-} >/dev/null
cmake --build "$dir" -j"$(nproc)"
# shellcheck disable=SC2086
ctest --test-dir "$dir" --output-on-failure -j"$(nproc)" ${EW_CTEST_ARGS:-}
