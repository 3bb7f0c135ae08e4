"""Headless test of the Edgewise Denoise add-on.

    blender -b --factory-startup --python tests/blender/test_addon.py [-- --bench]

Enables the add-on from the repository folder, builds a 96x96 scene with two
view layers, renders it at 1 spp with Cycles on the CPU and denoises it
through the add-on's operator; then renders 3 animation frames with the
render_write handler on. Exits 0 on success, 1 on failure (CTest runs it
through run_blender_test.py, which exits 77 when blender is missing).
"""
import math
import os
import shutil
import sys
import tempfile
import time
import traceback

import bpy
import addon_utils
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
ADDON_DIR = os.path.join(REPO, "blender_addon")
SIZE = 96
REF_SPP = 256
# The add-on's default method, "auto": at 1 spp (the render's sample count reaches the
# library through the add-on) it runs the 1-spp neural bilateral grid model.
METHOD = os.environ.get("EW_BLENDER_METHOD", "auto")
failures = []


def check(cond, what):
    print("%s: %s" % ("ok  " if cond else "FAIL", what))
    if not cond:
        failures.append(what)


def build_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.use_denoising = False
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.max_bounces = 4
    scene.render.resolution_x = scene.render.resolution_y = SIZE
    scene.render.resolution_percentage = 100
    scene.render.use_persistent_data = False
    scene.render.threads_mode = "FIXED"
    scene.render.threads = 2
    world = bpy.data.worlds.new("World")
    scene.world = world
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.3, 0.35, 0.45, 1.0)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.6

    def mat(name, color):
        m = bpy.data.materials.new(name)
        m.use_nodes = True
        m.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = color + (1.0,)
        return m

    bpy.ops.mesh.primitive_plane_add(size=8, location=(0, 0, 0))
    bpy.context.object.data.materials.append(mat("floor", (0.7, 0.7, 0.65)))
    bpy.ops.mesh.primitive_cube_add(size=1.2, location=(-0.8, 0.2, 0.6), rotation=(0, 0, 0.5))
    bpy.context.object.data.materials.append(mat("red", (0.8, 0.15, 0.1)))
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.6, location=(0.9, -0.3, 0.6))
    sphere = bpy.context.object
    sphere.data.materials.append(mat("blue", (0.1, 0.3, 0.8)))
    bpy.ops.object.shade_smooth()
    sphere.keyframe_insert("location", frame=1)
    sphere.location.x = 0.5
    sphere.keyframe_insert("location", frame=3)
    bpy.ops.object.light_add(type="AREA", location=(1.5, -1.5, 3.5))
    bpy.context.object.data.energy = 300
    bpy.context.object.data.size = 1.5
    bpy.ops.object.camera_add(location=(0, -5.5, 3.2), rotation=(math.radians(62), 0, 0))
    scene.camera = bpy.context.object
    scene.view_layers[0].name = "Main"
    second = scene.view_layers.new("Second")
    second.samples = 0
    for vl in scene.view_layers:
        vl.cycles.use_denoising = False
    return scene


def read_color(path, layer):
    import edgewise as ew
    return np.array(ew.run_node("read", path=path, layer=layer, outputs="color"))[:, :, :3]


def tonemap(x):
    x = np.nan_to_num(np.asarray(x, np.float64), nan=0.0, posinf=1e4)
    return np.clip(x, 0.0, 1.0) ** (1.0 / 2.2)


def psnr(a, b):
    mse = float(np.mean((tonemap(a) - tonemap(b)) ** 2))
    return 10.0 * math.log10(1.0 / max(mse, 1e-12))


def image_rgb(img):
    w, h = img.size
    a = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(a)
    return a.reshape(h, w, 4)[::-1, :, :3]


class FakeLayout(object):
    """Records what a panel draws (panels cannot be drawn in background mode)."""

    def __init__(self, log):
        self.log = log

    def prop(self, data, name, **kw):
        getattr(data, name)  # the property must exist
        self.log.append("prop " + name)

    def label(self, text="", **kw):
        self.log.append(text)

    def operator(self, idname, **kw):
        mod, op = idname.split(".")
        check(hasattr(getattr(bpy.ops, mod), op), "panel operator %s exists" % idname)
        self.log.append("op " + idname)

    def box(self):
        return self

    def column(self, **kw):
        return self


def draw_panel(scene):
    from edgewise_denoise import panels

    class Ctx(object):
        pass
    ctx = Ctx()
    ctx.scene = scene
    ctx.engine = scene.render.engine
    log = []
    panels.draw_settings(FakeLayout(log), ctx)
    check(panels.EDGEWISE_PT_render.poll(ctx), "render panel shows for Cycles")
    return log


