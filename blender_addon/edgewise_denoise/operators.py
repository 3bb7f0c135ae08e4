"""Operators: set up passes, turn off Cycles' own denoiser, reload the library."""
import bpy

from . import core
from .properties import library_path_of


def layer_switches(view_layer):
    return {"denoising_store_passes": bool(view_layer.cycles.denoising_store_passes),
            "use_pass_vector": bool(view_layer.use_pass_vector)}


def missing_by_layer(scene):
    """{view layer: [Blender pass labels]} the chosen method (and temporal)
    would use but the layer does not render. Nothing fails without them:
    colour-guided methods run instead; this is advice."""
    s = scene.edgewise
    try:
        needed = core.needed_passes(s.method, s.use_temporal, ew=core.load_edgewise(library_path_of(s)))
    except Exception:
        needed = ["albedo", "normal", "depth"] + (["vector"] if s.use_temporal else [])
    out = {}
    for vl in scene.view_layers:
        if not vl.use:
            continue
        m = core.missing_passes(needed, layer_switches(vl))
        if m:
            out[vl.name] = m
    return out


class EDGEWISE_OT_setup_passes(bpy.types.Operator):
    """Turn on the passes the chosen method uses in every view layer (Denoising Data; the Vector pass and
    motion blur off for temporal) and turn off Cycles' own denoiser, which this Blender cannot run"""
    bl_idname = "edgewise.setup_passes"
    bl_label = "Enable Passes"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        scene = context.scene
        if hasattr(scene, "cycles"):
            scene.cycles.use_denoising = False
        for vl in scene.view_layers:
            vl.cycles.denoising_store_passes = True
            vl.cycles.use_denoising = False
            if scene.edgewise.use_temporal:
                vl.use_pass_vector = True
        if scene.edgewise.use_temporal:
            scene.render.use_motion_blur = False  # Cycles writes no Vector pass with motion blur
        self.report({"INFO"}, "Edgewise: passes enabled in %d view layer(s)" % len(scene.view_layers))
        return {"FINISHED"}


class EDGEWISE_OT_cycles_denoise_off(bpy.types.Operator):
    """Turn off Render > Denoise (Cycles' own denoiser): this Blender has no OpenImageDenoise or OptiX, so with
    it on every render fails"""
    bl_idname = "edgewise.cycles_denoise_off"
    bl_label = "Turn Off Cycles Denoise"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        scene = context.scene
        scene.cycles.use_denoising = False
        for vl in scene.view_layers:
            vl.cycles.use_denoising = False
        self.report({"INFO"}, "Edgewise: Cycles' Denoise turned off; Edgewise denoises the renders")
        return {"FINISHED"}


class EDGEWISE_OT_reload_library(bpy.types.Operator):
    """Load the Edgewise library again (after a rebuild, or a new Library setting) and regenerate the methods"""
    bl_idname = "edgewise.reload_library"
    bl_label = "Reload Library"

    def execute(self, context):
        from . import properties
        core.reset()
        properties.rebuild()
        ok, text = core.library_status(library_path_of(context.scene.edgewise))
        self.report({"INFO"} if ok else {"ERROR"}, ("Edgewise: " + text) if ok else text)
        return {"FINISHED"} if ok else {"CANCELLED"}


classes = (EDGEWISE_OT_setup_passes, EDGEWISE_OT_cycles_denoise_off, EDGEWISE_OT_reload_library)
