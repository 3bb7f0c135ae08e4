"""Pure-Python logic of the Edgewise Denoise add-on (no bpy import).

Everything here can be unit-tested with a plain python3: finding and loading
the `edgewise` package and its libraries (without touching sys.path), the
settings generated from the library's node descriptors, which passes a
method uses, and the denoising itself on numpy arrays, as the render engine
hands them over (engine.py). Nothing here touches bpy, so it is safe in
Blender's render thread.
"""
import ctypes
import importlib.util
import os
import sys
import threading

# realpath: a developer install is a symlink into Blender's add-ons folder;
# the repository (python/edgewise, build/lib) is found from the link's target.
ADDON_DIR = os.path.dirname(os.path.realpath(__file__))
REPO_DIR = os.path.dirname(os.path.dirname(ADDON_DIR))
LIB_NAMES = ("libedgewise.so", "libedgewise_nodes.so")

# Blender view-layer switches that provide each library pass.
PASS_SOURCES = {
    "albedo": "denoising_store_passes",   # view_layer.cycles.denoising_store_passes
    "normal": "denoising_store_passes",
    "depth": "denoising_store_passes",
    "vector": "use_pass_vector",          # view_layer.use_pass_vector
}
PASS_LABELS = {"albedo": "Denoising Albedo", "normal": "Denoising Normal", "depth": "Denoising Depth",
               "vector": "Vector"}
# Render-result pass names read for each library pass, in order of preference
# (as the library's read node does for files).
BLENDER_PASSES = {
    "albedo": ("Denoising Albedo", "DiffCol"),
    "normal": ("Denoising Normal",),
    "depth": ("Denoising Depth",),
    "vector": ("Vector",),
}


class AddonLibraryError(RuntimeError):
    """The edgewise package or its libraries cannot be used; str() says why and what to do."""


# ---- finding and loading the package and the library ------------------------

def package_dir():
    """The directory holding the `edgewise` package: the copy bundled inside
    the add-on (zip install), else the repository's python/ (used from the repo)."""
    for d in (ADDON_DIR, os.path.join(REPO_DIR, "python")):
        if os.path.isfile(os.path.join(d, "edgewise", "__init__.py")):
            return d
    return None


def library_candidates(library_path=""):
    """Directories to load libedgewise from. The Library setting, when set, is
    the only candidate: a bad setting is refused, never replaced silently by
    another copy. Otherwise $EDGEWISE_LIB, the bundled copy, the repo's build/lib."""
    if library_path:
        p = os.path.realpath(os.path.expanduser(library_path))
        return [p if os.path.isdir(p) else os.path.dirname(p)]
    dirs = []
    env = os.environ.get("EDGEWISE_LIB")
    if env:
        dirs.append(os.path.realpath(env if os.path.isdir(env) else os.path.dirname(os.path.abspath(env))))
    dirs += [os.path.join(ADDON_DIR, "edgewise"), os.path.join(REPO_DIR, "build", "lib")]
    return dirs


def _explain(err):
    text = str(err)
    if any(s in text for s in ("wrong ELF class", "invalid ELF header", "not a dynamic executable",
                               "mach-o", "file too short", "version `GLIBC", "ELF load command")):
        return ("the Edgewise library was found but cannot be loaded on this platform (%s): "
                "it is not a library for this platform (built for another platform or architecture, or damaged); "
                "rebuild it here" % text)
    return text


def check_library_dir(d):
    """None when directory d holds loadable Edgewise libraries, else why not
    (a sentence for the panel). Loads them with ctypes: a damaged or foreign
    file fails here with the loader's reason, nothing else happens."""
    if not os.path.exists(d):
        return "Library folder %s does not exist" % d
    if not os.path.isdir(d):
        return "Library %s is not a folder" % d
    missing = [n for n in LIB_NAMES if not os.path.isfile(os.path.join(d, n))]
    if missing:
        return "no %s in %s: point Library at the folder holding the built libraries (build/lib)" % (
            " or ".join(missing), d)
    try:
        core = ctypes.CDLL(os.path.join(d, LIB_NAMES[0]))
        ctypes.CDLL(os.path.join(d, LIB_NAMES[1]))
        core.ew_version_string
    except (OSError, AttributeError) as e:
        return _explain(e)
    return None


_lock = threading.Lock()
_loaded = {"key": None, "ew": None, "error": None, "count": 0}


