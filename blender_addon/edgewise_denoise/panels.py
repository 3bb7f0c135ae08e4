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


def text_width(context):
    """Characters that fit on one line of the panel (the Properties editor
    can be narrow; a label Blender cuts in the middle says nothing)."""
    region = getattr(context, "region", None)
    try:
        scale = bpy.context.preferences.system.ui_scale
    except AttributeError:
        scale = 1.0
    if region is None or not getattr(region, "width", 0):
        return 70
    return max(20, int((region.width - 50) / (6.5 * scale)))


def missing_text(labels):
    """'Denoising Data' for the three passes one switch gives."""
    data = [p for p in labels if p.startswith("Denoising ")]
    rest = [p for p in labels if not p.startswith("Denoising ")]
    return ", ".join((["Denoising Data"] if data else []) + rest)


def draw_settings(layout, context):
    scene = context.scene
    width = text_width(context)
    s = scene.edgewise
    if scene.render.engine != "CYCLES":
        layout.label(text="Edgewise denoises Cycles renders; %s renders are left alone" %
                     scene.render.engine.replace("BLENDER_", "").title(), icon="INFO")
        return
    ok, text = core.library_status(library_path_of(s))
    layout.prop(s, "enabled")
    if engine.cycles_denoise_fails(scene):
        _wrapped(layout, "Render > Denoise is on, but this Blender has no OpenImageDenoise: every render fails. "
                 "Turn it off; Edgewise denoises instead.", width, alert=True, icon="ERROR")
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
        _wrapped(layout, text, width, alert=True, icon="ERROR")
    missing = missing_by_layer(scene)
    if missing:
        box = layout.box()
        for layer, passes in missing.items():
            _wrapped(box, "%s: no %s" % (layer, missing_text(passes)), width, icon="INFO")
        why = []
        if any(p.startswith("Denoising ") for ps in missing.values() for p in ps):
            why.append("without Denoising Data every method denoises colour-guided (less detail)")
        if any("Vector" in ps for ps in missing.values()):
            why.append("temporal needs the Vector pass")
        _wrapped(box, "; ".join(why)[:1].upper() + "; ".join(why)[1:] + ".", width, icon="BLANK1")
        box.operator("edgewise.setup_passes")
    if engine.state["last_error"]:
        _wrapped(layout, engine.state["last_error"], width, alert=True, icon="ERROR")
    else:
        if engine.state["last_warning"]:
            _wrapped(layout, engine.state["last_warning"], width, alert=True, icon="ERROR")
        if engine.state["last_note"]:
            _wrapped(layout, "Last: " + engine.state["last_note"], width, icon="INFO")


class EDGEWISE_PT_render(bpy.types.Panel):
    bl_label = "Edgewise Denoise"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"

    def draw(self, context):
        draw_settings(self.layout, context)


classes = (EDGEWISE_PT_render,)
