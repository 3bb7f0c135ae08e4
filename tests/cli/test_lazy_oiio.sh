#!/bin/sh
# OpenImageIO (and the ~260 libraries it pulls in) is loaded only for a file
# that is not an EXR: a denoise from EXR to EXR never maps it; the same run
# writing a PNG does (which also shows the first check can fail).
set -u
cli=$1
samples=$2
t=$(mktemp -d)
trap 'rm -rf "$t"' EXIT
src="$samples/cornell/f0001_spp0004.exr"
# a sanitizer build links OpenImageIO in (nodes/io/CMakeLists.txt says why)
if [ -n "${EW_OIIO_LINKED:-}" ]; then echo "skipped: OpenImageIO is linked in this build"; exit 77; fi

LD_DEBUG=files "$cli" denoise "$src" -o "$t/o.exr" -q 2> "$t/exr.txt" || {
    grep -v '^ *[0-9]*:' "$t/exr.txt"; echo "FAIL: denoise to EXR failed"; exit 1; }
if grep -q 'file=[^ ]*libOpenImageIO' "$t/exr.txt"; then
    echo "FAIL: a run on EXR files only loaded OpenImageIO:"
    grep 'libOpenImageIO\|edgewise_oiio' "$t/exr.txt" | head -3
    exit 1
fi

LD_DEBUG=files "$cli" denoise "$src" -o "$t/o.png" -q 2> "$t/png.txt" || {
    grep -v '^ *[0-9]*:' "$t/png.txt"; echo "FAIL: denoise to PNG failed"; exit 1; }
grep -q 'file=[^ ]*libedgewise_oiio.so' "$t/png.txt" || { echo "FAIL: writing a PNG did not load the OpenImageIO module"; exit 1; }
grep -q 'file=[^ ]*libOpenImageIO' "$t/png.txt" || { echo "FAIL: writing a PNG did not load OpenImageIO"; exit 1; }
"$cli" info "$t/o.png" | grep -q '256x256, 4 channels' || { echo "FAIL: the PNG does not read back"; exit 1; }
echo "ok: EXR runs without OpenImageIO, PNG runs load it"
