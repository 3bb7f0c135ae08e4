#!/bin/sh
# Build bench_filters against an existing CMake build directory:
#   bench/build.sh [BUILD_DIR]   -> BUILD_DIR/bin/bench_filters
# then e.g.  BUILD_DIR/bin/bench_filters --data ../shared/data/cycles-train \
#              --dof-pair DIR --out bench/results
set -e
ROOT=$(cd "$(dirname "$0")/.." && pwd)
B=${1:-$ROOT/build}
cc -O3 -DNDEBUG -std=c11 -D_POSIX_C_SOURCE=200809L -Wall -Wextra -Wshadow -Wstrict-prototypes -Wmissing-prototypes \
  -I"$ROOT/core" -I"$ROOT/core/include" -I"$ROOT/nodes/io" "$ROOT/bench/bench_filters.c" \
  "$B/lib/libedgewise_core.a" "$B/lib/libedgewise_io.a" $(pkg-config --libs OpenImageIO) -lstdc++ -lpthread -lm \
  -o "$B/bin/bench_filters"
echo "$B/bin/bench_filters"
