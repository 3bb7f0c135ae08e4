#!/bin/sh
# Regenerate every benchmark figure and chart of BENCHMARKS.md on this machine.
#
#   bench/run_all.sh [-d DATA_DIR] [-o OUT_DIR] [-q] [-n] [--docs]
#
#   -d DIR    Cycles renders with references, one folder per scene
#             (default ../shared/data/cycles-train; tools/blender/make_dataset.sh
#             renders an equivalent set)
#   -o DIR    where everything goes (default bench_out)
#   -q        quick: 4 of the 12 scenes at 1 and 4 spp, no 7-layer NBG or exact
#             bilateral filter, one temporal sequence, one timing repeat, the filters'
#             --quick subset (a check that everything runs, not the figures)
#   -n        print the commands it would run, run nothing
#   --docs    also copy the charts and tables into docs/bench and docs/temporal,
#             where BENCHMARKS.md shows them
#
# Steps, each writing into OUT_DIR:
#   quality/    edgewise bench on the 12 held-out scenes (PSNR/SSIM/relMSE/SMAPE, ms),
#               then tools/bench_report.py: quality-vs-time charts with Pareto fronts,
#               tables, index.html with input / outputs / reference / error maps
#   temporal/   edgewise bench --temporal on the g_anim sequences + its report
#   strips/     the stability suite's image strips (tests/stability), on DATA's hard scenes
#   nbg_speed.txt     train_nbg --bench: 1280x720 ms per model, GuideNet share, GFLOP/s, 4K memory
#   kpcn_oidn.txt     bench/bench_kpcn_oidn.py --uhd: kpcn and OIDN (oidn_torch.py) on one 1280x720
#                     frame, time ratios, conv share of the FMA peak, peak RSS at 3840x2160 (not with -q)
#   filters/    bench_filters: pyramid filter quality vs brute force, time vs radius, speed ratios
# Environment: EW_BUILD_DIR (default build), PYTHON (default /usr/bin/python3: the
# Debian interpreter, which has matplotlib). A build directory configured for this
# checkout is brought up to date; one configured elsewhere (a copied checkout) is
# used as it is when its programs exist.
set -eu
ROOT=$(cd "$(dirname "$0")/.." && pwd)
DATA=$ROOT/../shared/data/cycles-train
OUT=bench_out
QUICK=0
DOCS=0
DRY=0
while [ $# -gt 0 ]; do
    case $1 in
        -d) DATA=$2; shift 2 ;;
        -o) OUT=$2; shift 2 ;;
        -q) QUICK=1; shift ;;
        -n) DRY=1; shift ;;
        --docs) DOCS=1; shift ;;
        -h|--help) sed -n '2,/^set -eu/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//'; exit 0 ;;
        *) echo "run_all.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
    esac
done
[ -d "$DATA" ] || { echo "run_all.sh: no data directory '$DATA' (-d DIR)" >&2; exit 1; }
B=${EW_BUILD_DIR:-$ROOT/build}
PY=${PYTHON:-/usr/bin/python3}
step() { echo "== $(date +%H:%M:%S) $*" >&2; }
# run CMD...: runs it, or with -n prints it (quoted as a shell would take it)
run() {
    if [ "$DRY" -eq 1 ]; then
        { printf '+'; for a in "$@"; do printf " '%s'" "$a"; done; printf '\n'; } >&2
    else
        "$@"
    fi
}
run mkdir -p "$OUT"

step "build ($B)"
home=$(sed -n 's/^CMAKE_HOME_DIRECTORY:INTERNAL=//p' "$B/CMakeCache.txt" 2>/dev/null || true)
if [ -n "$home" ] && [ "$(cd "$home" 2>/dev/null && pwd -P)" = "$(cd "$ROOT" && pwd -P)" ]; then
    run cmake --build "$B" -j"$(nproc)" >/dev/null
elif [ -z "$home" ]; then
    run cmake -S "$ROOT" -B "$B" >/dev/null
    run cmake --build "$B" -j"$(nproc)" >/dev/null
elif [ -x "$B/bin/edgewise" ]; then
    echo "run_all.sh: $B was configured for $home, not this checkout: using its programs as they are" >&2
else
    echo "run_all.sh: $B was configured for $home and has no bin/edgewise: set EW_BUILD_DIR" >&2
    exit 1
fi
[ -x "$B/bin/bench_filters" ] || run "$ROOT/bench/build.sh" "$B" >/dev/null
EW=$B/bin/edgewise
REPEAT=$([ "$QUICK" -eq 1 ] && echo 1 || echo 2)

# Held out from every choice of settings and from training (models/nbg/README.md)
SCENES=a_cornell_119,a_cornell_122,b_glossy_112,b_glossy_118,c_glass_113,c_glass_120,h_hdri_114,h_hdri_121,e_dof_116,d_firefly_115,f_motionblur_117,g_anim_123
METHODS=input,bgrid-features,bgrid,nbg,nbg-1grid,nbg-7layer,nbg-1spp,kpcn,kpcn-small,kpcn-large,auto,auto-high,auto-noise,atrous,pyramid-gi,bilateral-gi
SPP=1,4,16,64
TSCENES=g_anim_111,g_anim_123
if [ "$QUICK" -eq 1 ]; then
    # the slow parts of a full run are the 12 scenes x 4 spp, the exact bilateral
    # filter and the 7-layer GuideNet: a quick run keeps one scene of four kinds
    SCENES=a_cornell_119,b_glossy_112,d_firefly_115,g_anim_123
    METHODS=input,bgrid,nbg,auto,atrous,pyramid-gi
    SPP=1,4
    TSCENES=g_anim_123
