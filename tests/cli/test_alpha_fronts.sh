#!/usr/bin/env bash
# Premultiplied RGBA through the filters as a user runs them: `edgewise
# filter`, `edgewise dof` and a graph's filter node blur alpha with the
# colour, so colour never ends above alpha (valid premultiplied colour), and
# a transparent/opaque checker gets soft alpha at its edges.
# Usage: test_alpha_fronts.sh EDGEWISE_BIN MAKE_FIXTURES_BIN
set -u
EW="$1"; FIX="$2"
. "$(dirname "$0")/../lib/harness.sh"
# check NAME FILE LAYER PASS: no colour above alpha, some soft alpha, all finite
check() {
  local got; got=$("$FIX" --premultiplied "$2" "$3" "$4")
  case "$got" in
    "over 0 soft 0 "*) bad "$1 (alpha not blurred: $got)" ;;
    "over 0 soft "*" nonfinite 0") ok "$1" ;;
    *) bad "$1 ($got)" ;;
  esac
}

"$FIX" "$T" || { echo "0 passed, 1 failed"; exit 1; }
IN="$T/alpha_checker.exr"
# the fixture itself: valid premultiplied, hard alpha
[ "$("$FIX" --premultiplied "$IN" ViewLayer Combined)" = "over 0 soft 0 nonfinite 0" ] \
  && ok fixture_is_premultiplied || bad fixture_is_premultiplied

for m in pyramid bilateral separable; do
  "$EW" filter "$IN" -o "$T/$m.exr" --method $m --radius 6 --sigma-range 100 -q 2>"$T/err" \
    && check "filter_${m}_keeps_premultiplied" "$T/$m.exr" ViewLayer Combined || bad "filter_${m}_runs"
done
"$EW" dof "$IN" -o "$T/dof.exr" --fstop 0.5 --focus-distance 0.5 -q 2>"$T/err" \
  && check dof_keeps_premultiplied "$T/dof.exr" ViewLayer Combined || bad dof_runs

# a graph: the RGBA pass (read's `image`) through a filter node into a plain RGBA EXR
cat >"$T/g.json" <<JSON
{"edgewise_graph": 1, "nodes": {
  "r": {"type": "read", "params": {"path": "$IN", "pass": "Combined"}},
  "f": {"type": "filter", "params": {"filter": "separable", "radius": 6, "sigma_range": 100}, "inputs": {"color": "r.image"}},
  "w": {"type": "write", "params": {"path": "$T/graph.exr"}, "inputs": {"image": "f"}}}}
JSON
"$EW" graph run "$T/g.json" -q 2>"$T/err" && check graph_filter_keeps_premultiplied "$T/graph.exr" "" "" \
  || bad graph_runs
# the graph's pixels are the CLI's
"$EW" compare "$T/graph.exr" "$T/separable.exr" 2>&1 | grep -q "^PSNR inf" && ok graph_equals_cli || bad graph_equals_cli

# An alpha of one value everywhere (bad_samples.exr: Combined.A = 1, some
# colour samples NaN or infinite) stays in the file and `filter`/`dof` run
# the method on RGB: the written colour and alpha are, value for value, a
# graph's, whose filter node gets the RGBA pass (the library's alpha path).
U="$T/bad_samples.exr"
same() { # NAME CLI_ARGS... -- GRAPH_FILTER_NODE_JSON
  local name="$1"; shift
  local args=(); while [ "$1" != "--" ]; do args+=("$1"); shift; done; shift
  cat >"$T/u.json" <<JSON
{"edgewise_graph": 1, "nodes": {
  "r": {"type": "read", "params": {"path": "$U", "pass": "Combined"}},
  "f": $1,
  "w": {"type": "write", "params": {"path": "$T/u_graph.exr", "pixel_type": "half"}, "inputs": {"image": "f"}}}}
JSON
  if "$EW" "${args[@]}" "$U" -o "$T/u_cli.exr" -q 2>"$T/err" && "$EW" graph run "$T/u.json" -q 2>"$T/err"; then
    local got; got=$("$FIX" --same "$T/u_cli.exr" ViewLayer Combined "$T/u_graph.exr" "" "" 2>&1)
    [ "$got" = same ] && ok "$name" || bad "$name ($got)"
  else
    bad "$name (runs)"
  fi
}
for m in pyramid bilateral separable atrous; do
  # the command guides the a-trous filter by the file's normal and depth
  guides=""; [ $m = atrous ] && guides=", \"normal\": \"r.normal\", \"depth\": \"r.depth\""
  same "uniform_alpha_filter_${m}_as_rgba" filter --method $m --radius 4 -- \
    "{\"type\": \"filter\", \"params\": {\"filter\": \"$m\", \"radius\": 4}, \"inputs\": {\"color\": \"r.image\"$guides}}"
done
same uniform_alpha_dof_as_rgba dof --fstop 0.5 --focus-distance 0.5 -- \
  "{\"type\": \"dof\", \"params\": {\"fstop\": 0.5, \"focus_distance\": 0.5}, \"inputs\": {\"color\": \"r.image\", \"depth\": \"r.depth\"}}"

finish
