#!/bin/sh
# Regenerate every benchmark figure and chart of BENCHMARKS.md on this machine.
#
#   bench/run_all.sh [-d DATA_DIR] [-o OUT_DIR] [-q] [--docs]
#
#   -d DIR    Cycles renders with references, one folder per scene
#             (default ../shared/data/cycles-train; tools/blender/make_dataset.sh
#             renders an equivalent set)
#   -o DIR    where everything goes (default bench_out)
#   -q        quick: fewer repeats, no brute-force timing sweep (minutes, not an hour)
#   --docs    also copy the charts and tables into docs/bench and docs/temporal,
#             where BENCHMARKS.md shows them
#
# Steps, each writing into OUT_DIR:
#   quality/    edgewise bench on the 12 held-out scenes (PSNR/SSIM/relMSE/SMAPE, ms),
#               then tools/bench_report.py: quality-vs-time charts with Pareto fronts,
#               tables, index.html with input / outputs / reference / error maps
#   temporal/   edgewise bench --temporal on the g_anim sequences + its report
#   strips/     the stability suite's image strips (tests/stability)
#   nbg_speed.txt     train_nbg --bench: 1280x720 ms per model, GuideNet share, GFLOP/s, 4K memory
#   filters/    bench_filters: pyramid filter quality vs brute force, time vs radius, speed ratios
# Environment: EW_BUILD_DIR (default build), PYTHON (default /usr/bin/python3: the
# Debian interpreter, which has matplotlib).
set -eu
ROOT=$(cd "$(dirname "$0")/.." && pwd)
DATA=$ROOT/../shared/data/cycles-train
OUT=bench_out
QUICK=0
DOCS=0
while [ $# -gt 0 ]; do
    case $1 in
        -d) DATA=$2; shift 2 ;;
        -o) OUT=$2; shift 2 ;;
        -q) QUICK=1; shift ;;
        --docs) DOCS=1; shift ;;
        -h|--help) sed -n '2,/^set -eu/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//'; exit 0 ;;
        *) echo "run_all.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
    esac
done
[ -d "$DATA" ] || { echo "run_all.sh: no data directory '$DATA' (-d DIR)" >&2; exit 1; }
B=${EW_BUILD_DIR:-$ROOT/build}
PY=${PYTHON:-/usr/bin/python3}
mkdir -p "$OUT"
step() { echo "== $(date +%H:%M:%S) $*" >&2; }

step "build ($B)"
cmake -S "$ROOT" -B "$B" >/dev/null
cmake --build "$B" -j"$(nproc)" >/dev/null
[ -x "$B/bin/bench_filters" ] || "$ROOT/bench/build.sh" "$B" >/dev/null
EW=$B/bin/edgewise
REPEAT=$([ "$QUICK" -eq 1 ] && echo 1 || echo 2)

# Held out from every choice of settings and from training (models/nbg/README.md)
SCENES=a_cornell_119,a_cornell_122,b_glossy_112,b_glossy_118,c_glass_113,c_glass_120,h_hdri_114,h_hdri_121,e_dof_116,d_firefly_115,f_motionblur_117,g_anim_123
METHODS=input,bgrid-features,bgrid,nbg,nbg-1grid,nbg-7layer,nbg-1spp,auto,auto-noise,atrous,pyramid-gi,bilateral-gi

step "quality against time"
"$EW" bench "$DATA" -o "$OUT/quality" --repeat "$REPEAT" --images --methods "$METHODS" --scenes "$SCENES"
"$PY" "$ROOT/tools/bench_report.py" "$OUT/quality"

step "temporal stability"
"$EW" bench "$DATA" -o "$OUT/temporal" --temporal --repeat "$REPEAT" --scenes g_anim_111,g_anim_123 --spp 1,4 \
    --methods input,bgrid-features,bgrid,nbg,auto,atrous,pyramid-gi,bilateral-gi,outlier+auto
"$PY" "$ROOT/tools/bench_report.py" "$OUT/temporal"

step "stability suite strips"
EW_STABILITY_STRIPS="$OUT/strips" "$B/bin/test_stability" >"$OUT/stability.txt" 2>&1 || {
    echo "run_all.sh: the stability suite failed; see $OUT/stability.txt" >&2; exit 1; }

step "NBG speed and memory at 1280x720"
"$B/bin/train_nbg" --bench --data "$DATA" --models "$ROOT/models/nbg" | tee "$OUT/nbg_speed.txt"

step "edge-aware filters (issue 4)"
# DoF pinhole/true-DoF pairs (bench/README.md): rendered once with Blender when absent
if ! ls -d "$ROOT"/bench/data/dof* >/dev/null 2>&1 && command -v blender >/dev/null; then
    for seed in 105 116; do
        [ -d "$OUT/dof_pairs/dof$seed" ] || blender -b --factory-startup --python "$ROOT/bench/render_dof_pair.py" -- \
            --seed $seed --width 256 --height 256 --pinhole-spp 128 --dof-spp 512 --out "$OUT/dof_pairs/dof$seed" \
            >"$OUT/dof_pairs_$seed.log" 2>&1 || echo "run_all.sh: DoF pair $seed failed ($OUT/dof_pairs_$seed.log)" >&2
    done
fi
set -- --data "$DATA" --out "$OUT/filters" --threads "$(nproc)"
for pair in "$ROOT"/bench/data/dof* "$OUT"/dof_pairs/dof*; do [ -d "$pair" ] && set -- "$@" --dof-pair "$pair"; done
[ "$QUICK" -eq 1 ] && set -- "$@" --quick
mkdir -p "$OUT/filters"
"$B/bin/bench_filters" "$@"

if [ "$DOCS" -eq 1 ]; then
    step "copying charts into docs/"
    cp "$OUT"/quality/*.png "$OUT"/quality/results.csv "$ROOT/docs/bench/" 2>/dev/null || true
    mkdir -p "$ROOT/docs/temporal"
    cp "$OUT"/temporal/*.png "$OUT"/temporal/*.csv "$OUT"/temporal/*.md "$ROOT/docs/temporal/" 2>/dev/null || true
fi
step "done: $OUT (quality/index.html, quality/*.png, temporal/, strips/, nbg_speed.txt, filters/)"