def _import_package(pkg_dir, lib_dir):
    """A private instance of the `edgewise` package, bound to the libraries in
    lib_dir. Imported under this add-on's own module name (nothing is added to
    sys.path and `import edgewise` elsewhere in Blender is unaffected)."""
    _loaded["count"] += 1
    base = __package__ or "edgewise_denoise"
    name = "%s._edgewise%d" % (base, _loaded["count"])
    init = os.path.join(pkg_dir, "edgewise", "__init__.py")
    spec = importlib.util.spec_from_file_location(name, init,
                                                  submodule_search_locations=[os.path.dirname(init)])
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    try:
        spec.loader.exec_module(mod)
        lib = sys.modules[name + "._lib"]
        lib._candidate_dirs = lambda: [lib_dir]  # this instance loads this library, nothing else
        lib.libs()
    except BaseException:
        for k in [k for k in sys.modules if k == name or k.startswith(name + ".")]:
            del sys.modules[k]
        raise
    return mod


def load_edgewise(library_path=""):
    """The `edgewise` package bound to libedgewise. library_path (the add-on's
    Library setting) is a directory holding libedgewise.so, or the path of the
    library; when set, it is the only library used. The result is cached per
    setting; a changed setting loads the new library at once (see reset()).
    Raises AddonLibraryError with a message meant for the user."""
    key = library_path or ""
    with _lock:
        if _loaded["key"] == key:
            if _loaded["ew"] is not None:
                return _loaded["ew"]
            raise AddonLibraryError(_loaded["error"])
        ew, error = None, None
        pkg = package_dir()
        if pkg is None:
            error = ("the Edgewise Python package was not found: install the add-on zip (it bundles the package "
                     "and the library), or use the add-on from the repository (blender_addon/ next to python/)")
        else:
            reasons = []
            for d in library_candidates(library_path):
                why = check_library_dir(d)
                if why is None:
                    try:
                        ew = _import_package(pkg, d)
                        break
                    except (ImportError, OSError, AttributeError) as e:
                        why = _explain(e)
                reasons.append(why)
                if library_path:
                    break
            if ew is None:
                if library_path:
                    error = "Library setting refused: %s" % reasons[0]
                else:
                    error = ("libedgewise not found (looked in: %s). Build the project (cmake --build build) or "
                             "set Library to the folder holding libedgewise.so" % "; ".join(reasons))
        _loaded.update(key=key, ew=ew, error=error)
        if ew is None:
            raise AddonLibraryError(error)
        return ew


def reset():
    """Forget the loaded library: the next load_edgewise() resolves the
    setting again (called when the Library setting changes and by Reload)."""
    with _lock:
        _loaded.update(key=None, ew=None, error=None)


def library_status(library_path=""):
    """(ok, text) for the panels: where the library is, or why it is refused."""
    try:
        ew = load_edgewise(library_path)
        return True, "libedgewise %s (%s)" % (ew.version(), ew.library_dir())
    except AddonLibraryError as e:
        return False, str(e)


# ---- settings generated from the descriptors ---------------------------------

FALLBACK_METHODS = ("auto",)


def readable(name):
    """A label for a descriptor name that has none: "firefly_k" -> "Firefly K";
    a word without vowels is an abbreviation: "nbg" -> "NBG"."""
    def word(w):
        if w.isalpha() and not any(c in "aeiouy" for c in w.lower()):
            return w.upper()
        return w[:1].upper() + w[1:]
    return " ".join(word(w) for w in name.replace("-", " ").replace("_", " ").split())


def method_summaries(ew):
    """{method: the library's one-line description} (ew_method_get), for
    the Method list's tooltips; {} when the library cannot say."""
    import ctypes
    out = {}
    try:
        lib = sys.modules[ew.__name__ + "._lib"].libs()[0]
        f = lib.ew_method_get
        f.restype = ctypes.c_int32
        f.argtypes = [ctypes.c_char_p, ctypes.c_int32, ctypes.POINTER(ctypes.c_char_p),
                      ctypes.POINTER(ctypes.c_char_p), ctypes.POINTER(ctypes.c_int32), ctypes.POINTER(ctypes.c_int32)]
        lib.ew_method_count.restype = ctypes.c_int32
        lib.ew_method_count.argtypes = [ctypes.c_char_p]
        for i in range(lib.ew_method_count(b"denoiser")):
            name, summary = ctypes.c_char_p(), ctypes.c_char_p()
            ni, np_ = ctypes.c_int32(), ctypes.c_int32()
            if f(b"denoiser", i, ctypes.byref(name), ctypes.byref(summary), ctypes.byref(ni), ctypes.byref(np_)) == 0:
                if name.value and summary.value:
                    out[name.value.decode()] = summary.value.decode()
    except (KeyError, AttributeError, OSError):
        pass
    return out


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


