"""render_init / render_complete / render_cancel handlers: a new render
starts a new temporal history; Cycles' render() is wrapped again if Cycles
was reloaded; an engine Edgewise does not handle gets a one-line note.
A timer on the main thread redraws the Edgewise panel when a render changed
its lines (the render thread must not touch the UI, and Blender redraws
the Properties editor only when the mouse moves over it)."""
import bpy
from bpy.app.handlers import persistent

from . import engine


@persistent
def on_render_init(scene, *args):
    engine.state["histories"].clear()
    s = getattr(scene, "edgewise", None)
    if s is None or not s.enabled:
        return
    engine.state["last_warning"] = ""
    if scene.render.engine != "CYCLES":
        try:
            name = scene.render.bl_rna.properties["engine"].enum_items[scene.render.engine].name
        except (KeyError, AttributeError):
            name = scene.render.engine
        engine.state["last_note"] = "%s render left alone (Edgewise denoises Cycles renders)" % name
        engine.state["redraw"] = True
        print("Edgewise: " + engine.state["last_note"])
        return
    engine.state["last_error"] = ""
    if not engine.install():
        engine.state["last_error"] = "Edgewise: the Cycles add-on is not enabled; nothing was denoised"


@persistent
def on_render_end(scene, *args):
    engine.state["histories"].clear()  # the library's history buffers go with it


REDRAW_INTERVAL = 0.5  # seconds


def redraw_panel():
    """Timer: tag the Properties editors for redraw after a render changed the panel's lines."""
    if engine.state["redraw"]:
        engine.state["redraw"] = False
        wm = getattr(bpy.context, "window_manager", None)
        for win in (wm.windows if wm else ()):
            for area in win.screen.areas:
                if area.type == "PROPERTIES":
                    area.tag_redraw()
    return REDRAW_INTERVAL


_HANDLERS = (("render_init", on_render_init), ("render_complete", on_render_end),
             ("render_cancel", on_render_end))


def register():
    for name, fn in _HANDLERS:
        lst = getattr(bpy.app.handlers, name)
        if fn not in lst:
            lst.append(fn)
    if not bpy.app.background and not bpy.app.timers.is_registered(redraw_panel):
        bpy.app.timers.register(redraw_panel, first_interval=REDRAW_INTERVAL, persistent=True)


def unregister():
    for name, fn in _HANDLERS:
        lst = getattr(bpy.app.handlers, name)
        if fn in lst:
            lst.remove(fn)
    if bpy.app.timers.is_registered(redraw_panel):
        bpy.app.timers.unregister(redraw_panel)
