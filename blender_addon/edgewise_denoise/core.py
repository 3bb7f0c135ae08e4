"""Pure-Python logic of the Edgewise Denoise add-on (no bpy import).

Everything here can be unit-tested with a plain python3: finding the
`edgewise` package and its libraries, the settings generated from the
library's node descriptors, which passes a method needs, output paths, and
the denoise jobs themselves (file in, array or file out, run by the
library, safe to call from a worker thread because they never touch bpy).
"""
import os
import sys
import tempfile
import threading

ADDON_DIR = os.path.dirname(os.path.abspath(__file__))
DENOISED_SUFFIX = "_denoised"
RESULT_IMAGE = "Edgewise Denoised"

# Blender view-layer switches that provide each library pass.
PASS_SOURCES = {
    "albedo": "denoising_store_passes",   # view_layer.cycles.denoising_store_passes
    "normal": "denoising_store_passes",
    "depth": "denoising_store_passes",
    "vector": "use_pass_vector",          # view_layer.use_pass_vector
}
PASS_LABELS = {"albedo": "Denoising Albedo", "normal": "Denoising Normal", "depth": "Denoising Depth",
               "vector": "Vector"}


class AddonLibraryError(RuntimeError):
    """The edgewise package or its libraries cannot be used; str() says why and what to do."""


def package_dirs(library_path=""):
    """Directories that may hold the `edgewise` Python package, in order:
    bundled inside the add-on, next to a configured library path, the
    repository's python/ (add-on used from the repo folder)."""
    dirs = [ADDON_DIR]
    if library_path:
        p = os.path.abspath(os.path.expanduser(library_path))
        d = p if os.path.isdir(p) else os.path.dirname(p)
        dirs += [d, os.path.join(d, "python")]
    env = os.environ.get("EDGEWISE_LIB")
    if env:
        d = env if os.path.isdir(env) else os.path.dirname(env)
        dirs.append(os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(d))), "python"))
    repo = os.path.dirname(os.path.dirname(ADDON_DIR))
    dirs.append(os.path.join(repo, "python"))
    out = []
    for d in dirs:
        if d not in out and os.path.isfile(os.path.join(d, "edgewise", "__init__.py")):
            out.append(d)
    return out


def _explain(err):
    text = str(err)
    if any(s in text for s in ("wrong ELF class", "invalid ELF header", "not a dynamic executable",
                               "mach-o", "file too short", "version `GLIBC")):
        return ("the Edgewise library was found but cannot be loaded on this platform (%s): "
                "it is not a library for this platform (built for another platform or architecture, or damaged); rebuild it here" % text)
    return text


_load_lock = threading.Lock()


def load_edgewise(library_path=""):
    """Import the `edgewise` package and load libedgewise. library_path (the
    add-on's setting) is a directory holding libedgewise.so, or the path of
    the library; it takes precedence over $EDGEWISE_LIB. Raises
    AddonLibraryError with a message meant for the user."""
    with _load_lock:
        if library_path:
            p = os.path.abspath(os.path.expanduser(library_path))
            if not os.path.exists(p):
                raise AddonLibraryError("Edgewise library path %r does not exist (Edgewise add-on settings)" % p)
            os.environ["EDGEWISE_LIB"] = p
        if "edgewise" not in sys.modules:
            dirs = package_dirs(library_path)
            if not dirs:
                raise AddonLibraryError(
                    "the Edgewise Python package was not found: install the add-on with the bundled "
                    "'edgewise' package and library, or use it from the repository (blender_addon/ next "
                    "to python/)")
            sys.path.insert(0, dirs[0])
        try:
            import edgewise
            from edgewise import _lib
            _lib.libs()
        except ImportError as e:
            raise AddonLibraryError("cannot import the Edgewise Python package: %s" % e)
        except OSError as e:  # LibraryNotFoundError is an OSError
            raise AddonLibraryError(_explain(e))
        return edgewise


def library_status(library_path=""):
    """(ok, text) for the panels: where the library is, or why it is missing."""
    try:
        ew = load_edgewise(library_path)
        return True, "libedgewise %s (%s)" % (ew.version(), ew.library_dir())
    except AddonLibraryError as e:
        return False, str(e)


# ---- settings generated from the descriptors ---------------------------------

FALLBACK_METHODS = ("auto",)


def method_names(ew=None):
    """The denoise node's 'method' choices (library introspection)."""
    try:
        ew = ew or load_edgewise()
        for p in ew.node_type("denoise")["params"]:
            if p["name"] == "method" and p.get("choices"):
                return tuple(p["choices"])
    except (AddonLibraryError, KeyError):
        pass
    return FALLBACK_METHODS


