#!/usr/bin/env bash
# 8-bit output (PNG/JPEG) of the CLI is a display image: the same pixels as
# the graph's `display` node with its defaults, not linear light clipped.
# Usage: test_display_output.sh EDGEWISE_BIN MAKE_FIXTURES_BIN
set -u
EW="$1"; FIX="$2"
. "$(dirname "$0")/../lib/harness.sh"
psnr() { "$EW" compare "$1" "$2" 2>&1 | sed -n 's/^PSNR \([0-9.inf]*\) dB.*/\1/p'; }

"$FIX" "$T" || { echo "0 passed, 1 failed"; exit 1; }
IN="$T/two_layers.exr"

"$EW" denoise --help | grep -q -- "--view NAME" && "$EW" denoise --help | grep -q "display/view transform" \
  && ok help_says_display || bad help_says_display
for c in filter dof; do
  "$EW" $c --help | grep -q -- "--raw" && ok "${c}_help_has_raw" || bad "${c}_help_has_raw"
done

# the CLI's PNG and the graph's read -> denoise -> display -> write PNG
"$EW" denoise "$IN" -o "$T/cli.png" --method bgrid-color 2>"$T/err" && ok denoise_png || bad denoise_png
grep -q "display '" "$T/err" && ok says_which_transform || bad says_which_transform
cat >"$T/g.json" <<EOF
{"edgewise_graph": 1, "nodes": {
  "r": {"type": "read", "params": {"path": "$IN"}},
  "d": {"type": "denoise", "params": {"method": "bgrid"},
        "inputs": {"color": "r.noisy"}},
  "v": {"type": "display", "inputs": {"color": "d"}},
  "w": {"type": "write", "params": {"path": "$T/graph.png"}, "inputs": {"image": "v"}}}}
EOF
"$EW" graph run "$T/g.json" -q 2>"$T/err" || bad graph_runs
[ "$(psnr "$T/cli.png" "$T/graph.png")" = inf ] && ok cli_png_equals_graph_display \
  || bad "cli_png_equals_graph_display (PSNR $(psnr "$T/cli.png" "$T/graph.png"))"

# --raw: the linear values clipped (what the PNG used to be), darker
"$EW" denoise "$IN" -o "$T/raw.png" --method bgrid-color --raw -q && ok raw_runs || bad raw_runs
[ "$(psnr "$T/cli.png" "$T/raw.png")" != inf ] && ok raw_differs || bad raw_differs
/usr/bin/python3 - "$T" <<'EOF' 2>"$T/err" && ok display_is_brighter_than_linear || bad display_is_brighter_than_linear
import subprocess, sys, os
# mean 8-bit value through oiiotool's stats when present, else skip the check
t = sys.argv[1]
def mean(p):
    out = subprocess.run(["oiiotool", "--stats", p], capture_output=True, text=True).stdout
    line = [l for l in out.splitlines() if "Avg:" in l][0]
    return sum(float(v) for v in line.split("Avg:")[1].split()[:3]) / 3
if subprocess.run(["which", "oiiotool"], capture_output=True).returncode == 0:
    assert mean(os.path.join(t, "cli.png")) > 1.2 * mean(os.path.join(t, "raw.png"))
EOF
"$EW" denoise "$IN" -o "$T/rawview.png" --method bgrid-color --view Raw -q && [ "$(psnr "$T/rawview.png" "$T/raw.png")" = inf ] \
  && ok view_raw_is_raw || bad view_raw_is_raw

# filter and dof write display PNGs too; EXR and float TIFF stay linear
"$EW" filter "$IN" -o "$T/f.png" -q && "$EW" filter "$IN" -o "$T/fr.png" --raw -q \
  && [ "$(psnr "$T/f.png" "$T/fr.png")" != inf ] && ok filter_png_display || bad filter_png_display
"$EW" dof "$IN" -o "$T/o.png" --layer ViewLayer -q && "$EW" dof "$IN" -o "$T/or.png" --layer ViewLayer --raw -q \
  && [ "$(psnr "$T/o.png" "$T/or.png")" != inf ] && ok dof_png_display || bad dof_png_display
"$EW" denoise "$IN" -o "$T/a.tif" --method bgrid-color -q && "$EW" denoise "$IN" -o "$T/b.tif" --method bgrid-color --raw -q \
  && [ "$(psnr "$T/a.tif" "$T/b.tif")" = inf ] && ok float_tiff_linear || bad float_tiff_linear

# an 8-bit input is display-encoded already: written as it is
"$EW" denoise "$T/raw.png" -o "$T/p1.png" --method bgrid-color -q && "$EW" denoise "$T/raw.png" -o "$T/p2.png" --method bgrid-color --raw -q \
  && [ "$(psnr "$T/p1.png" "$T/p2.png")" = inf ] && ok png_input_not_transformed_twice || bad png_input_not_transformed_twice

# names are checked before any work
"$EW" denoise "$IN" -o "$T/x.png" --view Nope >"$T/out" 2>"$T/err"; rc=$?
[ $rc -eq 2 ] && grep -q "unknown view 'Nope'" "$T/err" && [ ! -e "$T/x.png" ] && ok unknown_view_refused \
  || bad "unknown_view_refused (exit $rc)"
"$EW" denoise "$IN" -o "$T/x.png" --display Nope >"$T/out" 2>"$T/err"; rc=$?
[ $rc -eq 2 ] && grep -q "unknown display 'Nope'" "$T/err" && ok unknown_display_refused || bad "unknown_display_refused (exit $rc)"
"$EW" denoise "$IN" -o "$T/x.png" --raw --view Raw >"$T/out" 2>"$T/err"; rc=$?
[ $rc -eq 2 ] && ok raw_with_view_refused || bad "raw_with_view_refused (exit $rc)"

finish