def method_items(ew=None):
    """(identifier, label, description) of each method for an EnumProperty:
    the label is the descriptor's choice name when the library gives one,
    the description the method's summary."""
    out = []
    names = method_names(ew)
    labels = {}
    try:
        ew = ew or load_edgewise()
        for p in ew.node_type("denoise")["params"]:
            if p["name"] == "method":
                labels = dict(zip(p.get("choices") or (), p.get("choice_labels") or p.get("choice_names") or ()))
    except (AddonLibraryError, KeyError):
        ew = None
    summaries = method_summaries(ew) if ew is not None else {}
    for m in names:
        summary = summaries.get(m, "")
        out.append((m, labels.get(m) or readable(m), summary or "Edgewise denoiser '%s'" % m))
    return out


def param_label(p):
    """The label shown for a descriptor parameter: its label when it is more
    than the raw name ("Method"), else a readable form of the name
    ("quality" -> "Quality", "firefly_k" -> "Firefly K")."""
    label = p.get("label") or ""
    return label if label and label != p["name"] else readable(p["name"])


def stored_enum_index(stored, identifiers, default):
    """The position in `identifiers` (the choices as the library lists them
    now) of an enum setting saved in a .blend. The add-on stores the choice's
    identifier (a string), so a library that reorders, adds or removes choices
    keeps every saved choice that still exists. Files saved before stored the
    position (an int, Blender's own enum storage): read as that position.
    Anything else (unset, a choice this library lacks, a position out of
    range) gives the default's position."""
    ids = list(identifiers)
    d = ids.index(default) if default in ids else 0
    if isinstance(stored, str):
        return ids.index(stored) if stored in ids else d
    if isinstance(stored, int) and not isinstance(stored, bool) and 0 <= stored < len(ids):
        return stored
    return d


def enum_items(p):
    """(identifier, label, description) of an enum parameter's choices."""
    labels = p.get("choice_labels") or p.get("choice_names") or ()
    return [(c, (labels[i] if i < len(labels) and labels[i] else readable(c)), "")
            for i, c in enumerate(p["choices"])]


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


# ---- denoising arrays ---------------------------------------------------------

class Settings(object):
    def __init__(self, method="auto", params=None, threads=0, samples=0, library_path="", temporal=False):
        self.method = method
        self.params = dict(params or {})
        self.threads = int(threads)
        self.samples = int(samples)
        self.library_path = library_path
        self.temporal = bool(temporal)


_devices = {}


def _device(ew, threads):
    key = (id(ew), threads)
    if key not in _devices:
        _devices[key] = ew.default_device() if threads <= 0 else ew.Device(threads)
    return _devices[key]


def colour_guided_method(method, inputs, have):
    """The method to run when the render lacks passes the chosen one requires:
    the method itself when every required guide is there, else "auto", which
    runs colour-guided grids without albedo/normal/depth (as the CLI's auto
    does). Returns (method, note) where note says what was substituted."""
    missing = [p["name"] for p in inputs if p.get("required") and p["name"] != "color" and p["name"] not in have]
    if not missing:
        return method, ""
    return "auto", "%s needs %s (no Denoising Data): ran auto, colour-guided" % (method, "/".join(missing))


def denoise_arrays(passes, settings, progress=None, ew=None):
    """Denoise one view layer held in numpy arrays (rows top first):
    passes["color"] (H, W, 3 or 4: RGB + alpha, as Blender's Combined) and the
    optional "albedo", "normal", "depth". Returns (rgba float32 (H, W, 4) with
    the input's alpha (1 without), what ran). progress(fraction) may return
    False to cancel (the library raises CancelledError)."""
    import numpy as np
    ew = ew or load_edgewise(settings.library_path)
    color = np.ascontiguousarray(passes["color"], np.float32)
    h, w = color.shape[:2]
    method = settings.method
    inputs = method_inputs(method, ew)
    have = [k for k in ("albedo", "normal", "depth") if passes.get(k) is not None]
    method, note = colour_guided_method(method, inputs, have)
    if method != settings.method:
        inputs = method_inputs(method, ew)
    mparams = method_params(method, ew)
    params = coerce_params(mparams, settings.params) if method == settings.method else {}
    if settings.samples > 0 and any(p["name"] == "samples" for p in mparams):
        params["samples"] = settings.samples
    names = set(p["name"] for p in inputs)
    g = ew.Graph(_device(ew, settings.threads))
    kwargs = {"color": np.ascontiguousarray(color[:, :, :3])}
    for k in have:
        if k in names:
            kwargs[k] = np.ascontiguousarray(passes[k], np.float32)
    den = g.add("denoise", id="denoise", method=method, **dict(kwargs, **params))
    g.add("output", id="out", image=den["output"])
    report = g.run(progress)
    ran = report["frames"][0].get("methods", {}).get("denoise", method) if report.get("frames") else method
    rgb = g.output("out")
    out = np.empty((h, w, 4), np.float32)
    out[:, :, :3] = rgb[:, :, :3]
    if color.shape[2] > 3:
        out[:, :, 3] = color[:, :, 3]
        # Combined is premultiplied: where alpha is 0 no sample found a
        # surface, so the pixel has no colour of its own to denoise, and a
        # kernel reaching in from the object beside it would leave colour
        # there (a halo over whatever the layer is composited on).
        empty = color[:, :, 3] <= 0.0
        out[:, :, :3][empty] = color[:, :, :3][empty]
    else:
        out[:, :, 3] = 1.0
    return out, (ran + ("; " + note if note else ""))


