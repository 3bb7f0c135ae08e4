#!/bin/sh
# tools/blender's data generator in its simple style: every family of the style renders
# (32x32, 1 spp, a 4-spp reference) with its passes and meta.json saying the style and an
# unclipped exposure; a family the style does not have and an unknown style are refused
# with status 2; render_cache.sh -S simple names the scenes with seeds 20000 above the busy
# ones. Exit 77 (skipped) without blender.
set -u
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
blender=${BLENDER:-blender}
command -v "$blender" >/dev/null 2>&1 || { echo "skipped: no blender"; exit 77; }
py=/usr/bin/python3
[ -x "$py" ] || py=python3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail=0
no() { echo "FAIL: $*"; fail=1; }

render() { # family style out [extra...]
    f=$1; st=$2; out=$3; shift 3
    "$blender" -b --factory-startup --python "$root/tools/blender/render_scene.py" -- \
        --family "$f" --style "$st" --seed 270000 --width 32 --height 32 --spp 1 --ref-spp 4 \
        --preview-spp 4 --threads 2 --out "$out" "$@" > "$out.log" 2>&1
}

for f in cornell glossy glass firefly dof motionblur anim hdri; do
    render "$f" simple "$tmp/$f" --frames 1
    rc=$?
    [ "$rc" = 0 ] || { no "$f: exit $rc"; tail -5 "$tmp/$f.log"; continue; }
    "$py" - "$tmp/$f" "$f" <<'EOF' || no "$f: meta.json or files"
import json, os, sys
d, fam = sys.argv[1], sys.argv[2]
m = json.load(open(os.path.join(d, "meta.json")))
assert m["style"] == "simple" and m["family_name"] == fam, (m["style"], m["family_name"])
ae = m["autoexpose"]
assert ae["preview_clip_lum"] is None and len(ae["previews"]) == 1, ae
for name in ("f0001_spp0001.exr", "f0001_ref0004.exr"):
    assert os.path.getsize(os.path.join(d, name)) > 0, name
EOF
done
# the colour of a simple Cornell box: black around the open front, the box lit inside
"$py" - "$tmp/cornell/f0001_ref0004.exr" <<'EOF' || no "cornell: not a box seen from outside"
import sys
try:
    import OpenImageIO as oiio
except ImportError:
    sys.exit(0)
import numpy as np
i = oiio.ImageInput.open(sys.argv[1]); px = i.read_image(oiio.FLOAT); i.close()
lum = px[..., :3] @ np.array([0.2126, 0.7152, 0.0722])
corner, centre = lum[:2, :2].mean(), lum[12:20, 12:20].mean()
print("corner %.4f centre %.4f" % (corner, centre))
assert corner < 0.002 and centre > 0.05
EOF

render volume simple "$tmp/volume" --frames 1
rc=$?
[ "$rc" = 2 ] || no "volume in the simple style: exit $rc, want 2"
grep -q "simple has the families" "$tmp/volume.log" || no "volume: no message saying why"
render cornell fancy "$tmp/fancy" --frames 1
rc=$?
[ "$rc" = 2 ] || no "an unknown style: exit $rc, want 2"

names=$(BLENDER=true "$root/tools/blender/render_cache.sh" -S simple -s val -n 9 -o "$tmp/cache" -d 2>/dev/null | awk '{print $3}' | tr '\n' ' ')
want="a_cornell_270000_256x256 b_glossy_270001_256x256 c_glass_270002_256x256 d_firefly_270003_256x256 e_dof_270004_256x256 f_motionblur_270005_256x256 g_anim_270006_256x256 h_hdri_270007_256x256 a_cornell_270016_256x256 "
[ "$names" = "$want" ] || no "render_cache.sh -S simple names: $names"
"$root/tools/blender/render_cache.sh" -S fancy -d >/dev/null 2>&1
rc=$?
[ "$rc" = 2 ] || no "render_cache.sh -S fancy: exit $rc, want 2"

[ "$fail" = 0 ] && echo "ok"
exit "$fail"
