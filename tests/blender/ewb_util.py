"""Shared helpers of the headless Blender tests (run inside Blender's Python)."""
import math
import os
import sys
import tempfile

import addon_utils
import bpy
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
W, H = 96, 72
failures = []


def check(cond, what):
    print("%s: %s" % ("ok  " if cond else "FAIL", what))
    sys.stdout.flush()
    if not cond:
        failures.append(what)
    return cond


def edgewise_temp_entries():
    """Files the add-on could leave in the temporary folder."""
    d = tempfile.gettempdir()
    return set(n for n in os.listdir(d) if n.startswith("edgewise_render"))


def install_by_symlink(tmp):
    """The README's developer install: a symlink to the repo's package in an
    add-ons folder (not the repo's folder itself on sys.path)."""
    addons = os.path.join(tmp, "scripts", "addons")
    os.makedirs(addons)
    os.symlink(os.path.join(REPO, "blender_addon", "edgewise_denoise"), os.path.join(addons, "edgewise_denoise"))
    sys.path[:] = [p for p in sys.path if not p.startswith(REPO)]
    sys.path.append(addons)
    mod = addon_utils.enable("edgewise_denoise", default_set=True, handle_error=None)
    check(mod is not None and hasattr(bpy.types.Scene, "edgewise"), "add-on enabled through a symlink")
    return addons


def material(name, color, checker=False):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    bsdf = m.node_tree.nodes["Principled BSDF"]
    if checker:
        t = m.node_tree.nodes.new("ShaderNodeTexChecker")
        t.inputs["Scale"].default_value = 12
        t.inputs["Color1"].default_value = (0.8, 0.8, 0.75, 1)
        t.inputs["Color2"].default_value = (0.15, 0.15, 0.15, 1)
        m.node_tree.links.new(t.outputs["Color"], bsdf.inputs["Base Color"])
    else:
        bsdf.inputs["Base Color"].default_value = color + (1.0,)
    return m


def build_scene(frames=1, camera_motion=(0.0, 0.0), sphere_motion=(0.0, 0.0), reset=True):
    """A checker floor, a cube, a sphere, an area light and a world colour.
    camera_motion / sphere_motion: (x, z) travel in metres over the frames
    (linear), so the image moves by a known few pixels a frame. reset=False
    keeps the open file and its windows (the GUI test) and only removes its objects."""
    if reset:
        bpy.ops.wm.read_factory_settings(use_empty=True)
    else:
        for obj in list(bpy.data.objects):
            bpy.data.objects.remove(obj)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.use_denoising = False
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.max_bounces = 3
    scene.cycles.use_animated_seed = True
    scene.render.resolution_x, scene.render.resolution_y = W, H
    scene.render.resolution_percentage = 100
    scene.render.threads_mode = "FIXED"
    scene.render.threads = 2
    scene.view_settings.view_transform = "Standard"
    world = bpy.data.worlds.new("World")
    scene.world = world
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.3, 0.35, 0.45, 1.0)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.6
    bpy.ops.mesh.primitive_plane_add(size=10)
    bpy.context.object.data.materials.append(material("floor", None, True))
    bpy.ops.mesh.primitive_cube_add(size=1.2, location=(-0.8, 0.2, 0.6), rotation=(0, 0, 0.5))
    bpy.context.object.data.materials.append(material("red", (0.8, 0.15, 0.1)))
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.6, location=(0.9, -0.3, 0.6))
    sphere = bpy.context.object
    sphere.data.materials.append(material("blue", (0.1, 0.3, 0.8)))
    bpy.ops.object.shade_smooth()
    bpy.ops.object.light_add(type="AREA", location=(1.5, -1.5, 3.5))
    bpy.context.object.data.energy = 300
    bpy.context.object.data.size = 1.5
    bpy.ops.object.camera_add(location=(0, -5.5, 3.2), rotation=(math.radians(62), 0, 0))
    cam = bpy.context.object
    scene.camera = cam
    scene.frame_start, scene.frame_end = 1, frames
    for obj, (dx, dz) in ((cam, camera_motion), (sphere, sphere_motion)):
        if frames > 1 and (dx or dz):
            obj.keyframe_insert("location", frame=1)
            obj.location.x += dx
            obj.location.z += dz
            obj.keyframe_insert("location", frame=frames)
            for fc in obj.animation_data.action.fcurves:
                for k in fc.keyframe_points:
                    k.interpolation = "LINEAR"
    scene.frame_set(1)
    for vl in scene.view_layers:
        vl.cycles.use_denoising = False
        vl.use_pass_z = True  # a pass of the user's own, which the output files must keep
    return scene


def save_result(scene, path):
    """What the render window shows (the composite when compositing is on),
    as a float RGBA EXR."""
    fmt = scene.render.image_settings
    old = (fmt.file_format, fmt.color_depth, fmt.color_mode)
    try:
        fmt.file_format, fmt.color_depth, fmt.color_mode = "OPEN_EXR", "32", "RGBA"
        bpy.data.images["Render Result"].save_render(path, scene=scene)
    finally:
        fmt.file_format, fmt.color_depth, fmt.color_mode = old
    return load_rgba(path)


def load_rgba(path):
    """(H, W, 4) float, top row first, as Blender reads the file."""
    img = bpy.data.images.load(path, check_existing=False)
    try:
        w, h = img.size
        a = np.empty(w * h * 4, np.float32)
        img.pixels.foreach_get(a)
        return a.reshape(h, w, 4)[::-1].copy()
    finally:
        bpy.data.images.remove(img)


def tonemap(x):
    x = np.nan_to_num(np.asarray(x, np.float64)[..., :3], nan=0.0, posinf=1e4)
    return np.clip(x, 0.0, 1.0) ** (1.0 / 2.2)


def psnr(a, b):
    mse = float(np.mean((tonemap(a) - tonemap(b)) ** 2))
    return 10.0 * math.log10(1.0 / max(mse, 1e-12))


def save_png(rgba, path):
    """A tone-mapped PNG to look at (kept only with EW_KEEP_TMP / EW_LOOK_DIR)."""
    h, w = rgba.shape[:2]
    img = bpy.data.images.new(os.path.basename(path), w, h, alpha=False)
    px = np.ones((h, w, 4), np.float32)
    px[:, :, :3] = tonemap(rgba)
    img.pixels.foreach_set(px[::-1].ravel())
    img.filepath_raw = path
    img.file_format = "PNG"
    img.save()
    bpy.data.images.remove(img)


def finish(tmp):
    import shutil
    if not os.environ.get("EW_KEEP_TMP"):
        shutil.rmtree(tmp, ignore_errors=True)
    else:
        print("kept", tmp)
    print("%d failed" % len(failures))
    for f in failures:
        print("  FAILED:", f)
    sys.stdout.flush()
    os._exit(1 if failures else 0)
