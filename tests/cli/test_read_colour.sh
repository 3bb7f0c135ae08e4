#!/usr/bin/env bash
# Which colour each command reads from a file `denoise` wrote (Combined = the
# denoised image, Noisy Image = the original): only a denoiser reads Noisy
# Image; compare, info, filter, dof and the graph's read.color read Combined.
# Usage: test_read_colour.sh EDGEWISE_BIN MAKE_FIXTURES_BIN
set -u
EW="$1"; FIX="$2"
. "$(dirname "$0")/../lib/harness.sh"

"$FIX" "$T" || { echo "0 passed, 1 failed"; exit 1; }

# PSNR of pass $2 of file $1 against pass $4 of file $3, read by name through
# a graph (independent of which colour a command prefers); "inf" when equal.
psnr_of_passes() {
  cat >"$T/g.json" <<EOF
{"edgewise_graph": 1, "nodes": {
  "a": {"type": "read", "params": {"path": "$1", "layer": "ViewLayer", "pass": "$2"}},
  "b": {"type": "read", "params": {"path": "$3", "layer": "ViewLayer", "pass": "$4"}},
  "ca": {"type": "shuffle", "params": {"channels": "rgb"}, "inputs": {"image": "a.image"}},
  "cb": {"type": "shuffle", "params": {"channels": "rgb"}, "inputs": {"image": "b.image"}},
  "m": {"type": "metrics", "inputs": {"image": "ca", "reference": "cb"}}}}
EOF
  "$EW" graph run "$T/g.json" -q --report "$T/r.json" >/dev/null 2>&1 || { echo error; return; }
  python3 -c "import json,sys; p=json.load(open(sys.argv[1]))['frames'][0]['metrics']['m']['psnr']; print('inf' if p is None else '%.2f' % p)" "$T/r.json"
}

IN="$T/two_layers.exr"
"$EW" denoise "$IN" -o "$T/d.exr" --method bgrid-color --reference "$IN" >"$T/dn" 2>/dev/null || bad denoise_runs
want=$(sed -n 's/.*output PSNR \([0-9.]*\) dB.*/\1/p' "$T/dn")
[ -n "$want" ] && ok denoise_reports_output_psnr || bad denoise_reports_output_psnr
[ "$(psnr_of_passes "$T/d.exr" "Noisy Image" "$IN" Combined)" = inf ] && ok denoise_keeps_noisy_image \
  || bad denoise_keeps_noisy_image

# compare scores the denoised image, the number denoise printed
got=$("$EW" compare "$T/d.exr" "$IN" | sed -n 's/^PSNR \([0-9.inf]*\) dB.*/\1/p')
[ "$got" = "$want" ] && ok "compare_reads_combined ($got dB)" || bad "compare_reads_combined (got '$got', denoise said '$want')"

# info names the colour the file shows, and what denoise would read
"$EW" info "$T/d.exr" >"$T/info"
grep -q "layer 'ViewLayer': colour 'Combined' (denoise reads 'Noisy Image')" "$T/info" && ok info_names_combined \
  || { bad info_names_combined; cat "$T/info"; }

# filter and dof work on Combined and leave the noisy original alone
"$EW" filter "$T/d.exr" -o "$T/f.exr" --layer ViewLayer --radius 4 -q || bad filter_runs
[ "$(psnr_of_passes "$T/f.exr" "Noisy Image" "$T/d.exr" "Noisy Image")" = inf ] && ok filter_leaves_noisy_image \
  || bad filter_leaves_noisy_image
[ "$(psnr_of_passes "$T/f.exr" Combined "$T/d.exr" Combined)" != inf ] && ok filter_filters_combined \
  || bad filter_filters_combined
"$EW" dof "$T/d.exr" -o "$T/o.exr" --layer ViewLayer --focus-distance 1 --fstop 1 --radius 8 -q || bad dof_runs
[ "$(psnr_of_passes "$T/o.exr" "Noisy Image" "$T/d.exr" "Noisy Image")" = inf ] && ok dof_leaves_noisy_image \
  || bad dof_leaves_noisy_image
[ "$(psnr_of_passes "$T/o.exr" Combined "$T/d.exr" Combined)" != inf ] && ok dof_blurs_combined \
  || bad dof_blurs_combined

# the graph's read.color is Combined; read.noisy is what a denoiser takes
cat >"$T/g2.json" <<EOF
{"edgewise_graph": 1, "nodes": {
  "r": {"type": "read", "params": {"path": "$T/d.exr", "layer": "ViewLayer"}},
  "c": {"type": "read", "params": {"path": "$T/d.exr", "layer": "ViewLayer", "pass": "Combined"}},
  "n": {"type": "read", "params": {"path": "$T/d.exr", "layer": "ViewLayer", "pass": "Noisy Image"}},
  "cc": {"type": "shuffle", "params": {"channels": "rgb"}, "inputs": {"image": "c.image"}},
  "nn": {"type": "shuffle", "params": {"channels": "rgb"}, "inputs": {"image": "n.image"}},
  "mc": {"type": "metrics", "inputs": {"image": "r.color", "reference": "cc"}},
  "mn": {"type": "metrics", "inputs": {"image": "r.noisy", "reference": "nn"}}}}
EOF
if "$EW" graph run "$T/g2.json" -q --report "$T/r2.json" 2>"$T/err"; then
  python3 - "$T/r2.json" <<'EOF' && ok graph_read_color_is_combined_noisy_is_noisy || bad graph_read_color_is_combined_noisy_is_noisy
import json, sys
m = json.load(open(sys.argv[1]))['frames'][0]['metrics']
assert m['mc']['psnr'] is None, m
assert m['mn']['psnr'] is None, m
EOF
else
  bad "graph_read_runs: $(cat "$T/err")"
fi

finish
