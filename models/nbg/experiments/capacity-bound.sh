#!/bin/sh
# How far can the 1-spp recipe get on the held-out test scenes if it is
# allowed to see them? A diagnostic of the 1-spp target (+1.5 dB over bgrid
# on test), never a model to ship: both runs train on test scenes.
#
#   with-test: the 12 training scenes plus the 8 test scenes (--extra-train)
#   test-only: the 8 test scenes alone; train_nbg's split rule needs one
#              family of four for validation, so a_cornell_122 is linked twice
#              as training and the validation scene a_cornell_119 as its
#              validation; the ..._999 links are the split's "test" slots,
#              never read by training
#
# usage: capacity-bound.sh BUILD_DIR DATA_DIR OUT_DIR [ARCH] [STEPS]
set -eu
B=$1 D=$2 O=$3 ARCH=${4:-2layer-3grid} STEPS=${5:-3000}
TEST="a_cornell_122 b_glossy_118 c_glass_120 d_firefly_115 e_dof_116 f_motionblur_117 g_anim_123 h_hdri_121"
T="--seed 1 --batch 8 --patch 128 --lr 1e-3 --lr-final 1e-4 --clip 0.05 --val-every 100"
R="--arch $ARCH --spp 1 --rates 8:8,16:16,32:32 --steps $STEPS"
mkdir -p "$O/with-test-data" "$O/test-only-data"
for s in $TEST; do
    ln -sfn "$D/${s}_256x256" "$O/with-test-data/${s}_256x256"
    if [ "$s" = a_cornell_122 ]; then
        ln -sfn "$D/${s}_256x256" "$O/test-only-data/a_cornell_001_256x256"
        ln -sfn "$D/${s}_256x256" "$O/test-only-data/a_cornell_002_256x256"
        ln -sfn "$D/a_cornell_119_256x256" "$O/test-only-data/a_cornell_998_256x256"
    else
        ln -sfn "$D/${s}_256x256" "$O/test-only-data/${s}_256x256"
    fi
    ln -sfn "$D/${s}_256x256" "$O/test-only-data/${s%_*}_999_256x256"
done
# shellcheck disable=SC2086
nice "$B/bin/train_nbg" --data "$D" --extra-train "$O/with-test-data" $R $T --out "$O/$ARCH-with-test.ewm"
# shellcheck disable=SC2086
nice "$B/bin/train_nbg" --data "$O/test-only-data" $R $T --out "$O/$ARCH-test-only.ewm"
for m in with-test test-only; do
    echo "== $ARCH $m, on the test scenes at 1 spp:"
    "$B/bin/train_nbg" --data "$D" --eval "$O/$ARCH-$m.ewm" --split test --spp 1 > "$O/$ARCH-$m-test.csv"
done
