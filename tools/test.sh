#!/usr/bin/env bash
# Configure, build and run every test. Used by the README and by CI.
#   EW_BUILD_DIR   build directory (default: build)
#   EW_CMAKE_FLAGS extra CMake flags
set -euo pipefail
cd "$(dirname "$0")/.."
dir="${EW_BUILD_DIR:-build}"
cmake -S . -B "$dir" ${EW_CMAKE_FLAGS:-} >/dev/null
cmake --build "$dir" -j"$(nproc)"
ctest --test-dir "$dir" --output-on-failure -j"$(nproc)"
