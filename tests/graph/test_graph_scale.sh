#!/usr/bin/env bash
# Graph size and frame ranges: `graph check` of a long chain written in the
# worst order for a sweeping planner (each node after the one it feeds), and
# a frame range refused when a write has no frame pattern. The chain is large
# enough that a check quadratic in nodes runs for minutes (CTest's TIMEOUT
# stops it) while a linear one takes well under a second. Usage:
#   test_graph_scale.sh EDGEWISE_BIN SAMPLE_DIR
set -u
EW="$1"; SAMPLE=$(cd "$2" && pwd)
. "$(dirname "$0")/../lib/harness.sh"
cp "$SAMPLE/cornell/f0001_spp0004.exr" "$T/in.exr"

N=40000
awk -v n=$N 'BEGIN {
  printf "{\"edgewise_graph\": 1, \"nodes\": {\n";
  printf "\"w\": {\"type\": \"write\", \"params\": {\"path\": \"out.exr\"}, \"inputs\": {\"image\": \"a%d\"}},\n", n;
  for (i = n; i >= 2; i--)
    printf "\"a%d\": {\"type\": \"add\", \"params\": {\"value\": [0.001, 0, 0]}, \"inputs\": {\"a\": \"a%d\"}},\n", i, i - 1;
  printf "\"a1\": {\"type\": \"add\", \"params\": {\"value\": [0.001, 0, 0]}, \"inputs\": {\"a\": \"r.color\"}},\n";
  printf "\"r\": {\"type\": \"read\", \"params\": {\"path\": \"in.exr\"}}}}\n";
}' >"$T/chain.json"
start=$(date +%s.%N)
if "$EW" graph check "$T/chain.json" >"$T/out" 2>"$T/err"; then ok "chain_of_${N}_checks"; else bad "chain_of_${N}_checks"; fi
echo "     graph check of $N nodes: $(awk -v s="$start" -v e="$(date +%s.%N)" 'BEGIN{printf "%.2f", e - s}') s"

# a frame range over a write without a frame pattern
printf '%s' '{"edgewise_graph": 1, "nodes": {
  "r": {"type": "read", "params": {"path": "in.exr"}},
  "w": {"type": "write", "params": {"path": "same.exr"}, "inputs": {"image": "r.color"}}}}' >"$T/noframes.json"
"$EW" graph run "$T/noframes.json" --frames 0-1000000 >"$T/out" 2>"$T/err"; rc=$?
if [ "$rc" -ne 0 ] && grep -q "no frame pattern" "$T/err" && [ ! -e "$T/same.exr" ]; then ok frame_range_without_pattern_refused
else bad "frame_range_without_pattern_refused (exit $rc)"; fi
"$EW" graph run "$T/noframes.json" --frames 7 >"$T/out" 2>"$T/err" && [ -s "$T/same.exr" ] \
  && ok single_frame_without_pattern_runs || bad single_frame_without_pattern_runs

finish
