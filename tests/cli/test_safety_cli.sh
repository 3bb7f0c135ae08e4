#!/usr/bin/env bash
# Nothing lost, nothing read unbounded: what `edgewise` does to files other
# than its output (report paths, references, symlinks), on signals and full
# disks, and with headers that declare more memory than allowed. Usage:
#   test_safety_cli.sh EDGEWISE_BIN MAKE_FIXTURES_BIN
# Prints "N passed, N failed" and exits non-zero on any failure.
set -u
EW="$1"; FIX="$2"
. "$(dirname "$0")/../lib/harness.sh"
EXPECT_TIMEOUT=120 # a blocking open fails, not hangs

same() { if cmp -s "$1" "$2"; then ok "$3"; else bad "$3"; fi; }

"$FIX" "$T" || { echo "0 passed, 1 failed"; exit 1; }
IN="$T/two_layers.exr"

# ---- graph run --report follows the rules of image outputs
cd "$T" || exit 1
cp "$IN" in.exr; cp in.exr in.orig
printf '%s' '{"edgewise_graph": 1, "nodes": {
  "r": {"type": "read", "params": {"path": "in.exr"}},
  "w": {"type": "write", "params": {"path": "out.exr"}, "inputs": {"image": "r.color"}}}}' >g.json
cp g.json g.orig
expect report_over_input 2 "an input of the graph (node 'r'" -- "$EW" graph run g.json --report in.exr
same in.exr in.orig report_over_input_leaves_input
expect report_over_input_other_spelling 2 "refusing to write the report" -- "$EW" graph run g.json --report "$T/./in.exr"
expect report_over_graph 2 "over the graph file" -- "$EW" graph run g.json --report g.json
same g.json g.orig report_over_graph_leaves_graph
expect report_over_output 2 "an output of the graph (node 'w'" -- "$EW" graph run g.json --report out.exr
[ ! -e out.exr ] && ok report_refused_before_running || bad report_refused_before_running
expect report_written 0 "" -- "$EW" graph run g.json --report rep.json
grep -q '"frames"' rep.json && ok report_is_json || bad report_is_json
# a full disk (the file size limit) keeps the old report, leaves no empty one
cp rep.json rep.orig
( ulimit -f 0; trap '' XFSZ; exec "$EW" graph run g.json --report rep.json -q 2>/dev/null ); rc=$?
[ "$rc" = 1 ] && ok report_full_disk_fails || bad "report_full_disk_fails (exit $rc)"
same rep.json rep.orig report_full_disk_keeps_old
( ulimit -f 0; trap '' XFSZ; "$EW" graph run g.json --report new_rep.json >/dev/null 2>&1 )
[ ! -e new_rep.json ] && ok report_full_disk_no_empty_file || bad report_full_disk_no_empty_file
no_temps "$T" report_full_disk_no_temporary '\.tmp-'
mkfifo fifo.json
expect report_to_fifo_refused 1 "not a regular file" -- "$EW" graph run g.json --report fifo.json
rm -f fifo.json

# ---- the output is never the reference it is scored against
cp "$IN" ref.exr; cp ref.exr ref.orig
expect denoise_output_is_reference 1 "over the reference" -- "$EW" denoise "$IN" -o ref.exr --reference ref.exr
same ref.exr ref.orig denoise_reference_untouched
ln -s ref.exr ref_link.exr
expect denoise_output_is_reference_via_link 1 "over the reference" -- "$EW" denoise "$IN" -o ref_link.exr --reference ref.exr
expect filter_output_is_reference 1 "over the reference" -- "$EW" filter "$IN" -o ref.exr --reference ref.exr
expect dof_output_is_reference 1 "over the reference" -- "$EW" dof "$IN" -o ref.exr --reference ref.exr
same ref.exr ref.orig reference_untouched

# ---- a symlink at the output path is replaced by the new file; its target stays
echo "target" >target.exr
ln -s target.exr out_link.exr
expect write_over_symlink 0 "" -- "$EW" denoise "$IN" -o out_link.exr -q
[ -f out_link.exr ] && [ ! -L out_link.exr ] && ok symlink_replaced_by_file || bad symlink_replaced_by_file
grep -q '^target$' target.exr && ok symlink_target_untouched || bad symlink_target_untouched

