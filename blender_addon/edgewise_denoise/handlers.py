"""render_init / render_complete / render_cancel handlers: a new render
starts a new temporal history; Cycles' render() is wrapped again if Cycles
was reloaded; an engine Edgewise does not handle gets a one-line note."""
import bpy
from bpy.app.handlers import persistent

from . import engine


@persistent
def on_render_init(scene, *args):
    engine.state["histories"].clear()
    s = getattr(scene, "edgewise", None)
    if s is None or not s.enabled:
        return
    if scene.render.engine != "CYCLES":
        engine.state["last_note"] = "%s render left alone (Edgewise denoises Cycles renders)" % scene.render.engine
        print("Edgewise: " + engine.state["last_note"])
        return
    engine.state["last_error"] = ""
    if not engine.install():
        engine.state["last_error"] = "Edgewise: the Cycles add-on is not enabled; nothing was denoised"


@persistent
def on_render_end(scene, *args):
    engine.state["histories"].clear()  # the library's history buffers go with it


_HANDLERS = (("render_init", on_render_init), ("render_complete", on_render_end),
             ("render_cancel", on_render_end))


def register():
    for name, fn in _HANDLERS:
        lst = getattr(bpy.app.handlers, name)
        if fn not in lst:
            lst.append(fn)


def unregister():
    for name, fn in _HANDLERS:
        lst = getattr(bpy.app.handlers, name)
        if fn in lst:
            lst.remove(fn)