def save_render(scene, path):
    from edgewise_denoise.operators import save_render_exr
    return save_render_exr(scene, path)


def bench_viewer(scene, tmp):
    """Time the Viewer-node route (one pass per composite) against save_render + read."""
    from edgewise_denoise import core, operators
    scene.use_nodes = True
    tree = scene.node_tree
    rl = tree.nodes.get("Render Layers") or tree.nodes.new("CompositorNodeRLayers")
    viewer = tree.nodes.new("CompositorNodeViewer")
    tree.links.new(rl.outputs["Image"], viewer.inputs["Image"])
    bpy.ops.render.render()
    t0 = time.perf_counter()
    img = bpy.data.images["Viewer Node"]
    w, h = img.size
    a = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(a)
    t_viewer = time.perf_counter() - t0
    t0 = time.perf_counter()
    p = save_render(scene, os.path.join(tmp, "bench.exr"))
    t_save = time.perf_counter() - t0
    ew = core.load_edgewise()
    for layer in ("Main", "Second"):
        for port in ("color", "albedo", "normal", "depth"):
            ew.run_node("read", path=p, layer=layer, outputs=port)
    t_exr = time.perf_counter() - t0
    print("bench: viewer node pixels.foreach_get (Combined of the active layer only) %.4f s; "
          "save_render multilayer EXR (every pass, 2 layers) %.4f s + read 4 passes x 2 layers = %.4f s"
          % (t_viewer, t_save, t_exr))
    # the Viewer holds one pass of one layer per composite; in background mode the compositor
    # only runs inside a render, so each further pass costs a render + composite:
    t0 = time.perf_counter()
    bpy.ops.render.render()
    img.pixels.foreach_get(a)
    print("bench: one more Viewer pass (re-render 1 spp + composite + foreach_get) %.4f s"
          % (time.perf_counter() - t0))
    tree.nodes.remove(viewer)
    scene.use_nodes = False