# ---- long output names: the temporary's longer name must not fail the write
long=$(printf 'n%.0s' $(seq 1 246)).exr # 250 bytes
expect long_output_name 0 "" -- "$EW" denoise "$IN" -o "$long" -q
[ -s "$long" ] && ok long_output_written || bad long_output_written
no_temps "$T" long_name_no_temporary '\.tmp-'

# ---- read limits from the header, before any pixel memory
expect max_memory_refuses 1 "memory limit" -- "$EW" info "$IN" --max-memory 64K
grep -qF -- "--max-memory" "$T/err" && ok max_memory_says_how_to_raise || bad max_memory_says_how_to_raise
expect max_memory_allows 0 "" -- "$EW" info "$IN" --max-memory 64M
expect max_memory_bad_value 2 "--max-memory expects" -- "$EW" info "$IN" --max-memory lots
expect max_pixels_refuses 1 "above the limit of 1000" -- "$EW" --max-pixels 1000 info "$IN"
grep -qF -- "--max-pixels" "$T/err" && ok max_pixels_says_how_to_raise || bad max_pixels_says_how_to_raise
expect max_pixels_range 2 "--max-pixels expects" -- "$EW" info "$IN" --max-pixels 0

# denoise: the file, the command's buffers and the method's own memory (the
# library's estimate) against the limit from the header, before reading: a
# file that fits alone but not with kpcn's working memory is refused, saying
# what each part needs; nothing is written; with room enough it runs
expect method_memory_refused 1 "kpcn's working memory" -- "$EW" denoise "$IN" -o "$T/mem.exr" --method kpcn --layer ViewLayer --max-memory 2M
grep -qF "Nothing was read" "$T/err" && grep -qF -- "--max-memory" "$T/err" \
  && ok method_memory_says_why_and_how || bad method_memory_says_why_and_how
[ -e "$T/mem.exr" ] && bad method_memory_writes_nothing || ok method_memory_writes_nothing
expect method_memory_bgrid_fits 0 "" -- "$EW" denoise "$IN" -o "$T/mem.exr" --method bgrid --layer ViewLayer --max-memory 2M -q
expect method_memory_kpcn_fits 0 "" -- "$EW" denoise "$IN" -o "$T/mem2.exr" --method kpcn --layer ViewLayer --max-memory 8M -q

# A header whose data window claims 16384x16384 over a file of a few KB:
# refused from the header (at 1 GiB), not after gigabytes are allocated.
if command -v python3 >/dev/null; then
  python3 - "$IN" bomb.exr <<'EOF'
import struct, sys
b = bytearray(open(sys.argv[1], "rb").read())
key = b"dataWindow\x00box2i\x00"
i = b.index(key) + len(key) + 4
b[i:i + 16] = struct.pack("<4i", 0, 0, 16383, 16383)
open(sys.argv[2], "wb").write(b)
EOF
  "$EW" info bomb.exr --max-memory 1G >"$T/out" 2>"$T/err"; rc=$?
  if [ "$rc" = 1 ] && grep -q "memory limit" "$T/err"; then ok header_bomb_refused_from_header
  else bad "header_bomb_refused_from_header (exit $rc)"; fi
fi

# ---- multi-part EXRs: a part of another size is refused with the reason
if command -v oiiotool >/dev/null; then
  oiiotool --create 32x16 3 -o small.exr >/dev/null 2>&1
  oiiotool "$IN" small.exr --siappend -o parts.exr >/dev/null 2>&1
  if [ -s parts.exr ]; then
    expect multipart_other_size 1 "part 2" -- "$EW" info parts.exr
    grep -q "32x16" "$T/err" && ok multipart_names_the_size || bad multipart_names_the_size
  fi
  # beauty in part 2, part 1 a data pass of the same size: found
  oiiotool --create 64x48 1 --chnames Z -o depth.exr >/dev/null 2>&1
  oiiotool depth.exr "$T/no_albedo.exr" --siappend -o beauty2.exr >/dev/null 2>&1
  if [ -s beauty2.exr ]; then expect multipart_beauty_in_part_2 0 "" -- "$EW" denoise beauty2.exr -o b2out.exr -q; fi
