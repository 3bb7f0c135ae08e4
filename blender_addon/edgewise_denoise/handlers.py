"""render_init / render_write / render_complete handlers.

Animation frames are denoised as they are written (render_write), each
into <frame>_denoised.exr next to it. A still (render_complete with at most
one written frame) is denoised into the 'Edgewise Denoised' image(s):
synchronously in background mode, else through a worker thread polled by a
main-thread timer (bpy is only touched on the main thread).
"""
import bpy
from bpy.app.handlers import persistent

from . import core
from .properties import settings_of

state = {"frames": 0, "last_error": "", "written": [], "first_path": None, "first": None, "last": None}


def _log_error(msg):
    state["last_error"] = msg
    print(msg)


@persistent
def on_render_init(scene, *args):
    state["frames"] = 0
    state["written"] = []
    state["first_path"] = state["first"] = state["last"] = None


@persistent
def on_render_write(scene, *args):
    state["frames"] += 1
    if state["first"] is None:
        state["first"] = scene.frame_current
        state["first_path"] = bpy.path.abspath(scene.render.frame_path(frame=scene.frame_current))
    state["last"] = scene.frame_current
    s = getattr(scene, "edgewise", None)
    if s is None or not s.enabled:
        return
    if scene.render.image_settings.file_format != "OPEN_EXR_MULTILAYER":
        _log_error("Edgewise: frame not denoised: set the output format to OpenEXR MultiLayer "
                   "(the denoiser reads the render's passes from the file)")
        return
    path = bpy.path.abspath(scene.render.frame_path(frame=scene.frame_current))
    layers = [vl.name for vl in scene.view_layers if vl.use]
    try:
        state["written"] += core.denoise_file_to_files(path, layers, settings_of(scene))
    except Exception as e:
        _log_error(core.error_text(e))


def _poll_job(job, layers):
    from .operators import apply_results
    if not job.done:
        return 0.2
    if job.error is not None:
        _log_error(core.error_text(job.error))
    else:
        apply_results(job.result, len(layers))
    return None


def _temporal(scene):
    """After an animation: the temporal pass over the written frames."""
    pattern = core.sequence_pattern(state["first_path"], state["first"])
    if pattern is None:
        _log_error("Edgewise: temporal pass skipped: no frame number in %s" % state["first_path"])
        return
    layers = [vl.name for vl in scene.view_layers if vl.use]
    settings = settings_of(scene)
    settings.samples = 0  # accumulated frames: let the library estimate the noise
    args = (pattern, state["first"], state["last"], layers, settings)
    if bpy.app.background:
        try:
            state["written"] = core.denoise_sequence(*args)
        except Exception as e:
            _log_error(core.error_text(e))
        return
    job = core.Job(core.denoise_sequence, *args).start()

    def poll():
        if not job.done:
            return 0.5
        if job.error is not None:
            _log_error(core.error_text(job.error))
        return None
    bpy.app.timers.register(poll, first_interval=0.5)


@persistent
def on_render_complete(scene, *args):
    s = getattr(scene, "edgewise", None)
    if s is None or not s.enabled:
        return
    if state["frames"] > 1:
        if s.use_temporal and scene.render.image_settings.file_format == "OPEN_EXR_MULTILAYER":
            _temporal(scene)
        return
    from .operators import apply_results, start_still_job
    if bpy.app.background:
        try:
            job, layers = start_still_job(scene)
            job.start().wait()
            if job.error is not None:
                raise job.error
            apply_results(job.result, len(layers))
        except Exception as e:
            _log_error(core.error_text(e))
        return

    def start():
        try:
            job, layers = start_still_job(bpy.context.scene)
        except Exception as e:
            _log_error(core.error_text(e))
            return None
        job.start()
        bpy.app.timers.register(lambda: _poll_job(job, layers), first_interval=0.2)
        return None
    bpy.app.timers.register(start, first_interval=0.1)


_HANDLERS = (("render_init", on_render_init), ("render_write", on_render_write),
             ("render_complete", on_render_complete))


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
