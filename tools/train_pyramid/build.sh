#!/bin/sh
# Build train_pyramid against an existing CMake build directory (for when the
# top-level CMakeLists.txt does not add tools/train_pyramid):
#   tools/train_pyramid/build.sh [BUILD_DIR]   -> BUILD_DIR/bin/train_pyramid
set -e
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
B=${1:-$ROOT/build}
cc -O3 -DNDEBUG -std=c11 -D_POSIX_C_SOURCE=200809L -Wall -Wextra -Wshadow -Wstrict-prototypes -Wmissing-prototypes \
  -I"$ROOT/core" -I"$ROOT/core/include" -I"$ROOT/nodes/io" "$ROOT/tools/train_pyramid/train_pyramid.c" \
  "$B/lib/libedgewise_core.a" "$B/lib/libedgewise_io.a" $(pkg-config --libs OpenImageIO) -lstdc++ -lpthread -lm \
  -o "$B/bin/train_pyramid"
echo "$B/bin/train_pyramid"
