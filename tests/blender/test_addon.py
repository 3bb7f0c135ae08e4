"""Headless test of the Edgewise Denoise add-on on stills.

    blender -b --factory-startup --python tests/blender/test_addon.py

Installs the add-on as the README's developer install does (a symlink in an
add-ons folder), renders a 96x72 scene with Cycles on the CPU and checks what
a user gets after F12: the render result itself is denoised (what the render
window shows and saves), the compositor runs on the denoised colour (an
Invert node), alpha survives a transparent film, renders without Denoising
Data are denoised colour-guided, EEVEE is left alone, Render > Denoise left
on is detected and turned off, a bad Library setting is refused with its
reason (and nothing is denoised with another copy), no temporary file is
left. Exits 0 on success, 1 on failure (run_blender_test.py: 77 without blender).
"""
import os
import sys
import tempfile
import time
import traceback

import addon_utils
import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from ewb_util import (REPO, build_scene, check, edgewise_temp_entries, finish, install_by_symlink,  # noqa: E402
                      psnr, save_png, save_result)

SPP = 4
REF_SPP = 128


class FakeLayout(object):
    """Records what a panel draws (panels cannot be drawn in background mode)."""

    def __init__(self, log):
        self.log = log
        self.alert = False

    def prop(self, data, name, **kw):
        getattr(data, name)  # the property must exist
        self.log.append(("prop", name))

    def label(self, text="", **kw):
        self.log.append(("alert" if self.alert else "label", text))

    def operator(self, idname, **kw):
        mod, op = idname.split(".")
        check(hasattr(getattr(bpy.ops, mod), op), "panel operator %s exists" % idname)
        self.log.append(("op", idname))

    def box(self):
        return self

    def column(self, **kw):
        return FakeLayout(self.log)

    def row(self, **kw):
        return FakeLayout(self.log)


def draw_panel(scene):
    from edgewise_denoise import panels

    class Ctx(object):
        pass
    ctx = Ctx()
    ctx.scene = scene
    log = []
    panels.draw_settings(FakeLayout(log), ctx)
    return log


def alerts(log):
    return " ".join(t for k, t in log if k == "alert")


def render(scene, path):
    bpy.ops.render.render()
    return save_result(scene, path)


