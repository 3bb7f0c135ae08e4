"""Render a depth-of-field pair for bench_filters: the same procedural scene
(tools/blender/render_scene.py, family "dof") once through a pinhole camera
(Combined + Depth + Denoising passes) and once with the camera's depth of
field on (Combined only), plus the camera values the DoF filter needs.

    blender -b --factory-startup --python bench/render_dof_pair.py -- \
        --seed 105 --width 256 --height 256 --pinhole-spp 256 --dof-spp 1024 --out DIR

Writes DIR/pinhole.exr, DIR/dof.exr and DIR/camera.json (focal length mm,
sensor width mm and fit, f-stop, focus distance m, aperture blades). The
scene, its lights and exposure are built exactly as render_scene.py builds
them for that seed, so the pair differs only in the aperture.
"""
import json
import os
import random
import shutil
import sys
import tempfile

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tools", "blender"))
import render_scene as rs  # noqa: E402

import bpy  # noqa: E402


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    get = lambda name, default: argv[argv.index(name) + 1] if name in argv else default
    seed = int(get("--seed", "105"))
    width, height = int(get("--width", "256")), int(get("--height", "256"))
    pin_spp, dof_spp = int(get("--pinhole-spp", "256")), int(get("--dof-spp", "1024"))
    out = os.path.abspath(get("--out", "dof_pair"))
    os.makedirs(out, exist_ok=True)

    # the generator's own argument parsing and flow (run()), up to the renders
    args = rs.build_parser().parse_args(["--family", "dof", "--seed", str(seed), "--width", str(width),
                                         "--height", str(height), "--out", out, "--spp", "1"])
    sc = bpy.context.scene
    rs.clear_scene()
    vl = rs.configure_render(sc, "dof", args, 1)
    rng = random.Random(args.seed)
    ctx = {"width": width, "height": height, "frame_start": 1, "frames": 1}
    sc.frame_set(1)
    rs.BUILDERS["dof"](rng, ctx)
    tmpdir = tempfile.mkdtemp(prefix=".autoexpose-", dir=out)
    try:
        rs.autoexpose(sc, vl, args, tmpdir, True, random.Random("preview:%s:%d" % ("dof", args.seed)))
    finally:
        shutil.rmtree(tmpdir, ignore_errors=True)

    cam = sc.camera.data
    info = {
        "seed": seed, "width": width, "height": height,
        "focal_length_mm": cam.lens, "sensor_width_mm": cam.sensor_width, "sensor_fit": cam.sensor_fit,
        "fstop": cam.dof.aperture_fstop, "focus_distance_m": cam.dof.focus_distance,
        "aperture_blades": cam.dof.aperture_blades, "pinhole_spp": pin_spp, "dof_spp": dof_spp,
    }
    cam.dof.use_dof = False
    rs.render_one(sc, vl, out, "pinhole.exr", pin_spp, rs.render_seed("dof", seed, 1, "pinhole", pin_spp), True,
                  True, True)
    cam.dof.use_dof = True
    rs.render_one(sc, vl, out, "dof.exr", dof_spp, rs.render_seed("dof", seed, 1, "dof", dof_spp), False, True, True)
    with open(os.path.join(out, "camera.json"), "w") as f:
        json.dump(info, f, indent=1)
    print("render_dof_pair: wrote %s/{pinhole,dof}.exr and camera.json" % out)


main()
