#!/bin/sh
# Render training data for the learned denoisers into a cache outside git, resumably.
#
# Usage: tools/blender/render_cache.sh [options]
#   -o DIR        cache root (default: $EW_DATA_CACHE, else ~/.cache/edgewise/renders)
#   -s SPLIT      train or val (default train)
#   -n N          scenes to have in the split when done (default 120)
#   -f FAMILIES   comma-separated families (default: all eleven, interleaved)
#   -p SPP        noisy sample counts (default 1,2,4,8,16,32,64)
#   -r SPP        target spp (default 256)
#   -W W -H H     resolution (default 256x256)
#   -j THREADS    Cycles threads per render, 0 = all cores (default 0)
#   -N NICE       niceness of the renders (default 10: builds and tests go first)
#   -S STYLE      render_scene.py's --style: busy (default) or simple (the shared
#                 cycles-train set's look; its eight families; seeds base + 20000)
#   -c            check: verify every complete scene's checksums, render nothing
#   -d            dry run: print what would be rendered
#   -h            help
# Environment: BLENDER (default: blender).
#
# Layout: DIR/SPLIT/<letter>_<family>_<seed>_<W>x<H>/ as tools/blender/render_scene.py
# writes it, plus SHA256SUMS in each scene folder. DIR/manifest.tsv has one line per
# complete scene: split, scene, family, seed, noisy spp, target spp, frames, seconds,
# sha256 of the scene's SHA256SUMS.
#
# Resumable: a scene is rendered into SCENE.partial/ and renamed into place only when
# Blender succeeded and its checksums are written, so a killed run leaves no folder that
# looks complete; the next run deletes the .partial folder and starts that scene again.
# Complete scenes are skipped. On a new machine the same command re-renders what is
# missing (renders are deterministic per seed up to Cycles' last-bit noise).
#
# Seeds. Scene i of family k (k = position in the full list below) gets
#     seed = base + 16*i + k,  base 150000 (train) or 250000 (val), 20000 more for -S simple,
# inside make_dataset.sh's train (100000..199999) and val (200000..299999) ranges, so
# never a test seed (300000..) and never one of the shared cycles-train scenes (100..123),
# which hold the test scenes of BENCHMARKS.md. Families are interleaved, so any prefix of
# the set is balanced.
set -eu

here=$(cd "$(dirname "$0")" && pwd)
script="$here/render_scene.py"
blender=${BLENDER:-blender}

all_families=cornell,glossy,glass,firefly,dof,motionblur,anim,hdri,volume,texture,thin
out=${EW_DATA_CACHE:-${HOME:-/tmp}/.cache/edgewise/renders}
split=train
count=120
families=$all_families
spp=1,2,4,8,16,32,64
ref=256
width=256
height=256
threads=0
niceness=10
style=busy
families_given=0
check=0
dry=0

usage() { sed -n '2,/^set -eu/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//'; }

while getopts "o:s:n:f:p:r:W:H:j:N:S:cdh" opt; do
    case $opt in
        o) out=$OPTARG ;;
        s) split=$OPTARG ;;
        n) count=$OPTARG ;;
        f) families=$OPTARG; families_given=1 ;;
        p) spp=$OPTARG ;;
        r) ref=$OPTARG ;;
        W) width=$OPTARG ;;
        H) height=$OPTARG ;;
        j) threads=$OPTARG ;;
        N) niceness=$OPTARG ;;
        S) style=$OPTARG ;;
        c) check=1 ;;
        d) dry=1 ;;
        h) usage; exit 0 ;;
        *) usage >&2; exit 2 ;;
    esac
done
shift $((OPTIND - 1))
[ $# -eq 0 ] || { echo "render_cache.sh: unexpected argument: $1" >&2; exit 2; }

isnum() { case $1 in ''|*[!0-9]*) return 1 ;; *) return 0 ;; esac; }
for v in "$count" "$ref" "$width" "$height" "$threads" "$niceness"; do
    isnum "$v" || { echo "render_cache.sh: not a non-negative integer: $v" >&2; exit 2; }
done
case $split in
    train) base=150000 ;;
    val) base=250000 ;;
    *) echo "render_cache.sh: split must be train or val (test scenes are never rendered here)" >&2; exit 2 ;;