def check_enums_saved_by_identifier(tmp):
    """A .blend keeps its method and model when the library lists its choices
    in another order (the enums are generated from whichever library is
    loaded), and a file from before, which stored Blender's enum position,
    still loads its choice."""
    from edgewise_denoise import core, properties
    s = bpy.context.scene.edgewise
    s.method = "nbg"
    s.nbg__model = "7layer-3grid"
    check(s.get("method") == "nbg" and s.get("nbg__model") == "7layer-3grid",
          "enum settings saved by identifier: %r %r" % (s.get("method"), s.get("nbg__model")))
    path = os.path.join(tmp, "enums.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    items0, enum0 = core.method_items, core.enum_items
    core.method_items = lambda ew=None: list(reversed(items0(ew)))   # a library that orders them otherwise
    core.enum_items = lambda p: list(reversed(enum0(p)))
    try:
        properties.rebuild()
        bpy.ops.wm.open_mainfile(filepath=path)
        s = bpy.context.scene.edgewise
        order = [e.identifier for e in s.bl_rna.properties["method"].enum_items]
        check(order[0] != "auto", "the rebuilt Method list is in the other order: %s" % order)
        check(s.method == "nbg" and s.nbg__model == "7layer-3grid",
              "after a reorder the file still says nbg / 7layer-3grid: %s / %s" % (s.method, s.nbg__model))
        # a file from before: Blender's EnumProperty stored the position
        s["method"] = 1
        check(s.method == order[1], "an old file's position is read as the choice at that position: %s" % s.method)
        s.method = "auto"
        check(s.get("method") == "auto", "writing converts it to the identifier")
    finally:
        core.method_items, core.enum_items = items0, enum0
        properties.rebuild()
    s = bpy.context.scene.edgewise
    check(s.method == "auto" and s.nbg__model == "7layer-3grid", "back in the library's own order")


def main():
    t_start = time.perf_counter()
    tmp = tempfile.mkdtemp(prefix="ewb_still_")
    look = os.environ.get("EW_LOOK_DIR")
    temp_before = edgewise_temp_entries()
    try:
        scene = build_scene()  # factory settings first: they would disable add-ons
        install_by_symlink(tmp)
        import edgewise_denoise
        from edgewise_denoise import core, engine
        check(os.path.realpath(edgewise_denoise.__file__).startswith(REPO), "the symlinked package is the repo's")
        check(not any(p.startswith(REPO) for p in sys.path), "no repository folder on sys.path")
        check("edgewise" not in sys.modules, "no global 'edgewise' module (package-relative import)")
        s = scene.edgewise
        items = s.bl_rna.properties["method"].enum_items
        check(len(items) >= 2 and all("_" not in e.name for e in items),
              "methods from the library with readable names: %s" % [(e.identifier, e.name) for e in items])

        # Render > Denoise left on: detected, and the panel's operator turns it off
        scene.cycles.use_denoising = True
        log = draw_panel(scene)
        check("OpenImageDenoise" in alerts(log) and ("op", "edgewise.cycles_denoise_off") in log,
              "panel: red line and offer when Render > Denoise is on: %s" % alerts(log))
        s.enabled = True
        scene.cycles.samples = 1
        try:
            bpy.ops.render.render()
            raised = ""
        except RuntimeError as e:  # the engine's error report fails the operator, as Blender shows it
            raised = str(e)
        check("Render > Denoise is on" in raised and "Render > Denoise is on" in engine.state["last_error"],
              "a render with Render > Denoise on reports it as the render's error: %s" % raised)
        s.enabled = False
        bpy.ops.edgewise.cycles_denoise_off()
        check(not scene.cycles.use_denoising and not engine.cycles_denoise_fails(scene), "turned off by the operator")

        # reference, noisy, denoised stills (same seed: the same noisy render)
        scene.cycles.seed = 3
        scene.cycles.samples = REF_SPP
        ref = render(scene, os.path.join(tmp, "ref.exr"))
        scene.cycles.samples = SPP
        log = draw_panel(scene)
        check(any(k == "label" and "colour-guided" in t for k, t in log) and
              any(k == "label" and "no Denoising Data" in t for k, t in log),
              "panel: missing Denoising Data is advice: %s" % [t for k, t in log if k == "label"])
        bpy.ops.edgewise.setup_passes()
        check(all(vl.cycles.denoising_store_passes for vl in scene.view_layers), "Enable Passes turns on passes")
        noisy = render(scene, os.path.join(tmp, "noisy.exr"))
        s.enabled = True
        t0 = time.perf_counter()
        den = render(scene, os.path.join(tmp, "den.exr"))
        t_den = time.perf_counter() - t0
        p0, p1 = psnr(noisy, ref), psnr(den, ref)
        check(not engine.state["last_error"], "no error (%s)" % engine.state["last_error"])
        check(p1 - p0 >= 1.0, "F12 result is denoised: PSNR %.2f -> %.2f dB (%s)" % (p0, p1, engine.state["last_note"]))
        check(np.array_equal(den[:, :, 3], noisy[:, :, 3]), "alpha as Cycles wrote it (opaque film)")

        # the compositor runs on the denoised colour: an Invert node
        scene.use_nodes = True
        tree = scene.node_tree
        rl, comp = tree.nodes["Render Layers"], tree.nodes["Composite"]
        inv = tree.nodes.new("CompositorNodeInvert")
        tree.links.new(rl.outputs["Image"], inv.inputs["Color"])
        tree.links.new(inv.outputs["Color"], comp.inputs["Image"])
        comped = render(scene, os.path.join(tmp, "inverted.exr"))
        inside = (den[:, :, :3] >= 0) & (den[:, :, :3] <= 1)
        err = float(np.abs(comped[:, :, :3] - (1.0 - den[:, :, :3]))[inside].max())
        err_noisy = float(np.abs(comped[:, :, :3] - (1.0 - noisy[:, :, :3]))[inside].mean())
        check(err < 2e-3, "Invert node output is 1 - denoised (max error %.2g)" % err)
        check(err_noisy > 5 * float(np.abs(comped[:, :, :3] - (1.0 - den[:, :, :3]))[inside].mean()),
              "... and not 1 - noisy (mean difference %.3g)" % err_noisy)
        tree.nodes.remove(inv)
        tree.links.new(rl.outputs["Image"], comp.inputs["Image"])
        scene.use_nodes = False

        # transparent film: alpha survives, colour is denoised
        scene.render.film_transparent = True
        s.enabled = False
        noisy_t = render(scene, os.path.join(tmp, "noisy_t.exr"))
        s.enabled = True
        den_t = render(scene, os.path.join(tmp, "den_t.exr"))
        a = den_t[:, :, 3]
        check(np.array_equal(a, noisy_t[:, :, 3]) and (a < 0.01).mean() > 0.05 and (a > 0.99).mean() > 0.3,
              "transparent film: alpha kept (%.0f%% transparent, %.0f%% opaque)"
              % (100 * (a < 0.01).mean(), 100 * (a > 0.99).mean()))
        check(float(np.abs(den_t[:, :, :3] - noisy_t[:, :, :3]).mean()) > 1e-3, "transparent film: colour denoised")
        check(float(np.abs(den_t[:, :, :3][a < 0.01]).max()) < 0.05,
              "transparent film: no colour leaks into transparent pixels")
        scene.render.film_transparent = False

        # no Denoising Data: every method still denoises (colour-guided)
        for vl in scene.view_layers:
            vl.cycles.denoising_store_passes = False
        s.method = "nbg"
        den_np = render(scene, os.path.join(tmp, "den_nopasses.exr"))
        p2 = psnr(den_np, ref)
        check(not engine.state["last_error"] and "colour-guided" in engine.state["last_note"] and p2 - p0 >= 0.1,
              "no passes, method nbg: %s, PSNR %.2f -> %.2f dB" % (engine.state["last_note"], p0, p2))
        s.method = "auto"
        for vl in scene.view_layers:
            vl.cycles.denoising_store_passes = True

        # a bad Library setting is refused with the reason, never replaced by another copy
        bad = os.path.join(tmp, "emptylib")
        os.makedirs(bad)
        runs = engine.state["runs"]
        s.library_path = bad
        ok, text = core.library_status(bad)
        check(not ok and "no libedgewise.so" in text, "empty Library folder refused at once: %s" % text)
        log = draw_panel(scene)
        check("refused" in alerts(log), "panel: red line for the bad library")
        try:
            bpy.ops.render.render()
            raised = ""
        except RuntimeError as e:
            raised = str(e)
        check("refused" in raised, "the render reports the refused library: %s" % raised)
        bad_out = save_result(scene, os.path.join(tmp, "badlib.exr"))
        check(engine.state["runs"] == runs and "refused" in engine.state["last_error"] and
              np.array_equal(bad_out, noisy), "render with a bad library: reported, left as rendered (%s)"
              % engine.state["last_error"])
        corrupt = os.path.join(tmp, "corruptlib")
        os.makedirs(corrupt)
        for n in core.LIB_NAMES:
            with open(os.path.join(corrupt, n), "wb") as f:
                f.write(b"\x7fELF" + b"\0" * 100)
        s.library_path = corrupt
        ok, text = core.library_status(corrupt)
        check(not ok and "refused" in text, "corrupt library refused: %s" % text)
        s.library_path = ""
        check(core.library_status()[0], "library back when the setting is cleared")
        again = render(scene, os.path.join(tmp, "again.exr"))
        check(np.array_equal(again, den), "denoised again, as before")

        # EEVEE: left alone with a note
        scene.render.engine = "BLENDER_EEVEE"
        log = draw_panel(scene)
        check(any("left alone" in t for k, t in log), "panel: one-line note for EEVEE")
        runs = engine.state["runs"]
        bpy.ops.render.render()
        check("left alone" in engine.state["last_note"] and engine.state["runs"] == runs and
              not engine.state["last_error"], "EEVEE render: note '%s', nothing denoised" % engine.state["last_note"])
        scene.render.engine = "CYCLES"

        check_enums_saved_by_identifier(tmp)
        scene = bpy.context.scene

        check(edgewise_temp_entries() == temp_before, "no temporary file left behind")
        if look:
            os.makedirs(look, exist_ok=True)
            for name, img in (("still_ref", ref), ("still_noisy", noisy), ("still_denoised", den),
                              ("still_inverted_composite", comped), ("still_transparent_alpha",
                                                                     np.repeat(den_t[:, :, 3:4], 4, axis=2)),
                              ("still_nopasses", den_np)):
                save_png(img, os.path.join(look, name + ".png"))
        addon_utils.disable("edgewise_denoise")
        cls = engine.cycles_engine_class()
        check(not hasattr(bpy.types.Scene, "edgewise") and getattr(cls.render, "_edgewise_orig", None) is None,
              "add-on disabled: Cycles' render() restored")
        print("timings: denoised still %.2f s (render + denoise), total %.2f s"
              % (t_den, time.perf_counter() - t_start))
    except Exception:
        traceback.print_exc()
        check(False, "exception")
    finish(tmp)


main()