class TemporalHistory(object):
    """The library's temporal filters for one view layer across the frames of
    an animation render: the history lives in the filters between frames.
    Each stream (a name) is a filter of its own. Frames must come in order;
    a gap or a new size starts a stream over."""

    def __init__(self, ew, threads=0):
        self.ew = ew
        self.threads = threads
        self.filters = {}
        self.frames = {}

    def accumulate(self, frame, color, normal, depth, vector, stream="main", **params):
        """color (H, W, 3), normal (H, W, 3) or None, depth (H, W[, 1]) or None,
        vector (H, W, 2..4: Blender's Vector pass, rows top first). Returns the
        accumulated colour (H, W, 3)."""
        import numpy as np
        f = self.filters.get(stream)
        if f is None:
            f = self.filters[stream] = self.ew.Filter("temporal", _device(self.ew, self.threads))
        last = self.frames.get(stream)
        if last is None or frame != last[0] + 1 or color.shape != last[1]:
            f.set("reset", 1)
        self.frames[stream] = (frame, color.shape)
        for k, v in params.items():
            f.set(k, v)
        out = np.empty(color.shape[:2] + (3,), np.float32)
        c = lambda a: None if a is None else np.ascontiguousarray(a, np.float32)  # noqa: E731
        f.run(color=c(color[:, :, :3]), normal=c(normal), depth=c(depth),
              vector=None if vector is None else c(vector[:, :, :2]), output=out)
        return out

    def close(self):
        for f in self.filters.values():
            f.close()
        self.filters.clear()


# Temporal accumulation, as the add-on runs it: each frame is denoised alone,
# then its denoised colour, demodulated as the denoisers do (divided by
# Denoising Albedo plus the library's epsilon, so texture does not blur into
# the history), is accumulated with its
# predecessors along the Vector pass by the library's temporal filter (normal
# and depth rejection of disoccluded history, the history clamped to the
# frame's 3x3 mean +- 1 standard deviation, as the bench's after-demod-clamp
# mode), and multiplied back by the albedo. Whether the history matches the
# frame is judged on the noisy colour, whose noise is known: a second filter
# accumulates it (at least half of each pixel from the frame, no clamp), and
# where that accumulation disagrees with the frame by more than the frame's
# noise explains (history_mismatch: a shadow that moved over static geometry,
# a disocclusion the normal/depth test missed, vectors that point the wrong
# way), or the denoised accumulation moved away from the frame's denoised
# colour by more than that noise, the pixel keeps the per-frame result. One
# denoise per frame (and two ~10 ms filter runs at 256x256).
# Accumulating the noisy colour first and denoising that (this add-on's
# earlier way) lost up to 1.0 dB against per-frame denoising at 4 spp on the
# 256x256 g_anim sequences (surfaces moving ~10 px a frame: the bilinear
# reprojection blurs the input the denoiser sees); see docs/temporal.md.
TEMPORAL_PARAMS = {"clamp": 1.0}
CHECK_PARAMS = {"alpha_min": 0.5}
MISMATCH_RADII = (1, 2)  # 3x3 and 5x5 windows
MISMATCH_Z = 2.5         # standard errors of the windowed noise


def box_mean(img, r):
    """Mean over the (2r+1)^2 window around each pixel (edges repeated), per channel."""
    import numpy as np
    k = 2 * r + 1
    pad = np.pad(np.asarray(img, np.float64), ((r, r), (r, r), (0, 0)), mode="edge")
    c = np.pad(np.cumsum(np.cumsum(pad, axis=0), axis=1), ((1, 0), (1, 0), (0, 0)))
    h, w = img.shape[:2]
    return (c[k:k + h, k:k + w] - c[:h, k:k + w] - c[k:k + h, :w] + c[:h, :w]) / (k * k)


