"""Headless test of the Edgewise Denoise add-on on animations (Ctrl+F12).

    blender -b --factory-startup --python tests/blender/test_addon_anim.py

A 96x72, 4-frame shot whose camera pans and rises (about 2-3 px a frame)
while the sphere moves on its own, rendered at 4 spp and at 128 spp (the
reference). Checks: the frames written in the user's format are the denoised
ones (OpenEXR MultiLayer: every pass, alpha and Cycles' metadata kept;
PNG: the denoised colour through the view transform); with Temporal on, no
frame is more than 0.2 dB below per-frame denoising; no temporary file left.
"""
import os
import sys
import tempfile
import time
import traceback

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from ewb_util import (build_scene, check, edgewise_temp_entries, finish, install_by_symlink, load_rgba,  # noqa: E402
                      psnr, save_png, tonemap)

FRAMES = 4
SPP = 4
REF_SPP = 128
PASSES = ("Combined", "Depth", "Vector", "Denoising Normal", "Denoising Albedo", "Denoising Depth")


def render_animation(scene, folder, fmt="OPEN_EXR_MULTILAYER"):
    scene.render.image_settings.file_format = fmt
    if fmt == "OPEN_EXR_MULTILAYER":
        scene.render.image_settings.color_depth = "16"
    scene.render.filepath = os.path.join(folder, "frame_####")
    bpy.ops.render.render(animation=True)
    ext = ".exr" if fmt.startswith("OPEN_EXR") else ".png"
    return [os.path.join(folder, "frame_%04d%s" % (f, ext)) for f in range(scene.frame_start, scene.frame_end + 1)]


def read_pass(ew, path, name, layer="ViewLayer"):
    return np.array(ew.run_node("read", path=path, layer=layer, **{"pass": name}, outputs="image"))


