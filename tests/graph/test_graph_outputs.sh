#!/usr/bin/env bash
# Graph outputs: frame patterns ('####', '%04d', '%d') and outputs that would
# collide (two writes on one file, every frame into one file) refused before
# any work. Usage: test_graph_outputs.sh EDGEWISE_BIN SAMPLE_DIR
set -u
EW="$1"; SAMPLE=$(cd "$2" && pwd)
. "$(dirname "$0")/../lib/harness.sh"
expect_graph() { # NAME EXIT STDERR_SUBSTRING GRAPH_FILE
  "$EW" graph run "$4" -q >"$T/so" 2>"$T/err"; local got=$?
  if [ "$got" -ne "$2" ]; then bad "$1 (exit $got, expected $2)"; return; fi
  if [ -n "$3" ] && ! grep -qF -- "$3" "$T/err"; then bad "$1 (stderr lacks '$3')"; return; fi
  ok "$1"
}

mkdir -p "$T/seq" "$T/out"
for f in 1 2 3; do cp "$SAMPLE/cornell/f0001_spp0004.exr" "$T/seq/render_000$f.exr"; done
graph() { # FILE READ_PATH WRITE1 [WRITE2]
  local second=""
  [ -n "${4:-}" ] && second=", \"w2\": {\"type\": \"write\", \"params\": {\"path\": \"$4\"}, \"inputs\": {\"image\": \"r.color\"}}"
  cat >"$1" <<EOF
{"edgewise_graph": 1, "nodes": {
  "r": {"type": "read", "params": {"path": "$2"}},
  "w": {"type": "write", "params": {"path": "$3"}, "inputs": {"image": "r.color"}}$second}}
EOF
}

# printf-style patterns read and write frame sequences
graph "$T/pct.json" "$T/seq/render_%04d.exr" "$T/out/pct_%04d.exr"
expect_graph percent_pattern_runs 0 "" "$T/pct.json"
[ -f "$T/out/pct_0001.exr" ] && [ -f "$T/out/pct_0003.exr" ] && [ ! -e "$T/out/pct_%04d.exr" ] \
  && ok percent_pattern_one_file_a_frame || bad "percent_pattern_one_file_a_frame ($(ls "$T/out"))"
graph "$T/d.json" "$T/seq/render_####.exr" "$T/out/plain_%d.exr"
expect_graph percent_d_runs 0 "" "$T/d.json"
[ -f "$T/out/plain_1.exr" ] && [ -f "$T/out/plain_3.exr" ] && ok percent_d_unpadded || bad percent_d_unpadded
graph "$T/hash.json" "$T/seq/render_####.exr" "$T/out/hash_####.exr"
expect_graph hash_pattern_runs 0 "" "$T/hash.json"
[ -f "$T/out/hash_0002.exr" ] && ok hash_pattern_one_file_a_frame || bad hash_pattern_one_file_a_frame

# collisions, refused before anything is written
rm -rf "$T/out"; mkdir -p "$T/out"
graph "$T/same.json" "$T/seq/render_0001.exr" "$T/out/a.exr" "$T/out/a.exr"
expect_graph two_writes_one_file 1 "nodes 'w' and 'w2' would both write" "$T/same.json"
graph "$T/spell.json" "$T/seq/render_0001.exr" "$T/out/a.exr" "$T/out/../out/./a.exr"
expect_graph two_spellings_one_file 1 "would both write" "$T/spell.json"
graph "$T/seq1.json" "$T/seq/render_####.exr" "$T/out/every.exr"
expect_graph every_frame_one_file 1 "frames 1 and 2 would both be written to" "$T/seq1.json"
graph "$T/seq2.json" "$T/seq/render_####.exr" "$T/out/x_####.exr" "$T/out/x_%04d.exr"
expect_graph two_patterns_same_files 1 "would both write" "$T/seq2.json"
[ -z "$(ls -A "$T/out")" ] && ok collisions_write_nothing || bad "collisions_write_nothing ($(ls "$T/out"))"
"$EW" graph check "$T/same.json" >/dev/null 2>&1 && bad check_finds_collisions || ok check_finds_collisions

# a write that keeps the source: every pass, alpha and the header, like the CLI
IN="$SAMPLE/cornell/f0001_spp0004.exr"
cat >"$T/keep.json" <<EOF
{"edgewise_graph": 1, "nodes": {
  "r": {"type": "read", "params": {"path": "$IN"}},
  "d": {"type": "denoise", "params": {"method": "bgrid"},
        "inputs": {"color": "r.noisy", "albedo": "r.albedo", "normal": "r.normal", "depth": "r.depth"}},
  "w": {"type": "write", "params": {"path": "$T/keep.exr", "keep_source": true, "original": "Noisy Image"},
        "inputs": {"image": "d"}}}}
EOF
expect_graph keep_source_runs 0 "" "$T/keep.json"
channels() { "$EW" info "$1" | sed -n 's/^channels: //p' | tr ',' '\n' | sed 's/^ //' | sort; }
channels "$IN" >"$T/in.ch"; channels "$T/keep.exr" >"$T/keep.ch"
"$EW" info "$T/keep.exr" >"$T/keep.info"
missing=$(comm -23 "$T/in.ch" "$T/keep.ch" | tr '\n' ' ')
[ -z "$missing" ] && ok keep_source_keeps_every_channel || bad "keep_source_keeps_every_channel (missing: $missing)"
grep -q "ViewLayer.Combined.A" "$T/keep.ch" && ok keep_source_keeps_alpha || bad keep_source_keeps_alpha
grep -q "ViewLayer.Noisy Image.R" "$T/keep.ch" && ok keep_source_keeps_original || bad keep_source_keeps_original
grep -q "samples: 4" "$T/keep.info" && ok keep_source_keeps_header || bad keep_source_keeps_header
"$EW" denoise "$IN" -o "$T/cli.exr" --method bgrid -q
[ "$("$EW" compare "$T/keep.exr" "$T/cli.exr" | sed -n 's/^PSNR \([0-9.inf]*\) dB.*/\1/p')" = inf ] \
  && ok keep_source_combined_is_the_result || bad keep_source_combined_is_the_result

finish
