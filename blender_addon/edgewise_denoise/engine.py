"""Denoising inside Cycles' render, where Blender's own Denoise checkbox works.

Cycles renders each view layer in its engine's render(depsgraph) method;
the compositor, the render window and the file output (stills and every
animation frame, in the user's format) all read the render result after
that. The add-on wraps that method: once Cycles has rendered a view layer,
its Combined pass is read from the render result (engine.get_result()),
denoised by libedgewise (with the layer's Denoising Data and, for
animations, the temporal history when they exist) and written back in place.
So everything downstream sees the denoised colour, exactly as with Cycles'
built-in denoiser; alpha and every other pass are left as Cycles wrote them.

This module runs in Blender's render thread: it reads the scene's settings
and calls the RenderEngine API only (report, update_stats, test_break).
"""
import time

import bpy
import numpy as np

from . import core

state = {
    "last_error": "",       # the last failure, for the panel's red line
    "last_warning": "",     # the last thing the user should change (the frame was still denoised)
    "redraw": False,        # the panel's lines changed during a render: redraw it (handlers.py)
    "last_note": "",        # what the last denoise did (layer: method, time)
    "histories": {},        # (view layer, view) -> core.TemporalHistory during an animation
    "runs": 0,              # layers denoised since the add-on was enabled (tests read it)
}


def cycles_engine_class():
    """The registered RenderEngine subclass whose bl_idname is CYCLES, or None."""
    stack = list(bpy.types.RenderEngine.__subclasses__())
    while stack:
        cls = stack.pop()
        if getattr(cls, "bl_idname", "") == "CYCLES":
            return cls
        stack += cls.__subclasses__()
    return None


def install():
    """Wrap Cycles' render() (idempotent; again after Cycles is reloaded)."""
    cls = cycles_engine_class()
    if cls is None or getattr(cls.render, "_edgewise_orig", None) is not None:
        return cls is not None
    orig = cls.render

    def render(self, depsgraph):
        orig(self, depsgraph)
        if not self.is_preview:
            after_layer(self, depsgraph)
    render._edgewise_orig = orig
    render.__doc__ = orig.__doc__
    cls.render = render
    return True


def uninstall():
    cls = cycles_engine_class()
    if cls is not None and getattr(cls.render, "_edgewise_orig", None) is not None:
        cls.render = cls.render._edgewise_orig
    state["histories"].clear()


def cycles_denoise_fails(scene):
    """True when Render > Denoise is on while this Blender has no denoiser
    for it (Debian's build: no OpenImageDenoise, no OptiX), so every render
    fails with "Build without OpenImageDenoiser"."""
    cyc = getattr(scene, "cycles", None)
    if cyc is None or not cyc.use_denoising:
        return False
    try:
        return len(cyc.bl_rna.properties["denoiser"].enum_items) == 0 and not _has_denoiser(cyc)
    except (KeyError, AttributeError):
        return False


def _has_denoiser(cyc):
    try:
        import _cycles
        return bool(getattr(_cycles, "with_openimagedenoise", False))
    except ImportError:
        return False


def layer_samples(scene, view_layer):
    if getattr(view_layer, "samples", 0) > 0:
        return view_layer.samples
    return scene.cycles.samples if hasattr(scene, "cycles") else 0


def _read(rpass, w, h):
    a = np.empty((w * h, rpass.channels), np.float32)
    rpass.rect.foreach_get(a)
    return np.ascontiguousarray(a.reshape(h, w, rpass.channels)[::-1])  # Blender's rows go bottom-up; ours top-down


def _find(passes, names, view):
    for n in names:
        p = passes.find_by_name(n, view)
        if p is not None:
            return p
    return None


def _report(engine, kind, msg):
    state["redraw"] = True
    try:
        engine.report({kind}, msg)
    except Exception:
        print(msg)


def report_error(engine, msg):
    """Where Blender shows render errors: the report (status bar, Info
    editor, console, the render window's header) and the panel's red line.
    Blender stops an animation render at a frame whose engine reported an
    error (that frame is not written): a failed denoise never leaves a
    sequence of noisy files that look finished."""
    state["last_error"] = msg
    _report(engine, "ERROR", msg)


def report_warning(engine, msg):
    """Something the user should change while the frame is still denoised:
    a warning that does not stop an animation, as an error would. Blender
    3.4 shows only a render engine's errors in the status bar, so the panel's
    red line and the console carry it."""
    state["last_warning"] = msg
    print(msg)
    _report(engine, "WARNING", msg)


def after_layer(engine, depsgraph):
    scene = depsgraph.scene
    s = getattr(scene, "edgewise", None)
    if s is None or not s.enabled:
        return
    from .properties import settings_of
    view_layer = depsgraph.view_layer
    if cycles_denoise_fails(scene):
        report_error(engine, "Edgewise: Render > Denoise is on, and this Blender cannot run it (no OpenImageDenoise): "
                     "turn it off (Edgewise panel: Turn Off Cycles Denoise); Edgewise denoises instead")
        return
    try:
        settings = settings_of(scene)
        settings.samples = layer_samples(scene, view_layer)
        ew = core.load_edgewise(settings.library_path)
    except Exception as e:
        report_error(engine, core.error_text(e))
        return
    rr = engine.get_result()
    layer = rr.layers.get(view_layer.name) if hasattr(rr.layers, "get") else rr.layers[view_layer.name]
    if layer is None:
        return
    w, h = rr.resolution_x, rr.resolution_y
    views = [v.name for v in rr.views] or [""]
    for view in views:
        if engine.test_break():
            return
        t0 = time.perf_counter()
        combined = layer.passes.find_by_name("Combined", view)
        if combined is None:
            continue
        passes = {"color": _read(combined, w, h)}
        for k in ("albedo", "normal", "depth", "vector"):
            p = _find(layer.passes, core.BLENDER_PASSES[k], view)
            if p is not None:
                passes[k] = _read(p, w, h)
        where = view_layer.name + (" (%s)" % view if len(views) > 1 else "")

        def progress(f, where=where):
            engine.update_stats("", "Edgewise: denoising %s %d%%" % (where, 100 * f))
            engine.update_progress(f)
            return not engine.test_break()
        try:
            history = None
            if s.use_temporal and engine.is_animation and passes.get("vector") is not None:
                key = (view_layer.name, view)
                history = state["histories"].get(key)
                if history is None or history.ew is not ew:
                    history = state["histories"][key] = core.TemporalHistory(ew, settings.threads)
            rgba, ran = core.denoise_frame(passes, settings, scene.frame_current, history, progress, ew)
        except Exception as e:
            if engine.test_break():
                return
            report_error(engine, "Edgewise: %s not denoised: %s" % (where, core.error_text(e)))
            continue
        combined.rect.foreach_set(np.ascontiguousarray(rgba[::-1]).reshape(w * h, 4))
        state["runs"] += 1
        state["last_error"] = ""
        note = "%s: %s, %.2f s" % (where, ran, time.perf_counter() - t0)
        state["last_note"] = note
        engine.update_stats("", "Edgewise: denoised " + note)
        state["redraw"] = True  # the panel's Last line (Blender shows no engine info in the status bar)
        print("Edgewise: denoised " + note)  # beside Cycles' own lines in the console (blender -b -a)
        if s.use_temporal and engine.is_animation and passes.get("vector") is None:
            report_warning(engine, "Edgewise: temporal off for %s (each frame denoised alone): no Vector pass; "
                           "the panel's Enable Passes turns it on and motion blur off" % where)
