"""Render Properties panel: settings, and every problem as a red line that says what to do."""
import bpy

from . import core, engine
from .operators import missing_by_layer
from .properties import library_path_of, method_params


def _alert(layout, text, icon="ERROR"):
    row = layout.row()
    row.alert = True
    row.label(text=text, icon=icon)
    return row


def _wrapped(layout, text, width=70, alert=False, icon="NONE"):
    words, line, first = text.split(), "", True
    lines = []
    for w in words:
        if line and len(line) + 1 + len(w) > width:
            lines.append(line)
            line = w
        else:
            line = (line + " " + w) if line else w
    if line:
        lines.append(line)
    col = layout.column(align=True)
    col.alert = alert
    for t in lines:
        col.label(text=t, icon=icon if first else "BLANK1")
        first = False


def draw_settings(layout, context):
    scene = context.scene
    s = scene.edgewise
    if scene.render.engine != "CYCLES":
        layout.label(text="Edgewise denoises Cycles renders; %s renders are left alone" %
                     scene.render.engine.replace("BLENDER_", "").title(), icon="INFO")
        return
    ok, text = core.library_status(library_path_of(s))
    layout.prop(s, "enabled")
    if engine.cycles_denoise_fails(scene):
        _wrapped(layout, "Render > Denoise is on, but this Blender has no OpenImageDenoise: every render fails. "
                 "Turn it off; Edgewise denoises instead.", alert=True, icon="ERROR")
        layout.operator("edgewise.cycles_denoise_off", icon="CANCEL")
    col = layout.column()
    col.prop(s, "method")
    for p in method_params(s.method):
        col.prop(s, "%s__%s" % (s.method, p["name"]))
    col.prop(s, "use_temporal")
    if s.use_temporal and scene.render.use_motion_blur:
        _alert(col, "Temporal needs motion blur off (no Vector pass with it)")
    col.prop(s, "threads")
    row = col.row(align=True)
    row.prop(s, "library_path")
    row.operator("edgewise.reload_library", text="", icon="FILE_REFRESH")
    if ok:
        col.label(text=text, icon="CHECKMARK")
    else:
        _wrapped(layout, text, alert=True, icon="ERROR")
    missing = missing_by_layer(scene)
    if missing:
        box = layout.box()
        for layer, passes in missing.items():
            box.label(text="%s: no %s (colour-guided; passes help)" % (layer, ", ".join(passes)), icon="INFO")
        box.operator("edgewise.setup_passes")
    if engine.state["last_error"]:
        _wrapped(layout, engine.state["last_error"], alert=True, icon="ERROR")
    elif engine.state["last_note"]:
        layout.label(text="Last: " + engine.state["last_note"], icon="INFO")


class EDGEWISE_PT_render(bpy.types.Panel):
    bl_label = "Edgewise Denoise"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"

    def draw(self, context):
        draw_settings(self.layout, context)


classes = (EDGEWISE_PT_render,)
