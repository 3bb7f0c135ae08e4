"""Operators: set up passes, denoise the current render (still)."""
import os

import bpy

from . import core
from .properties import settings_of


def render_layers(scene):
    return [vl.name for vl in scene.view_layers if vl.use]


def layer_switches(view_layer):
    return {"denoising_store_passes": bool(view_layer.cycles.denoising_store_passes),
            "use_pass_vector": bool(view_layer.use_pass_vector)}


def missing_by_layer(scene):
    s = scene.edgewise
    try:
        needed = core.needed_passes(s.method, s.use_temporal, ew=core.load_edgewise(settings_of(scene).library_path))
    except Exception:
        needed = ["albedo", "normal", "depth"]
    out = {}
    for vl in scene.view_layers:
        m = core.missing_passes(needed, layer_switches(vl))
        if m:
            out[vl.name] = m
    return out


def save_render_exr(scene, path):
    """Save Render Result (every view layer and pass) as a multilayer EXR."""
    img = bpy.data.images.get("Render Result")
    if img is None or not img.has_data and img.type != "RENDER_RESULT":
        raise RuntimeError("there is no render result to denoise: render first (F12)")
    fmt = scene.render.image_settings
    old = (fmt.file_format, fmt.color_depth, fmt.exr_codec)
    try:
        fmt.file_format = "OPEN_EXR_MULTILAYER"
        fmt.color_depth = "32"
        fmt.exr_codec = "ZIP"
        img.save_render(path, scene=scene)
    finally:
        fmt.file_format, fmt.color_depth, fmt.exr_codec = old
    return path


def apply_results(results, n_layers):
    """Create/replace one float Image per view layer (main thread only)."""
    images = []
    for layer, rgba in results.items():
        name = core.result_image_name(layer, n_layers)
        h, w = rgba.shape[:2]
        img = bpy.data.images.get(name)
        if img is not None and (img.size[0] != w or img.size[1] != h):
            bpy.data.images.remove(img)
            img = None
        if img is None:
            img = bpy.data.images.new(name, w, h, alpha=True, float_buffer=True)
        img.pixels.foreach_set(rgba[::-1].ravel())  # Blender's rows go bottom-up
        img.update()
        images.append(img)
    return images


def start_still_job(scene):
    """Main thread: save the render, start the library job in a worker thread."""
    settings = settings_of(scene)
    core.load_edgewise(settings.library_path)  # clear message early
    path = save_render_exr(scene, core.temp_exr_path())
    layers = render_layers(scene)

    methods = {}

    def run(progress=None, cancel=None):
        try:
            return core.denoise_file(path, layers, settings, progress=progress, cancel=cancel, methods=methods)
        finally:
            try:
                os.remove(path)
            except OSError:
                pass
    job = core.Job(run)
    job.methods = methods  # {layer: what ran}, filled by the worker
    return job, layers


class EDGEWISE_OT_setup_passes(bpy.types.Operator):
    """Turn on the passes the chosen method needs in every view layer (and turn off Cycles' own denoiser,
    which this Blender build cannot run)"""
    bl_idname = "edgewise.setup_passes"
    bl_label = "Enable Needed Passes"
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
        self.report({"INFO"}, "Edgewise: denoising passes enabled in %d view layer(s)" % len(scene.view_layers))
        return {"FINISHED"}


class EDGEWISE_OT_denoise_render(bpy.types.Operator):
    """Denoise every view layer of the current render into 'Edgewise Denoised' images (the render is kept)"""
    bl_idname = "edgewise.denoise_render"
    bl_label = "Denoise Render"

    _job = None
    _timer = None

    def execute(self, context):  # synchronous (scripts, background mode)
        try:
            job, layers = start_still_job(context.scene)
            job.start().wait()
        except Exception as e:
            self.report({"ERROR"}, core.error_text(e))
            return {"CANCELLED"}
        return self._finish(job, layers)

    def _finish(self, job, layers):
        if job.error is not None:
            self.report({"WARNING"} if job.cancelled else {"ERROR"},
                        "Edgewise: cancelled" if job.cancelled else core.error_text(job.error))
            return {"CANCELLED"}
        imgs = apply_results(job.result, len(layers))
        used = sorted(set(getattr(job, "methods", {}).values()))
        self.report({"INFO"}, "Edgewise: denoised %s%s" % (", ".join(i.name for i in imgs),
                                                          " with " + "; ".join(used) if used else ""))
        return {"FINISHED"}

    def invoke(self, context, event):  # interactive: worker thread + modal timer, Esc cancels
        try:
            self._job, self._layers = start_still_job(context.scene)
        except Exception as e:
            self.report({"ERROR"}, core.error_text(e))
            return {"CANCELLED"}
        self._job.start()
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.progress_begin(0, 100)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        wm = context.window_manager
        if event.type == "ESC":
            self._job.cancel()
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        wm.progress_update(int(self._job.progress * 100))
        if context.area:
            context.area.header_text_set("Edgewise: denoising %d%% (Esc to cancel)" % (self._job.progress * 100))
        if not self._job.done:
            return {"RUNNING_MODAL"}
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        if context.area:
            context.area.header_text_set(None)
        return self._finish(self._job, self._layers)


classes = (EDGEWISE_OT_setup_passes, EDGEWISE_OT_denoise_render)
