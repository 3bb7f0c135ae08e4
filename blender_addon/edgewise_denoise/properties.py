"""Scene settings. The method list and each method's parameters are
generated from the library's denoise-node descriptors (one property per
method parameter, named <method>__<param>), with the descriptors' labels and
choice names. The settings class is rebuilt when the library changes (the
Library setting, Reload Library), so a library set after install brings its
methods at once.

Enum settings (the method, a method's model or quality) are saved in the
.blend by the choice's identifier, not by its position in the list: the list
comes from whichever library is loaded, and a library that orders its choices
differently must not change a saved scene's choice. Blender's EnumProperty
stores a position, so these enums read and write a string of their own
(core.stored_enum_index says how a saved value is read, older files' positions
included)."""
import bpy

from . import core

_generated = {}  # method -> [param dicts] the properties were made from
_registered = {"cls": None}


def enum_by_identifier(key, items, default, **kw):
    """An EnumProperty over items whose value is saved as the chosen
    identifier under the ID property `key` (the property's own name)."""
    ids = [it[0] for it in items]
    if default not in ids:
        default = ids[0]

    def get(self):
        return core.stored_enum_index(self.get(key), ids, default)

    def set(self, index):
        self[key] = ids[index]
    return bpy.props.EnumProperty(items=items, default=default, get=get, set=set, **kw)


def _param_property(key, p):
    label = core.param_label(p)
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
        return enum_by_identifier(key, core.enum_items(p), p.get("default"), name=label, description=desc)
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
        "method": enum_by_identifier("method", items, items[0][0], name="Method",
                                     description="The library's denoiser"),
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
            key = "%s__%s" % (m, p["name"])
            prop = _param_property(key, p)
            if prop is not None:
                ann[key] = prop
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