fi

step "quality against time"
run "$EW" bench "$DATA" -o "$OUT/quality" --repeat "$REPEAT" --images --methods "$METHODS" --scenes "$SCENES" \
    --spp "$SPP"
# OIDN's figures on the test scenes (not run here: see the anchor's header)
ANCHOR=$ROOT/../shared/anchors/oidn-shared-test.md
if [ -f "$ANCHOR" ]; then run "$PY" "$ROOT/tools/bench_report.py" "$OUT/quality" --oidn "$ANCHOR"
else run "$PY" "$ROOT/tools/bench_report.py" "$OUT/quality"; fi

step "temporal stability"
TMETHODS=input,bgrid-features,bgrid,nbg,auto,atrous,pyramid-gi,bilateral-gi,outlier+auto
[ "$QUICK" -eq 1 ] && TMETHODS=input,bgrid,auto,pyramid-gi,outlier+auto
run "$EW" bench "$DATA" -o "$OUT/temporal" --temporal --repeat "$REPEAT" --scenes "$TSCENES" --spp 1,4 \
    --methods "$TMETHODS"
run "$PY" "$ROOT/tools/bench_report.py" "$OUT/temporal"

step "stability suite strips"
# the suite writes its strips into an existing directory, and finds the hard
# scenes of -d through EW_SHARED_DATA
run mkdir -p "$OUT/strips"
if [ "$DRY" -eq 1 ]; then
    echo "+ EW_SHARED_DATA='$DATA' EW_STABILITY_STRIPS='$OUT/strips' '$B/bin/test_stability'" >&2
else
    EW_SHARED_DATA="$DATA" EW_STABILITY_STRIPS="$OUT/strips" "$B/bin/test_stability" >"$OUT/stability.txt" 2>&1 || {
        echo "run_all.sh: the stability suite failed; see $OUT/stability.txt" >&2; exit 1; }
    ls "$OUT/strips"/*.png >/dev/null 2>&1 || { echo "run_all.sh: the stability suite wrote no strips" >&2; exit 1; }
fi

step "NBG speed and memory at 1280x720"
if [ "$DRY" -eq 1 ]; then
    run "$B/bin/train_nbg" --bench --data "$DATA" --models "$ROOT/models/nbg"
else
    "$B/bin/train_nbg" --bench --data "$DATA" --models "$ROOT/models/nbg" | tee "$OUT/nbg_speed.txt"
fi

step "kpcn against OIDN at 1280x720, kpcn's peak memory at 3840x2160"
if [ "$QUICK" -eq 1 ]; then
    echo "run_all.sh: -q leaves out kpcn against OIDN (minutes of OIDN's network on the CPU)" >&2
elif [ "$DRY" -eq 1 ]; then
    run "$PY" "$ROOT/bench/bench_kpcn_oidn.py" --uhd
else
    EW_BUILD_DIR=$B "$PY" "$ROOT/bench/bench_kpcn_oidn.py" --uhd | tee "$OUT/kpcn_oidn.txt"
fi

step "edge-aware filters (issue 4)"
# DoF pinhole/true-DoF pairs (bench/README.md): rendered once with Blender when absent
if [ "$DRY" -eq 0 ] && ! ls -d "$ROOT"/bench/data/dof* >/dev/null 2>&1 && command -v blender >/dev/null; then
    for seed in 105 116; do
        [ -d "$OUT/dof_pairs/dof$seed" ] || blender -b --factory-startup --python "$ROOT/bench/render_dof_pair.py" -- \
            --seed $seed --width 256 --height 256 --pinhole-spp 128 --dof-spp 512 --out "$OUT/dof_pairs/dof$seed" \
            >"$OUT/dof_pairs_$seed.log" 2>&1 || echo "run_all.sh: DoF pair $seed failed ($OUT/dof_pairs_$seed.log)" >&2
    done
fi
set -- --data "$DATA" --out "$OUT/filters" --threads "$(nproc)"
for pair in "$ROOT"/bench/data/dof* "$OUT"/dof_pairs/dof*; do [ -d "$pair" ] && set -- "$@" --dof-pair "$pair"; done
[ "$QUICK" -eq 1 ] && set -- "$@" --quick
run mkdir -p "$OUT/filters"
run "$B/bin/bench_filters" "$@"

if [ "$DOCS" -eq 1 ] && [ "$DRY" -eq 0 ]; then
    step "copying charts into docs/"
    cp "$OUT"/quality/*.png "$OUT"/quality/results.csv "$ROOT/docs/bench/" 2>/dev/null || true
    mkdir -p "$ROOT/docs/temporal"
    cp "$OUT"/temporal/*.png "$OUT"/temporal/*.csv "$OUT"/temporal/*.md "$ROOT/docs/temporal/" 2>/dev/null || true
fi
[ "$DRY" -eq 1 ] && exit 0
step "done: $OUT (quality/index.html, quality/*.png, temporal/, strips/, nbg_speed.txt, filters/)"