def history_mismatch(cur, acc, single, radii=MISMATCH_RADII, z=MISMATCH_Z):
    """history_mismatch on noisy accumulation: see mismatch()."""
    return mismatch(acc - cur, cur - single, radii, z)


def mismatch(diff, residual, radii=MISMATCH_RADII, z=MISMATCH_Z):
    """Pixels where the history's contribution `diff` (accumulated minus the
    frame) exceeds noise: in a window around the pixel (3x3 or 5x5; the
    smaller one catches differences of alternating sign that cancel in the
    larger), the mean of diff exceeds z standard errors of the frame's noise,
    estimated from what the per-frame denoiser removed (`residual`: noisy
    minus denoised) in the same window. On the channel mean (render noise is
    correlated across RGB)."""
    import numpy as np
    diff = diff.mean(axis=2, keepdims=True)
    res = residual.mean(axis=2, keepdims=True)
    bad = np.zeros(diff.shape[:2], bool)
    for r in radii:
        d = box_mean(diff, r)[:, :, 0]
        sigma = np.sqrt(np.maximum(box_mean(res * res, r)[:, :, 0], 0.0))
        bad |= np.abs(d) > z * sigma / (2 * r + 1) + 1e-6
    # a pixel most of whose neighbours mismatch does too (differences of
    # alternating sign, e.g. a texture's corners, cancel in every window)
    near = box_mean(bad[:, :, None].astype(np.float64), 1)[:, :, 0] * 9.0
    return bad | (near >= 5.0 - 1e-9)


def denoise_frame(passes, settings, frame, history=None, progress=None, ew=None):
    """Denoise one view layer of one frame (arrays with rows top first, see
    denoise_arrays). With a TemporalHistory and passes["vector"], the
    denoised frame is then accumulated with its predecessors (see above).
    Returns (rgba, what ran)."""
    import numpy as np
    ew = ew or load_edgewise(settings.library_path)
    single, ran = denoise_arrays(passes, settings, progress, ew)
    if history is None or passes.get("vector") is None:
        return single, ran
    # accumulated demodulated, as the denoisers work: the library's own
    # demodulate/remodulate nodes, so the add-on has no copy of the formula
    # or its epsilon. The albedo divided out and multiplied back is itself
    # accumulated along the vectors (its own stream, the colour's settings):
    # kpcn-large remodulates by an albedo it filtered, so dividing its output
    # by the frame's raw albedo and multiplying the accumulation by that raw
    # albedo again would put the raw albedo's few-spp noise back (0.3-0.6 dB
    # below per-frame denoising at 4 spp in tests/blender/test_addon_anim.py);
    # the accumulated albedo keeps the texture and changes little from one
    # frame to the next.
    albedo = passes.get("albedo")
    base = single[:, :, :3]
    if albedo is not None:
        albedo = np.ascontiguousarray(np.asarray(albedo, np.float32)[:, :, :3])
        albedo = history.accumulate(frame, albedo, passes.get("normal"), _depth(passes.get("depth")),
                                    passes["vector"], stream="albedo", **TEMPORAL_PARAMS)
        base = ew.run_node("demodulate", color=np.ascontiguousarray(base), albedo=albedo)
    acc = history.accumulate(frame, base, passes.get("normal"), _depth(passes.get("depth")), passes["vector"],
                             **TEMPORAL_PARAMS)
    if albedo is not None:
        acc = ew.run_node("remodulate", color=np.ascontiguousarray(acc, np.float32), albedo=albedo)
    color = np.asarray(passes["color"], np.float32)[:, :, :3]
    check = history.accumulate(frame, color, passes.get("normal"), _depth(passes.get("depth")), passes["vector"],
                               stream="check", **CHECK_PARAMS)
    bad = history_mismatch(color, check, single[:, :, :3]) | mismatch(acc - single[:, :, :3], color - single[:, :, :3])
    out = single.copy()
    out[:, :, :3] = np.where(bad[:, :, None], single[:, :, :3], acc)
    return out, ran + " + temporal"


def _depth(d):
    if d is None:
        return None
    return d[:, :, :1] if d.ndim == 3 else d


def error_text(err):
    """The library's message for the report area."""
    name = getattr(err, "code_name", None)
    text = str(err)
    if not text.startswith("Edgewise"):
        text = "Edgewise: " + text
    return "%s%s" % (text, " (%s)" % name if name else "")