def main():
    tmp = tempfile.mkdtemp(prefix="ewb_anim_")
    look = os.environ.get("EW_LOOK_DIR")
    temp_before = edgewise_temp_entries()
    try:
        # camera: 0.4 m right and 0.3 m up over 3 frames (the image moves left and down);
        # sphere: 0.5 m left and 0.3 m up on its own
        scene = build_scene(frames=FRAMES, camera_motion=(0.4, 0.3), sphere_motion=(-0.5, 0.3))
        install_by_symlink(tmp)
        from edgewise_denoise import core, engine
        ew = core.load_edgewise()
        s = scene.edgewise
        s.use_temporal = True
        bpy.ops.edgewise.setup_passes()  # Denoising Data, Vector, motion blur off
        check(all(vl.use_pass_vector for vl in scene.view_layers), "Enable Passes turns on Vector for temporal")
        scene.cycles.samples = REF_SPP
        s.enabled = False
        refs = render_animation(scene, os.path.join(tmp, "ref"))
        scene.cycles.samples = SPP
        noisy = render_animation(scene, os.path.join(tmp, "noisy"))
        s.enabled = True
        s.use_temporal = False
        t0 = time.perf_counter()
        single = render_animation(scene, os.path.join(tmp, "single"))
        t_single = time.perf_counter() - t0
        s.use_temporal = True
        t0 = time.perf_counter()
        temporal = render_animation(scene, os.path.join(tmp, "temporal"))
        t_temporal = time.perf_counter() - t0
        check(not engine.state["last_error"], "no error (%s)" % engine.state["last_error"])
        check("temporal" in engine.state["last_note"], "temporal ran: %s" % engine.state["last_note"])

        # the vectors of the test's shot move the image by a few pixels a frame
        v = read_pass(ew, refs[2], "Vector")
        print("Vector pass frame 3: mean X %.2f, mean Y %.2f px (|max| %.1f)"
              % (v[:, :, 0].mean(), v[:, :, 1].mean(), np.abs(v[:, :, :2]).max()))
        check(1.0 < abs(v[:, :, 0].mean()) < 5.0 and 0.5 < abs(v[:, :, 1].mean()) < 5.0,
              "the shot moves in x and y")

        rows = []
        for f in range(FRAMES):
            ref = read_pass(ew, refs[f], "Combined")
            pn = psnr(read_pass(ew, noisy[f], "Combined"), ref)
            ps = psnr(read_pass(ew, single[f], "Combined"), ref)
            pt = psnr(read_pass(ew, temporal[f], "Combined"), ref)
            rows.append((pn, ps, pt))
            print("frame %d: noisy %.2f dB, per-frame denoised %.2f dB, temporal %.2f dB (%+.2f)"
                  % (f + 1, pn, ps, pt, pt - ps))
            check(ps - pn >= 1.0, "frame %d: the written file is denoised (%.2f -> %.2f dB)" % (f + 1, pn, ps))
            check(pt >= ps - 0.2, "frame %d: temporal %.2f dB not more than 0.2 dB below per-frame %.2f dB"
                  % (f + 1, pt, ps))
        print("mean: noisy %.2f, per-frame %.2f, temporal %.2f dB" % tuple(np.mean(rows, axis=0)))

        # every pass, alpha and the metadata are in the denoised multilayer files
        for path in single[:1] + temporal[-1:]:
            for name in PASSES:
                try:
                    a = read_pass(ew, path, name)
                    ok = np.isfinite(a).all()
                except Exception as e:
                    ok = False
                    print(e)
                check(ok, "%s has pass %s" % (os.path.basename(os.path.dirname(path)), name))
            alpha = read_pass(ew, path, "Combined")[:, :, 3]
            check(np.array_equal(alpha, read_pass(ew, noisy[0], "Combined")[:, :, 3]), "alpha kept")
            head = open(path, "rb").read(20000)
            check(b"cycles.ViewLayer.samples" in head, "Cycles' metadata kept")
        for name in PASSES[1:]:
            check(np.array_equal(read_pass(ew, single[1], name), read_pass(ew, noisy[1], name)),
                  "pass %s exactly as Cycles wrote it" % name)

        # PNG: the user's format, the denoised colour through the view transform
        s.use_temporal = False
        pngs = render_animation(scene, os.path.join(tmp, "png"), fmt="PNG")
        check(all(os.path.isfile(p) for p in pngs), "PNG frames written")
        for f in (0, FRAMES - 1):
            got = load_rgba(pngs[f])[:, :, :3]
            want = tonemap(read_pass(ew, single[f], "Combined")) ** 2.2  # Blender reads sRGB PNG as linear
            was = tonemap(read_pass(ew, noisy[f], "Combined")) ** 2.2
            d_den, d_noisy = float(np.abs(got - want).mean()), float(np.abs(got - was).mean())
            check(d_den < 0.01 and d_noisy > 3 * d_den,
                  "PNG frame %d is the denoised frame (mean diff %.4f; to the noisy one %.4f)" % (f + 1, d_den, d_noisy))
        # temporal on without a Vector pass: a warning, every frame still denoised and written
        scene.frame_end = 2
        s.use_temporal = True
        for vl in scene.view_layers:
            vl.use_pass_vector = False
        novec = [os.path.join(tmp, "novec", "frame_%04d.png" % f) for f in (1, 2)]
        try:
            render_animation(scene, os.path.join(tmp, "novec"), fmt="PNG")
            raised = ""
        except RuntimeError as e:
            raised = str(e)
        check(not raised and all(os.path.isfile(p) for p in novec) and "no Vector pass" in
              engine.state["last_warning"] and not engine.state["last_error"],
              "temporal without Vector: warned (%s), both frames written %s" % (engine.state["last_warning"], raised))
        # a failed denoise is an error: Blender stops the animation, no noisy frame is written as if done
        bad = os.path.join(tmp, "emptylib")
        os.makedirs(bad)
        s.library_path = bad
        failed = [os.path.join(tmp, "failed", "frame_%04d.png" % f) for f in (1, 2)]
        try:
            render_animation(scene, os.path.join(tmp, "failed"), fmt="PNG")
            raised = ""
        except RuntimeError as e:
            raised = str(e)
        check("refused" in raised and not any(os.path.exists(p) for p in failed),
              "an error stops the animation before its frame is written: %s" % raised)
        s.library_path = ""
        check(edgewise_temp_entries() == temp_before, "no temporary file left behind")
        if look:
            os.makedirs(look, exist_ok=True)
            f = FRAMES - 1
            for name, path in (("ref", refs[f]), ("noisy", noisy[f]), ("single", single[f]),
                               ("temporal", temporal[f])):
                save_png(read_pass(ew, path, "Combined"), os.path.join(look, "anim_f%d_%s.png" % (f + 1, name)))
        print("timings: 4-frame animation denoised per frame %.2f s, with temporal %.2f s" % (t_single, t_temporal))
    except Exception:
        traceback.print_exc()
        check(False, "exception")
    finish(tmp)


main()
