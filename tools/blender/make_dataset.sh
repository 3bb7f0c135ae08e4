#!/bin/sh
# Render an Edgewise training/validation/test set with tools/blender/render_scene.py.
#
# Usage: tools/blender/make_dataset.sh [options]
#   -o DIR        output root (default: data/cycles-gen); scenes go to
#                 DIR/{train,val,test}/<letter>_<family>_<seed>_<W>x<H>/
#   -s SPLITS     splits to render, comma-separated (default: train,val,test)
#   -n N          scenes per family in train (default 8)
#   -v N          scenes per family in val   (default 2)
#   -t N          scenes per family in test  (default 2)
#   -f FAMILIES   comma-separated families (default: all eight)
#   -W W -H H     resolution (default 256x256)
#   -r SPP        reference spp (default 1024)
#   -j THREADS    Cycles threads per render, 0 = all cores (default 0)
#   -d            dry run: print the commands, render nothing
#   -h            help
# Environment: BLENDER (default: blender).
#
# Seeds.  The three splits use disjoint seed ranges, so no scene (hence no
# layout, material or noise pattern) is shared between them:
#     train  100000 .. 199999
#     val    200000 .. 299999
#     test   300000 .. 399999
# Within a split, scene i of family k (k = 0..7 in the order
# cornell glossy glass firefly dof motionblur anim hdri) gets
#     seed = base + 8*i + k
# so every scene in the whole set has a distinct seed even across families
# (render_scene.py seeds random.Random(seed) the same way for every family).
# 8*i + k < 100000, i.e. at most 12500 scenes per family and split.
# The bundled sample (samples/cornell, seed 7) and the shared cycles-train set
# (seeds 100..123, another generator) lie outside all three ranges.
#
# Noisy inputs: 1,4,16,64 spp; anim (4 frames): 1,4 spp.  A scene whose
# meta.json exists is complete and is skipped, so the script can be re-run to
# resume.  Renders run one at a time (each uses all cores).
set -eu

here=$(cd "$(dirname "$0")" && pwd)
script="$here/render_scene.py"
blender=${BLENDER:-blender}

out=data/cycles-gen
splits=train,val,test
n_train=8
n_val=2
n_test=2
families=cornell,glossy,glass,firefly,dof,motionblur,anim,hdri
width=256
height=256
ref=1024
threads=0
dry=0

usage() { sed -n '2,/^set -eu/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//'; }

while getopts "o:s:n:v:t:f:W:H:r:j:dh" opt; do
    case $opt in
        o) out=$OPTARG ;;
        s) splits=$OPTARG ;;
        n) n_train=$OPTARG ;;
        v) n_val=$OPTARG ;;
        t) n_test=$OPTARG ;;
        f) families=$OPTARG ;;
        W) width=$OPTARG ;;
        H) height=$OPTARG ;;
        r) ref=$OPTARG ;;
        j) threads=$OPTARG ;;
        d) dry=1 ;;
        h) usage; exit 0 ;;
        *) usage >&2; exit 2 ;;
    esac
done
shift $((OPTIND - 1))
[ $# -eq 0 ] || { echo "make_dataset.sh: unexpected argument: $1" >&2; exit 2; }

isnum() { case $1 in ''|*[!0-9]*) return 1 ;; *) return 0 ;; esac; }
for v in "$n_train" "$n_val" "$n_test" "$width" "$height" "$ref" "$threads"; do
    isnum "$v" || { echo "make_dataset.sh: not a non-negative integer: $v" >&2; exit 2; }
done

letter_of() {
    case $1 in
        cornell) echo "a 0" ;; glossy) echo "b 1" ;; glass) echo "c 2" ;;
        firefly) echo "d 3" ;; dof) echo "e 4" ;; motionblur) echo "f 5" ;;
        anim) echo "g 6" ;; hdri) echo "h 7" ;;
        *) return 1 ;;
    esac
}

fams=$(echo "$families" | tr ',' ' ')
for fam in $fams; do
    letter_of "$fam" >/dev/null || { echo "make_dataset.sh: unknown family: $fam" >&2; exit 2; }
done

failed=0
done_n=0
skipped=0
for split in $(echo "$splits" | tr ',' ' '); do
    case $split in
        train) base=100000; count=$n_train ;;
        val)   base=200000; count=$n_val ;;
        test)  base=300000; count=$n_test ;;
        *) echo "make_dataset.sh: unknown split: $split" >&2; exit 2 ;;
    esac
    [ "$count" -le 12500 ] || { echo "make_dataset.sh: at most 12500 scenes per family/split" >&2; exit 2; }
    i=0
    while [ "$i" -lt "$count" ]; do
        for fam in $fams; do
            lk=$(letter_of "$fam")
            letter=${lk% *}; k=${lk#* }
            seed=$((base + 8 * i + k))
            dir="$out/$split/${letter}_${fam}_${seed}_${width}x${height}"
            if [ "$fam" = anim ]; then spp=1,4; frames=4; else spp=1,4,16,64; frames=1; fi
            if [ -f "$dir/meta.json" ]; then
                skipped=$((skipped + 1))
                continue
            fi
            echo "== $split $fam seed $seed -> $dir" >&2
            set -- "$blender" -b --factory-startup --python "$script" -- \
                --family "$fam" --seed "$seed" --width "$width" --height "$height" \
                --spp "$spp" --ref-spp "$ref" --frames "$frames" --threads "$threads" --out "$dir"
            if [ "$dry" = 1 ]; then
                echo "$*"
                continue
            fi
            if "$@"; then
                done_n=$((done_n + 1))
            else
                echo "make_dataset.sh: FAILED: $split $fam seed $seed" >&2
                failed=$((failed + 1))
            fi
        done
        i=$((i + 1))
    done
done
echo "make_dataset.sh: rendered $done_n, skipped $skipped (complete), failed $failed" >&2
[ "$failed" -eq 0 ]
