#!/usr/bin/env bash
# The render's sample count (Cycles' cycles.<layer>.samples) reaches "auto"
# in a graph as it does in the CLI: the same frame, the same choice. (The
# OFX side: tests/ofx, auto_takes_*_sample_count_from_the_source_clip.)
# Usage: test_samples.sh EDGEWISE_BIN SAMPLE_DIR
set -u
EW="$1"; SAMPLE=$(cd "$2" && pwd)
. "$(dirname "$0")/../lib/harness.sh"

# what "auto" picked: the CLI's line, the graph's summary
cli_choice() {
  "$EW" denoise "$1" -o "$T/cli.exr" 2>&1 | sed -n "s/^edgewise: layer 'ViewLayer': \(.*\) (Combined.*/\1/p"
}
graph_choice() { # FILE [middle node type]
  local src="r.noisy"
  if [ -n "${2:-}" ]; then
    src="m"
    middle=", \"m\": {\"type\": \"$2\", \"inputs\": {\"color\": \"r.noisy\"}}"
  else
    middle=""
  fi
  cat >"$T/g.json" <<EOF
{"edgewise_graph": 1, "nodes": {
  "r": {"type": "read", "params": {"path": "$1"}},
  "d": {"type": "denoise", "params": {"method": "auto"},
        "inputs": {"color": "$src", "albedo": "r.albedo", "normal": "r.normal", "depth": "r.depth"}},
  "w": {"type": "write", "params": {"path": "$T/graph.exr"}, "inputs": {"image": "d"}}$middle}}
EOF
  "$EW" graph run "$T/g.json" 2>/dev/null | sed -n 's/^frame 1: d: \(.*\); wrote.*/\1/p'
}

IN="$SAMPLE/cornell/f0001_spp0004.exr"
a=$(cli_choice "$IN"); b=$(graph_choice "$IN")
echo "     CLI: $a; graph: $b"
[ -n "$a" ] && [ "$a" = "$b" ] && ok "same_choice_cli_graph ($a)" || bad "same_choice_cli_graph (CLI '$a', graph '$b')"
case "$b" in *"4 spp"*) ok graph_uses_file_samples ;; *) bad "graph_uses_file_samples ($b)" ;; esac
# and the same pixels: the CLI holds the file's half albedo as halves for
# auto, the graph as floats
"$EW" compare "$T/cli.exr" "$T/graph.exr" 2>&1 | grep -q "^PSNR inf" && ok same_pixels_cli_graph || bad same_pixels_cli_graph

if command -v oiiotool >/dev/null; then
  # a count the noise estimate would not give: the choice must follow it
  oiiotool "$IN" --attrib:type=string cycles.ViewLayer.samples 1024 -o "$T/spp1024.exr"
  a=$(cli_choice "$T/spp1024.exr"); b=$(graph_choice "$T/spp1024.exr")
  [ -n "$a" ] && [ "$a" = "$b" ] && ok "same_choice_1024 ($a)" || bad "same_choice_1024 (CLI '$a', graph '$b')"
  case "$b" in *"1024 spp"*) ok graph_uses_1024 ;; *) bad "graph_uses_1024 ($b)" ;; esac
  # through another node: metadata travels with the pixels
  c=$(graph_choice "$T/spp1024.exr" outlier)
  [ "$c" = "$a" ] && ok "samples_through_a_filter ($c)" || bad "samples_through_a_filter ('$c', want '$a')"
  # an explicit parameter wins over the file
  sed -i 's/"method": "auto"}/"method": "auto", "samples": 2}/' "$T/g.json"
  c=$("$EW" graph run "$T/g.json" 2>/dev/null | sed -n 's/^frame 1: d: \(.*\); wrote.*/\1/p')
  case "$c" in *"2 spp"*) ok "parameter_overrides_file ($c)" ;; *) bad "parameter_overrides_file ($c)" ;; esac
else
  echo "skip: no oiiotool for the 1024-spp copy"
fi

finish