def main():
    t_start = time.perf_counter()
    tmp = tempfile.mkdtemp(prefix="edgewise_blender_")
    try:
        if ADDON_DIR not in sys.path:
            sys.path.insert(0, ADDON_DIR)  # the add-on from the repo folder
        scene = build_scene()  # factory settings first: they would disable add-ons
        mod = addon_utils.enable("edgewise_denoise", default_set=True, handle_error=None)
        check(mod is not None and hasattr(bpy.types.Scene, "edgewise"), "add-on enabled from the repo")
        from edgewise_denoise import core
        s = scene.edgewise
        check(len(s.bl_rna.properties["method"].enum_items) >= 2, "methods generated from the library: %s"
              % [e.identifier for e in s.bl_rna.properties["method"].enum_items])
        check(scene.view_layers[0].name in __import__("edgewise_denoise.operators", fromlist=["x"]).missing_by_layer(scene),
              "panel logic reports missing passes before set-up")
        labels = draw_panel(scene)
        check(any("missing" in t and "Denoising Albedo" in t for t in labels),
              "panel says which passes are missing: %s" % [t for t in labels if "missing" in t])
        bpy.ops.edgewise.setup_passes()
        check(all(vl.cycles.denoising_store_passes for vl in scene.view_layers), "setup_passes turns on passes")
        labels = draw_panel(scene)
        check(not any("missing" in t for t in labels), "panel: no missing passes after set-up")

        # reference (both layers show the same objects: render it for "Main" only, to save time)
        scene.view_layers["Second"].use = False
        scene.cycles.samples = REF_SPP
        scene.cycles.seed = 7
        t0 = time.perf_counter()
        bpy.ops.render.render()
        t_ref = time.perf_counter() - t0
        ref_path = save_render(scene, os.path.join(tmp, "ref.exr"))
        refs = {"Main": read_color(ref_path, "Main")}
        refs["Second"] = refs["Main"]
        scene.view_layers["Second"].use = True

        # 1 spp still, denoised by the operator
        scene.cycles.samples = 1
        scene.cycles.seed = 1
        t0 = time.perf_counter()
        bpy.ops.render.render()
        t_noisy = time.perf_counter() - t0
        noisy_path = save_render(scene, os.path.join(tmp, "noisy.exr"))
        check(s.method == "auto", "the add-on's default method is auto (got %r)" % s.method)
        s.method = METHOD
        t0 = time.perf_counter()
        r = bpy.ops.edgewise.denoise_render()
        t_den = time.perf_counter() - t0
        check(r == {"FINISHED"}, "denoise_render operator finished")
        after_path = save_render(scene, os.path.join(tmp, "after.exr"))
        for layer in ("Main", "Second"):
            name = core.result_image_name(layer, 2)
            img = bpy.data.images.get(name)
            check(img is not None, "result image %r exists" % name)
            if img is None:
                continue
            den = image_rgb(img)
            noisy = read_color(noisy_path, layer)
            p0, p1 = psnr(noisy, refs[layer]), psnr(den, refs[layer])
            check(p1 - p0 >= 6.0, "%s: PSNR %.2f -> %.2f dB (+%.2f, need >= 6)" % (layer, p0, p1, p1 - p0))
            check(np.array_equal(noisy, read_color(after_path, layer)), "%s: render result untouched" % layer)

        # the render_complete handler (still)
        for img in [i for i in bpy.data.images if i.name.startswith(core.RESULT_IMAGE)]:
            bpy.data.images.remove(img)
        s.enabled = True
        bpy.ops.render.render()
        check(all(bpy.data.images.get(core.result_image_name(l, 2)) for l in ("Main", "Second")),
              "render_complete handler made the result images")

        # animation: render_write writes <frame>_denoised_<layer>.exr next to each frame
        scene.frame_start, scene.frame_end = 1, 3
        scene.cycles.use_animated_seed = True
        scene.render.image_settings.file_format = "OPEN_EXR_MULTILAYER"
        scene.render.image_settings.color_depth = "16"
        scene.render.filepath = os.path.join(tmp, "anim", "frame_####")
        t0 = time.perf_counter()
        bpy.ops.render.render(animation=True)
        t_anim = time.perf_counter() - t0
        from edgewise_denoise.handlers import state
        check(not state["last_error"], "no handler error (%s)" % state["last_error"])
        for f in (1, 2, 3):
            frame = os.path.join(tmp, "anim", "frame_%04d.exr" % f)
            check(os.path.isfile(frame), "frame %d rendered" % f)
            for layer in ("Main", "Second"):
                out = core.denoised_path(frame, layer, True)
                ok = os.path.isfile(out)
                check(ok, "frame %d %s: %s written" % (f, layer, os.path.basename(out)))
                if ok and f == 1:
                    d = read_color(out, "")
                    n = read_color(frame, layer)
                    p0, p1 = psnr(n, refs[layer]), psnr(d, refs[layer])
                    check(p1 - p0 >= 6.0, "frame 1 %s file: PSNR %.2f -> %.2f dB" % (layer, p0, p1))
        # animation with the temporal pass (Vector pass; runs at render_complete, replacing the files)
        s.use_temporal = True
        bpy.ops.edgewise.setup_passes()
        check(all(vl.use_pass_vector for vl in scene.view_layers), "setup_passes turns on Vector for temporal")
        scene.render.filepath = os.path.join(tmp, "temporal", "shot_####")
        t0 = time.perf_counter()
        bpy.ops.render.render(animation=True)
        t_temporal = time.perf_counter() - t0
        check(not state["last_error"], "no temporal error (%s)" % state["last_error"])
        check(len(state["written"]) == 2, "temporal pass ran for both layers: %s" % state["written"])
        for f in (1, 2, 3):
            frame = os.path.join(tmp, "temporal", "shot_%04d.exr" % f)
            for layer in ("Main", "Second"):
                out = core.denoised_path(frame, layer, True)
                ok = os.path.isfile(out)
                check(ok, "temporal frame %d %s: %s written" % (f, layer, os.path.basename(out)))
                if ok:
                    d, n = read_color(out, ""), read_color(frame, layer)
                    msg = "temporal frame %d %s: finite, PSNR vs noisy frame %.2f dB" % (f, layer, psnr(d, n))
                    check(np.isfinite(d).all(), msg)
                    if f == 1:
                        p0, p1 = psnr(n, refs[layer]), psnr(d, refs[layer])
                        check(p1 - p0 >= 6.0, "temporal frame 1 %s: PSNR %.2f -> %.2f dB" % (layer, p0, p1))
        s.use_temporal = False
        if "--bench" in sys.argv:
            s.enabled = False
            scene.cycles.samples = 1
            bench_viewer(scene, tmp)
        addon_utils.disable("edgewise_denoise")
        check(not hasattr(bpy.types.Scene, "edgewise"), "add-on disabled cleanly")
        print("timings: reference %d spp %.2f s, 1 spp %.2f s, denoise operator (2 layers) %.2f s, "
              "3-frame animation with denoise %.2f s, with temporal %.2f s, total %.2f s"
              % (REF_SPP, t_ref, t_noisy, t_den, t_anim, t_temporal, time.perf_counter() - t_start))
    except Exception:
        traceback.print_exc()
        failures.append("exception")
    finally:
        if not os.environ.get("EW_KEEP_TMP"):
            shutil.rmtree(tmp, ignore_errors=True)
        else:
            print("kept", tmp)
    print("%d failed" % len(failures))
    sys.stdout.flush()
    os._exit(1 if failures else 0)


main()