def method_params(method, ew=None):
    """Parameters of denoise method `method` other than 'method' itself (dicts as node_type gives)."""
    ew = ew or load_edgewise()
    return [p for p in ew.node_type("denoise", method)["params"] if p["name"] != "method"]


def method_inputs(method, ew=None):
    ew = ew or load_edgewise()
    return ew.node_type("denoise", method)["inputs"]


def needed_passes(method, temporal=False, ew=None):
    """Library pass names ("albedo", "normal", "depth", "vector") the method
    uses (required or optional guides); "vector" when temporal is on."""
    passes = [p["pass"] for p in method_inputs(method, ew) if p["pass"] in PASS_SOURCES]
    if temporal:
        passes.append("vector")
    out = []
    for p in passes:
        if p not in out:
            out.append(p)
    return out


def missing_passes(needed, layer_switches):
    """needed: library pass names; layer_switches: {switch name: bool} of a
    view layer. Returns the Blender labels of the passes that are missing."""
    return [PASS_LABELS[p] for p in needed if not layer_switches.get(PASS_SOURCES[p], False)]


def coerce_params(params, values):
    """Keep only values for known parameters, converted to their types and clamped to [min, max]."""
    out = {}
    for p in params:
        if p["name"] not in values:
            continue
        v = values[p["name"]]
        t = p["type"]
        if t == "bool":
            v = bool(v)
        elif t in ("int", "float"):
            v = int(round(v)) if t == "int" else float(v)
            if p.get("min") is not None:
                v = max(v, type(v)(p["min"]))
            if p.get("max") is not None:
                v = min(v, type(v)(p["max"]))
        elif t in ("enum", "string"):
            v = str(v)
            if t == "enum" and p.get("choices") and v not in p["choices"]:
                continue
        out[p["name"]] = v
    return out


# ---- paths --------------------------------------------------------------------

def denoised_path(path, layer=None, multi_layer=False):
    """Where the denoised copy of rendered file `path` goes: next to it,
    `<stem>_denoised.exr`, or `<stem>_denoised_<layer>.exr` when the render
    has several view layers."""
    d, name = os.path.split(path)
    stem = name.rsplit(".", 1)[0] if "." in name else name
    if multi_layer and layer:
        safe = "".join(c if c.isalnum() or c in "-_." else "_" for c in layer)
        return os.path.join(d, "%s%s_%s.exr" % (stem, DENOISED_SUFFIX, safe))
    return os.path.join(d, "%s%s.exr" % (stem, DENOISED_SUFFIX))


def sequence_pattern(path, frame):
    """Turn a rendered frame's path into the library's '#' pattern: the
    rightmost digit run of the file name whose value is `frame` becomes
    '#'s ("/r/shot_0007.exr", 7 -> "/r/shot_####.exr"). None if not found."""
    d, name = os.path.split(path)
    i = len(name)
    while i > 0:
        j = i
        while j > 0 and name[j - 1].isdigit():
            j -= 1
        if j < i and int(name[j:i]) == frame:
            return os.path.join(d, name[:j] + "#" * (i - j) + name[i:])
        i = j - 1 if j == i else j
    return None


def result_image_name(layer, n_layers):
    return RESULT_IMAGE if n_layers <= 1 else "%s - %s" % (RESULT_IMAGE, layer)


def temp_exr_path():
    fd, p = tempfile.mkstemp(prefix="edgewise_render_", suffix=".exr")
    os.close(fd)
    return p


# ---- denoise jobs (no bpy: safe in a worker thread) ---------------------------

class Settings(object):
    def __init__(self, method="auto", params=None, threads=0, samples=0, library_path=""):
        self.method = method
        self.params = dict(params or {})
        self.threads = int(threads)
        self.samples = int(samples)
        self.library_path = library_path


_devices = {}


def _device(ew, threads):
    if threads <= 0:
        return ew.default_device()
    if threads not in _devices:
        _devices[threads] = ew.Device(threads)
    return _devices[threads]


def _graph(ew, path, layer, settings):
    params = coerce_params(method_params(settings.method, ew), settings.params)
    if settings.samples > 0 and any(p["name"] == "samples" for p in method_params(settings.method, ew)):
        params.setdefault("samples", settings.samples)
    g = ew.Graph(_device(ew, settings.threads))
    rd = g.add("read", id="read", path=path, layer=layer or "")
    inputs = dict((p["name"], p) for p in method_inputs(settings.method, ew))
    kwargs = {"color": rd["color"]}
    for name in ("albedo", "normal", "depth"):
        if name in inputs:
            kwargs[name] = rd[name]
    g.add("denoise", id="denoise", method=settings.method, **dict(kwargs, **params))
    return g


