"""Render Properties panel (Cycles) and Image Editor sidebar panel."""
import bpy

from . import core
from .handlers import state
from .operators import missing_by_layer
from .properties import method_params, settings_of


def draw_settings(layout, context):
    scene = context.scene
    s = scene.edgewise
    ok, text = core.library_status(settings_of(scene).library_path)
    layout.prop(s, "enabled")
    col = layout.column()
    col.prop(s, "method")
    for p in method_params(s.method):
        col.prop(s, "%s__%s" % (s.method, p["name"]))
    col.prop(s, "use_temporal")
    col.prop(s, "threads")
    col.prop(s, "library_path")
    if not ok:
        box = layout.box()
        box.label(text="Library missing", icon="ERROR")
        for i in range(0, len(text), 60):
            box.label(text=text[i:i + 60])
    missing = missing_by_layer(scene)
    if missing:
        box = layout.box()
        for layer, passes in missing.items():
            box.label(text="%s: missing %s" % (layer, ", ".join(passes)), icon="INFO")
        box.operator("edgewise.setup_passes")
    if scene.render.image_settings.file_format != "OPEN_EXR_MULTILAYER":
        layout.label(text="Animations: set Output to OpenEXR MultiLayer", icon="INFO")
    if state["last_error"]:
        layout.label(text=state["last_error"][:120], icon="ERROR")
    layout.operator("edgewise.denoise_render", icon="SHADERFX")


class EDGEWISE_PT_render(bpy.types.Panel):
    bl_label = "Edgewise Denoise"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"
    COMPAT_ENGINES = {"CYCLES"}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES

    def draw(self, context):
        draw_settings(self.layout, context)


class EDGEWISE_PT_image(bpy.types.Panel):
    bl_label = "Edgewise Denoise"
    bl_space_type = "IMAGE_EDITOR"
    bl_region_type = "UI"
    bl_category = "Edgewise"

    def draw(self, context):
        draw_settings(self.layout, context)


classes = (EDGEWISE_PT_render, EDGEWISE_PT_image)
