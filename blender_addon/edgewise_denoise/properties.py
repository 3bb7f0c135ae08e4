"""Scene settings. The method list and each method's parameters are
generated from the library's denoise-node descriptors (one property per
method parameter, named <method>__<param>), with the descriptors' labels and
choice names. The settings class is rebuilt when the library changes (the
Library setting, Reload Library), so a library set after install brings its
methods at once."""
import bpy

from . import core

_generated = {}  # method -> [param dicts] the properties were made from
_registered = {"cls": None}


def _param_property(p):
    label = p.get("label") or core.readable(p["name"])
    desc = p.get("hint") or ""
    t = p["type"]
    if t == "bool":
        return bpy.props.BoolProperty(name=label, description=desc, default=bool(p["default"]))
    if t == "int":
        return bpy.props.IntProperty(name=label, description=desc, default=int(p["default"]),
                                     min=int(p["min"]), max=int(p["max"]))
    if t == "float":
        return bpy.props.FloatProperty(name=label, description=desc, default=float(p["default"]),
                                       min=float(p["min"]), max=float(p["max"]))
    if t == "enum" and p.get("choices"):
        return bpy.props.EnumProperty(name=label, description=desc, items=core.enum_items(p),
                                      default=p["default"] if p.get("default") in p["choices"] else p["choices"][0])
    return None


def _library_changed(self, context):
    # Honour the new setting at once: forget the loaded library and rebuild
    # the settings (methods, parameters) from the new one, outside this callback.
    core.reset()
    bpy.app.timers.register(rebuild, first_interval=0.0)


def library_path_of(s):
    return bpy.path.abspath(s.library_path) if s.library_path else ""


def build_settings_class(library_path=""):
    try:
        ew = core.load_edgewise(library_path)
    except core.AddonLibraryError:
        ew = None
    items = core.method_items(ew) if ew else [(m, core.readable(m), "") for m in core.FALLBACK_METHODS]
    ann = {
        "enabled": bpy.props.BoolProperty(
            name="Denoise Renders", default=False,
            description="Denoise every Cycles render (F12 and each animation frame) before the compositor, the "
                        "render window and the output file see it, as Cycles' own Denoise does"),
        "method": bpy.props.EnumProperty(
            name="Method", items=items, default=items[0][0], description="The library's denoiser"),
        "use_temporal": bpy.props.BoolProperty(
            name="Temporal (Animations)", default=False,
            description="In animation renders, accumulate each frame with its predecessors along the Vector pass "
                        "(needs the Vector pass and motion blur off); never far from the per-frame result"),
        "threads": bpy.props.IntProperty(name="Threads", default=0, min=0, max=1024,
                                         description="CPU threads for the library (0: one per core)"),
        "library_path": bpy.props.StringProperty(
            name="Library", subtype="DIR_PATH", default="", update=_library_changed,
            description="Folder holding libedgewise.so; empty: $EDGEWISE_LIB, the bundled copy, or the "
                        "repository's build/lib. A folder set here is the only one used"),
    }
    _generated.clear()
    for m, _, _ in items:
        try:
            params = core.method_params(m, ew) if ew else []
        except Exception:
            params = []
        kept = []
        for p in params:
            if p["name"] == "samples":
                continue  # taken from the render's sample count
            prop = _param_property(p)
            if prop is not None:
                ann["%s__%s" % (m, p["name"])] = prop
                kept.append(p)
        _generated[m] = kept
    return type("EdgewiseSettings", (bpy.types.PropertyGroup,), {"__annotations__": ann})


def register(library_path=""):
    cls = build_settings_class(library_path)
    bpy.utils.register_class(cls)
    bpy.types.Scene.edgewise = bpy.props.PointerProperty(type=cls)
    _registered["cls"] = cls


def unregister():
    if _registered["cls"] is not None:
        del bpy.types.Scene.edgewise
        bpy.utils.unregister_class(_registered["cls"])
        _registered["cls"] = None


def rebuild():
    """Re-generate the settings from the library the current setting names
    (values persist: they are stored on the scene by name)."""
    scene = bpy.context.scene if bpy.context else None
    path = ""
    if scene is not None and hasattr(scene, "edgewise"):
        path = library_path_of(scene.edgewise)
    unregister()
    register(path)
    return None


def method_params(method):
    return _generated.get(method, [])


def settings_of(scene):
    """core.Settings from the scene's properties."""
    s = scene.edgewise
    params = dict((p["name"], getattr(s, "%s__%s" % (s.method, p["name"]))) for p in method_params(s.method))
    return core.Settings(method=s.method, params=params, threads=s.threads,
                         samples=scene.cycles.samples if hasattr(scene, "cycles") else 0,
                         library_path=library_path_of(s), temporal=s.use_temporal)