esac
case $style in
    busy) ;;
    simple)
        base=$((base + 20000))
        [ "$families_given" = 1 ] || families=cornell,glossy,glass,firefly,dof,motionblur,anim,hdri ;;
    *) echo "render_cache.sh: style must be busy or simple" >&2; exit 2 ;;
esac

# family -> "letter index" in the full list (the index fixes the seed)
family_info() {
    k=0
    for f in $(echo "$all_families" | tr ',' ' '); do
        if [ "$f" = "$1" ]; then
            case $f in
                cornell) l=a ;; glossy) l=b ;; glass) l=c ;; firefly) l=d ;; dof) l=e ;;
                motionblur) l=f ;; anim) l=g ;; hdri) l=h ;; volume) l=i ;; texture) l=j ;;
                thin) l=k ;;
            esac
            echo "$l $k"
            return 0
        fi
        k=$((k + 1))
    done
    return 1
}
fams=$(echo "$families" | tr ',' ' ')
nfam=0
for f in $fams; do
    family_info "$f" >/dev/null || { echo "render_cache.sh: unknown family: $f" >&2; exit 2; }
    nfam=$((nfam + 1))
done

mkdir -p "$out/$split"
manifest="$out/manifest.tsv"
[ -f "$manifest" ] || printf 'split\tscene\tfamily\tseed\tspp\tref_spp\tframes\tseconds\tsums_sha256\n' > "$manifest"

rendered=0; skipped=0; failed=0; bad=0
n=0; i=0
while [ "$n" -lt "$count" ]; do
    for fam in $fams; do
        [ "$n" -lt "$count" ] || break
        n=$((n + 1))
        info=$(family_info "$fam"); letter=${info% *}; k=${info#* }
        seed=$((base + 16 * i + k))
        name="${letter}_${fam}_${seed}_${width}x${height}"
        dir="$out/$split/$name"
        if [ -f "$dir/SHA256SUMS" ]; then
            if [ "$check" = 1 ] && ! (cd "$dir" && sha256sum --quiet -c SHA256SUMS); then
                echo "render_cache.sh: checksum mismatch: $dir (delete it to re-render)" >&2
                bad=$((bad + 1))
            fi
            skipped=$((skipped + 1))
            continue
        fi
        [ "$check" = 0 ] || { echo "missing: $dir"; continue; }
        if [ "$fam" = anim ]; then frames=2; else frames=1; fi
        if [ "$dry" = 1 ]; then
            echo "render $split $name (spp $spp, target $ref, $frames frame(s))"
            continue
        fi
        rm -rf "$dir.partial" "$dir"
        echo "== [$n/$count] $split $name" >&2
        t0=$(date +%s)
        if nice -n "$niceness" "$blender" -b --factory-startup --python "$script" -- \
                --family "$fam" --seed "$seed" --width "$width" --height "$height" \
                --spp "$spp" --ref-spp "$ref" --frames "$frames" --threads "$threads" --style "$style" \
                --out "$dir.partial" </dev/null \
            && [ -f "$dir.partial/meta.json" ] \
            && (cd "$dir.partial" && sha256sum -- *.exr meta.json > SHA256SUMS.tmp && mv SHA256SUMS.tmp SHA256SUMS)
        then
            mv "$dir.partial" "$dir"
            secs=$(( $(date +%s) - t0 ))
            sums=$(sha256sum "$dir/SHA256SUMS" | cut -d' ' -f1)
            printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\n' "$split" "$name" "$fam" "$seed" \
                "$spp" "$ref" "$frames" "$secs" "$sums" >> "$manifest"
            rendered=$((rendered + 1))
        else
            echo "render_cache.sh: FAILED: $split $name" >&2
            rm -rf "$dir.partial"
            failed=$((failed + 1))
        fi
    done
    i=$((i + 1))
done
if [ "$check" = 1 ]; then
    echo "render_cache.sh: $split: complete $skipped, bad checksums $bad" >&2
else
    echo "render_cache.sh: $split: rendered $rendered, complete before $skipped, failed $failed" >&2
fi
[ "$failed" -eq 0 ] && [ "$bad" -eq 0 ]
