"""Headless test of installing the add-on from a zip with the library bundled.

    blender -b --factory-startup --python tests/blender/test_addon_zip.py

Builds the zip with blender_addon/make_zip.py (library from $EDGEWISE_LIB or
build/lib), installs it with preferences.addon_install into a temporary user
scripts folder, enables it with $EDGEWISE_LIB unset, checks that the bundled
library is the one loaded, and denoises a 64x64 1-spp render (F12).
"""
import os
import runpy
import shutil
import sys
import tempfile
import traceback

import addon_utils
import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
failures = []


def check(cond, what):
    print("%s: %s" % ("ok  " if cond else "FAIL", what))
    if not cond:
        failures.append(what)


def main():
    tmp = tempfile.mkdtemp(prefix="edgewise_zip_")
    try:
        zpath = os.path.join(tmp, "edgewise_denoise.zip")
        argv = sys.argv
        sys.argv = ["make_zip.py", "-o", zpath]
        try:
            runpy.run_path(os.path.join(REPO, "blender_addon", "make_zip.py"), run_name="__main__")
        finally:
            sys.argv = argv
        os.environ.pop("EDGEWISE_LIB", None)
        sys.path[:] = [p for p in sys.path if not p.startswith(REPO)]
        scripts = os.path.join(tmp, "scripts")
        os.environ["BLENDER_USER_SCRIPTS"] = scripts
        bpy.ops.wm.read_factory_settings(use_empty=True)
        bpy.ops.preferences.addon_install(filepath=zpath, overwrite=True)
        target = bpy.utils.user_resource("SCRIPTS", path="addons")
        check(os.path.isdir(os.path.join(target, "edgewise_denoise")), "installed into %s" % target)
        if target not in sys.path:
            sys.path.append(target)
        mod = addon_utils.enable("edgewise_denoise", default_set=True, handle_error=None)
        check(mod is not None and mod.__file__.startswith(target), "enabled the installed copy")
        from edgewise_denoise import core
        ok, text = core.library_status()
        print(text)
        check(ok and os.path.realpath(target) in os.path.realpath(text), "bundled library loaded: " + text)

        scene = bpy.context.scene
        scene.render.engine = "CYCLES"
        scene.cycles.samples = 1
        scene.cycles.use_denoising = False
        scene.render.resolution_x = scene.render.resolution_y = 64
        scene.render.resolution_percentage = 100
        scene.world = bpy.data.worlds.new("W")
        bpy.ops.mesh.primitive_uv_sphere_add()
        bpy.ops.object.light_add(type="POINT", location=(2, -2, 3))
        bpy.ops.object.camera_add(location=(0, -5, 0), rotation=(1.5708, 0, 0))
        scene.camera = bpy.context.object
        bpy.ops.edgewise.setup_passes()
        scene.edgewise.enabled = True
        scene.edgewise.method = "nbg"
        from edgewise_denoise import engine
        bpy.ops.render.render()
        check(engine.state["runs"] == 1 and not engine.state["last_error"],
              "F12 denoised with the bundled library: %s %s" % (engine.state["last_note"], engine.state["last_error"]))
    except Exception:
        traceback.print_exc()
        failures.append("exception")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print("%d failed" % len(failures))
    sys.stdout.flush()
    os._exit(1 if failures else 0)


main()
