#!/usr/bin/env bash
# The trainers' command lines and checkpoints, on the committed 64x64 renders of
# the stability suite. Usage:
#   test_trainers.sh TRAIN_KPCN TRAIN_NBG STABILITY_DATA_DIR
# A run stopped by --stop-after and continued with --resume (on another thread
# count) must end with the bytes of an uninterrupted run's model: checkpoints
# hold the weights, the optimiser's moments and the step, and a step depends on
# nothing else. Prints "N passed, N failed" and exits non-zero on any failure.
set -u
KPCN="$1"; NBG="$2"; STAB="$3"
. "$(dirname "$0")/../lib/harness.sh"
EXPECT_ONE_LINE=0

# train_kpcn: render_cache.sh's layout (a folder of scene folders), validation apart
mkdir -p "$T/train" "$T/val" "$T/nbg"
for s in b_glossy_1 f_motionblur_1 j_texture_1; do ln -s "$STAB/${s}_64x64" "$T/train/${s}_64x64"; done
ln -s "$STAB/i_volume_1_64x64" "$T/val/i_volume_1_64x64"
K=(--arch kpcn-c4 --train "$T/train" --val "$T/val" --steps 6 --batch 2 --patch 32 --val-every 3)

"$KPCN" "${K[@]}" --out "$T/whole.ewm" --threads 1 >"$T/out" 2>"$T/err" && grep -q "^step      6" "$T/out" &&
  ok kpcn_trains || bad kpcn_trains
"$KPCN" "${K[@]}" --out "$T/split.ewm" --threads 2 --stop-after 4 >"$T/out" 2>"$T/err" &&
  grep -q "stopped at step 4" "$T/out" && [ -s "$T/split.ewm.ckpt" ] && ok kpcn_stop_after || bad kpcn_stop_after
"$KPCN" "${K[@]}" --out "$T/split.ewm" --threads 1 --resume >"$T/out" 2>"$T/err" &&
  grep -q "resumed from .* at step 4" "$T/out" && ok kpcn_resumes || bad kpcn_resumes
cmp -s "$T/whole.ewm" "$T/split.ewm" && ok kpcn_resumed_run_is_the_uninterrupted_one ||
  bad kpcn_resumed_run_is_the_uninterrupted_one
# the validation curve has each step once
[ "$(cut -d, -f1 "$T/split.ewm.csv" | tr '\n' ' ')" = "step 0 3 6 " ] && ok kpcn_curve_rows ||
  { bad kpcn_curve_rows; cat "$T/split.ewm.csv"; }
left=$(ls "$T" | grep -Ev '^(train|val|nbg|out|err|[a-z]+\.ewm(\.ckpt|\.csv|\.scenes)?)$')
[ -z "$left" ] && ok kpcn_no_temporaries_left || bad "kpcn_no_temporaries_left: $left"

# a checkpoint of another architecture, or one that cannot be read, stops the run
# instead of training from scratch over it
expect kpcn_checkpoint_of_another_arch 1 "not one of this architecture's" -- \
  "$KPCN" --arch kpcn-c8 --train "$T/train" --val "$T/val" --steps 2 --batch 1 --patch 32 \
  --out "$T/other.ewm" --checkpoint "$T/split.ewm.ckpt" --resume
mkdir "$T/dir.ckpt"
expect kpcn_unreadable_checkpoint 1 "exists but cannot be read" -- \
  "$KPCN" "${K[@]}" --out "$T/d.ewm" --checkpoint "$T/dir.ckpt" --resume
[ -d "$T/dir.ckpt" ] && ok kpcn_unreadable_checkpoint_kept || bad kpcn_unreadable_checkpoint_kept

# option values are numbers in range, whole
expect kpcn_bad_steps 2 "--steps takes a whole number" -- "$KPCN" "${K[@]}" --out "$T/x.ewm" --steps 12abc
expect kpcn_bad_lr 2 "--lr takes a number" -- "$KPCN" "${K[@]}" --out "$T/x.ewm" --lr fast
expect kpcn_missing_value 2 "--out needs a value" -- "$KPCN" "${K[@]}" --out
expect kpcn_unknown_option 2 "unknown option '--frobnicate'" -- "$KPCN" "${K[@]}" --out "$T/x.ewm" --frobnicate
expect kpcn_stray_argument 2 "unexpected argument 'extra'" -- "$KPCN" "${K[@]}" --out "$T/x.ewm" extra
expect kpcn_eval_needs_scenes 2 "--eval needs scenes" -- "$KPCN" --eval "$T/whole.ewm"
# scenes past the memory budget stop the run before it trains, with what to do
expect kpcn_scenes_past_the_memory_budget 2 "would take the scenes held past" -- \
  "$KPCN" "${K[@]}" --out "$T/x.ewm" --max-memory-gb 0.001
[ ! -e "$T/x.ewm" ] && ok kpcn_usage_errors_write_nothing || bad kpcn_usage_errors_write_nothing
"$KPCN" --help | grep -q -- "--stop-after" && ok kpcn_help || bad kpcn_help

# train_nbg: one folder of scenes split by seed (the same render as four scenes)
for s in 1 2 3 4; do ln -s "$STAB/i_volume_1_64x64" "$T/nbg/i_volume_${s}_64x64"; done
N=(--data "$T/nbg" --arch 2layer-1grid --steps 4 --batch 2 --patch 32 --val-every 2)
"$NBG" "${N[@]}" --out "$T/nwhole.ewm" --threads 1 >"$T/out" 2>"$T/err" && ok nbg_trains || bad nbg_trains
"$NBG" "${N[@]}" --out "$T/nsplit.ewm" --threads 2 --stop-after 2 >"$T/out" 2>"$T/err" &&
  grep -q "stopped at step 2" "$T/out" && ok nbg_stop_after || bad nbg_stop_after
"$NBG" "${N[@]}" --out "$T/nsplit.ewm" --threads 1 --resume >"$T/out" 2>"$T/err" &&
  grep -q "resumed from .* at step 2" "$T/out" && ok nbg_resumes || bad nbg_resumes
cmp -s "$T/nwhole.ewm" "$T/nsplit.ewm" && ok nbg_resumed_run_is_the_uninterrupted_one ||
  bad nbg_resumed_run_is_the_uninterrupted_one
expect nbg_checkpoint_of_another_arch 1 "not one of this architecture's" -- \
  "$NBG" --data "$T/nbg" --arch 2layer-3grid --steps 2 --batch 1 --patch 32 --out "$T/n3.ewm" \
  --checkpoint "$T/nsplit.ewm.ckpt" --resume
expect nbg_bad_size 2 "--size WxH" -- "$NBG" --bench --size 640x480x3
expect nbg_bad_clip 2 "--clip takes a number" -- "$NBG" "${N[@]}" --out "$T/y.ewm" --clip -1

finish