def _finite_progress(progress, cancel, base, span):
    def cb(f):
        if cancel is not None and cancel.is_set():
            return False
        if progress is not None:
            progress(base + span * max(0.0, min(1.0, f)))
        return True
    return cb


def denoise_file(path, layers, settings, progress=None, cancel=None, methods=None):
    """Denoise view layers `layers` of multilayer EXR `path`. Returns
    {layer: (H, W, 4) float32 array, top row first} (alpha from Combined.A
    when present, else 1). progress(fraction); cancel: a threading.Event;
    methods: a dict that receives {layer: what the denoiser ran}, e.g. the
    model "auto" picked."""
    ew = load_edgewise(settings.library_path)
    out = {}
    for i, layer in enumerate(layers):
        g = _graph(ew, path, layer, settings)
        g.add("output", id="out", image=g.node("denoise")["output"])
        report = g.run(_finite_progress(progress, cancel, float(i) / len(layers), 1.0 / len(layers)))
        if methods is not None:
            methods[layer] = report["frames"][0].get("methods", {}).get("denoise", settings.method)
        rgb = g.output("out")
        h, w = rgb.shape[:2]
        import numpy as np
        rgba = np.ones((h, w, 4), np.float32)
        rgba[:, :, :3] = rgb[:, :, :3]
        out[layer] = rgba
    return out


def denoise_file_to_files(path, layers, settings, progress=None, cancel=None):
    """Denoise rendered frame `path` and write each layer next to it
    (denoised_path). Returns the written paths."""
    ew = load_edgewise(settings.library_path)
    written = []
    for i, layer in enumerate(layers):
        dst = denoised_path(path, layer, len(layers) > 1)
        g = _graph(ew, path, layer, settings)
        g.add("write", id="write", image=g.node("denoise")["output"], path=dst, layer=layer or "",
              pixel_type="float")
        g.run(_finite_progress(progress, cancel, float(i) / len(layers), 1.0 / len(layers)))
        written.append(dst)
    return written


def denoise_sequence(pattern, first, last, layers, settings, progress=None, cancel=None):
    """Temporal pass over rendered frames first..last of `pattern` ('#' =
    frame number): per view layer, one library graph reads each frame's
    colour, normal, depth and Vector, accumulates history along the motion
    vectors (temporal node), denoises the result and writes it next to the
    frame (denoised_path of the pattern), replacing the per-frame results.
    Returns the written patterns."""
    ew = load_edgewise(settings.library_path)
    written = []
    for i, layer in enumerate(layers):
        dst = denoised_path(pattern, layer, len(layers) > 1)
        params = coerce_params(method_params(settings.method, ew), settings.params)
        g = ew.Graph(_device(ew, settings.threads))
        rd = g.add("read", id="read", path=pattern, layer=layer or "")
        tp = g.add("temporal", id="temporal", color=rd["color"], normal=rd["normal"], depth=rd["depth"],
                   vector=rd["vector"])
        inputs = dict((p["name"], p) for p in method_inputs(settings.method, ew))
        kwargs = {"color": tp["output"]}
        for name in ("albedo", "normal", "depth"):
            if name in inputs:
                kwargs[name] = rd[name]
        g.add("denoise", id="denoise", method=settings.method, **dict(kwargs, **params))
        g.add("write", id="write", image=g.node("denoise")["output"], path=dst, layer=layer or "",
              pixel_type="float")
        g.set_frames(first, last)
        g.run(_finite_progress(progress, cancel, float(i) / len(layers), 1.0 / len(layers)))
        written.append(dst)
    return written


class Job(object):
    """A denoise run in a worker thread: poll() from the UI thread (a timer
    or a modal operator) to read progress and the result; cancel() stops it
    at the library's next progress check."""

    def __init__(self, fn, *args):
        self.progress = 0.0
        self.result = None
        self.error = None
        self.done = False
        self._cancel = threading.Event()
        self._args = args
        self._fn = fn
        self._thread = threading.Thread(target=self._run, daemon=True)

    def start(self):
        self._thread.start()
        return self

    def _set_progress(self, f):
        self.progress = f

    def _run(self):
        try:
            self.result = self._fn(*self._args, progress=self._set_progress, cancel=self._cancel)
        except BaseException as e:  # reported on the UI thread
            self.error = e
        finally:
            self.done = True

    def cancel(self):
        self._cancel.set()

    @property
    def cancelled(self):
        return self._cancel.is_set()

    def wait(self, timeout=None):
        self._thread.join(timeout)
        return self.done


def error_text(err):
    """The library's message for the report area."""
    name = getattr(err, "code_name", None)
    return "Edgewise: %s%s" % (err, " (%s)" % name if name else "")
