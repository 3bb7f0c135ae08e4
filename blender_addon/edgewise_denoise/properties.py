"""Scene settings. The method list and each method's parameters are
generated from the library's denoise-node descriptors at register time
(one property per method parameter, named <method>__<param>)."""
import bpy

from . import core

_generated = {}  # method -> [param dicts] the properties were made from


def _param_property(p):
    label = p.get("label") or p["name"]
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
    if t == "enum":
        return bpy.props.EnumProperty(name=label, description=desc, items=[(c, c, "") for c in p["choices"]],
                                      default=p["default"] or p["choices"][0])
    return None


def build_settings_class():
    try:
        ew = core.load_edgewise()
    except core.AddonLibraryError:
        ew = None
    methods = core.method_names(ew) if ew else core.FALLBACK_METHODS
    ann = {
        "enabled": bpy.props.BoolProperty(
            name="Denoise Renders", default=False,
            description="Denoise every still render (Edgewise Denoised image) and every animation frame "
                        "(<frame>_denoised.exr next to it)"),
        "method": bpy.props.EnumProperty(
            name="Method", items=[(m, m, "Edgewise denoiser '%s'" % m) for m in methods], default=methods[0],
            description="The library's denoiser"),
        "use_temporal": bpy.props.BoolProperty(
            name="Temporal (Animations)", default=False,
            description="After an animation render, accumulate each frame with its predecessors along the "
                        "Vector pass before denoising (needs the Vector pass and motion blur off)"),
        "threads": bpy.props.IntProperty(name="Threads", default=0, min=0, max=1024,
                                         description="CPU threads for the library (0: one per core)"),
        "library_path": bpy.props.StringProperty(
            name="Library", subtype="FILE_PATH", default="",
            description="Directory holding libedgewise.so (or its path); empty: bundled copy, "
                        "$EDGEWISE_LIB, or the repository's build/lib"),
    }
    _generated.clear()
    for m in methods:
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


def method_params(method):
    return _generated.get(method, [])


def settings_of(scene):
    """core.Settings from the scene's properties (call on the main thread)."""
    s = scene.edgewise
    params = dict((p["name"], getattr(s, "%s__%s" % (s.method, p["name"]))) for p in method_params(s.method))
    return core.Settings(method=s.method, params=params, threads=s.threads,
                         samples=scene.cycles.samples if hasattr(scene, "cycles") else 0,
                         library_path=bpy.path.abspath(s.library_path) if s.library_path else "")