fi

# ---- SIGTERM / SIGINT during a write: the temporary goes, exit 128+n
if command -v oiiotool >/dev/null; then
  oiiotool --pattern noise 1536x1536 12 -d float -o big.exr >/dev/null 2>&1
  for sig in TERM INT; do
    mkdir -p "sig$sig"; rm -f "sig$sig"/*
    # env restores the default action: sh starts a background job with SIGINT
    # ignored, and the program keeps an ignored signal ignored (as nohup wants)
    env --default-signal="$sig" "$EW" filter big.exr -o "sig$sig/out.exr" --method bilateral --float -q >/dev/null 2>&1 &
    pid=$!
    caught=0
    # until the write starts, however long the filter takes (minutes under ASan)
    while kill -0 "$pid" 2>/dev/null; do
      if ls -A "sig$sig" | grep -q '\.tmp-'; then kill -s "$sig" "$pid"; caught=1; break; fi
      sleep 0.01
    done
    wait "$pid"; rc=$?
    if [ "$caught" = 1 ]; then
      want=$((128 + $(kill -l "$sig")))
      [ "$rc" = "$want" ] && ok "sig${sig}_exit_$want" || bad "sig${sig}_exit_$want (exit $rc)"
      no_temps "sig$sig" "sig${sig}_removes_temporary" '\.tmp-'
      [ ! -e "sig$sig/out.exr" ] && ok "sig${sig}_no_partial_output" || bad "sig${sig}_no_partial_output"
    else
      bad "sig${sig}_caught_a_temporary (exit $rc: the write of ~100 MB ended before a temporary was seen)"
    fi
  done
fi

# ---- outputs that cannot be written are refused before the input is read
expect output_without_extension 1 "no file extension" -- "$EW" denoise nope.exr -o noext
expect output_device 1 "no file extension" -- "$EW" filter nope.exr -o /dev/null
expect output_empty 1 "-o needs a file name" -- "$EW" dof nope.exr -o ''
expect filter_missing_input_once 1 "no such file" -- "$EW" filter nope.exr -o x.exr
[ "$(grep -o "cannot read" "$T/err" | wc -l)" = 1 ] && ok filter_error_not_repeated || bad filter_error_not_repeated
mkfifo model.fifo
expect model_fifo_refused 1 "not a regular file" -- "$EW" denoise "$IN" -o m.exr --model model.fifo
expect graph_fifo_refused 1 "not a regular file" -- "$EW" graph run model.fifo
rm -f model.fifo

# ---- metadata and boundaries
if command -v oiiotool >/dev/null; then
  oiiotool "$IN" --sattrib cycles.ViewLayer.samples 99999999999 -o manysamples.exr >/dev/null 2>&1
  expect samples_past_int 0 "" -- "$EW" denoise manysamples.exr -o many_out.exr
  oiiotool "$IN" --sattrib cycles.ViewLayer.samples 16777216 -o maxsamples.exr >/dev/null 2>&1
  expect samples_blender_max 0 "" -- "$EW" denoise maxsamples.exr -o max_out.exr
fi
# the documented minimum f-stop, given as JSON's double 0.1
printf '%s' '{"edgewise_graph": 1, "nodes": {
  "r": {"type": "read", "params": {"path": "in.exr", "layer": "ViewLayer"}},
  "d": {"type": "dof", "params": {"fstop": 0.1}, "inputs": {"color": "r.color", "depth": "r.depth"}},
  "w": {"type": "write", "params": {"path": "dof_out.exr"}, "inputs": {"image": "d"}}}}' >fstop.json
"$EW" graph check fstop.json >"$T/out" 2>"$T/err"
if grep -q "outside" "$T/err"; then bad fstop_minimum_accepted; else ok fstop_minimum_accepted; fi
expect fstop_minimum_by_set 0 "" -- "$EW" graph check fstop.json --set d.fstop=0.1

finish
