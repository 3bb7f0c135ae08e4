"""Image files to numpy arrays and back: the passes of a layer of a
(multilayer) EXR, PNG, TIFF or JPEG, read and written through the same
file code as the CLI and graphs (libedgewise_nodes: OpenEXR, OpenImageIO for the rest)."""
import ctypes
import json
import os

import numpy as np

from . import _lib

PIXEL_TYPES = {"keep": 0, "half": 1, "float": 2}


def _e(s):
    return s.encode("utf-8") if s is not None else None


class _File(object):
    """An ew_image_file handle, freed with the object."""

    def __init__(self, handle):
        _, self._lib = _lib.libs()
        self.handle = handle

    @classmethod
    def read(cls, path):
        _, lib = _lib.libs()
        h, err = ctypes.c_void_p(), ctypes.create_string_buffer(1024)
        r = lib.ew_image_file_read(_e(os.fspath(path)), ctypes.byref(h), err, len(err))
        if r != 0:
            raise _lib.EdgewiseError(r, err.value.decode("utf-8", "replace"))
        return cls(h)

    @classmethod
    def create(cls, width, height):
        _, lib = _lib.libs()
        h, err = ctypes.c_void_p(), ctypes.create_string_buffer(1024)
        r = lib.ew_image_file_create(int(width), int(height), ctypes.byref(h), err, len(err))
        if r != 0:
            raise _lib.EdgewiseError(r, err.value.decode("utf-8", "replace"))
        return cls(h)

    def info(self):
        return json.loads(self._lib.ew_image_file_describe(self.handle).decode("utf-8"))

    def get(self, layer, name, comps):
        info = self.info()
        a = np.empty((info["height"], info["width"], len(comps)), np.float32)
        view = _lib.Image(a.ctypes.data, a.shape[1], a.shape[0], a.shape[2], 0, 0, 1)
        err = ctypes.create_string_buffer(1024)
        r = self._lib.ew_image_file_get_pass(self.handle, _e(layer), _e(name), _e(comps), ctypes.byref(view), err,
                                             len(err))
        if r != 0:
            raise _lib.EdgewiseError(r, err.value.decode("utf-8", "replace"))
        return a

    def set(self, layer, name, comps, array):
        a = np.ascontiguousarray(array, dtype=np.float32)
        if a.ndim == 2:
            a = a[:, :, None]
        view = _lib.Image(a.ctypes.data, a.shape[1], a.shape[0], a.shape[2], 0, 0, 1)
        err = ctypes.create_string_buffer(1024)
        r = self._lib.ew_image_file_set_pass(self.handle, _e(layer), _e(name), _e(comps), ctypes.byref(view), err,
                                             len(err))
        if r != 0:
            raise _lib.EdgewiseError(r, "pass %r: %s" % (name, err.value.decode("utf-8", "replace")))

    def write(self, path, pixel_type, layer, name):
        err = ctypes.create_string_buffer(1024)
        r = self._lib.ew_image_file_write(self.handle, _e(os.fspath(path)), PIXEL_TYPES[pixel_type], _e(layer),
                                          _e(name), err, len(err))
        if r != 0:
            raise _lib.EdgewiseError(r, err.value.decode("utf-8", "replace"))

    def __del__(self):
        if getattr(self, "handle", None):
            self._lib.ew_image_file_destroy(self.handle)
            self.handle = None


def file_info(path):
    """What an image file holds, without its pixels as arrays: width, height,
    layers (each with its passes and their components, e.g. {"Combined":
    "RGBA"}, and which pass is the colour the file shows, "color", and what a
    denoiser reads, "noisy", "albedo", "normal", "depth") and attributes
    (Cycles' sample counts, compression)."""
    return _File.read(path).info()


def _pick_layer(info, layer, path):
    layers = info["layers"]
    if layer is not None:
        if layer not in layers:
            raise _lib.UnknownNameError("no layer %r in %s (layers: %s)" % (layer, path, ", ".join(map(repr, layers))))
        return layer
    for name, l in layers.items():
        if "color" in l:
            return name
    return next(iter(layers))


def read(path, layer=None, passes=None):
    """The passes of one layer of an image file as float32 arrays of shape
    (height, width, channels), in a dict keyed by pass name ("Combined",
    "Denoising Albedo", ...; a plain RGB(A) file has the one pass ""). The
    channels are the pass's components in file order (file_info says which).
    layer: the view layer (default: the first with a colour pass); passes:
    names to read (default: all of the layer). Alpha stays with its colour:
    Combined is RGBA when the file has A."""
    f = _File.read(path)
    info = f.info()
    layer = _pick_layer(info, layer, path)
    available = info["layers"][layer]["passes"]
    names = list(available) if passes is None else list(passes)
    out = {}
    for name in names:
        if name not in available:
            raise _lib.UnknownNameError("no pass %r in layer %r of %s (passes: %s)"
                                        % (name, layer, path, ", ".join(map(repr, available))))
        out[name] = f.get(layer, name, available[name])
    return out


def _default_comps(name, channels):
    if channels == 1:
        return "Z" if "Depth" in name or name == "Z" else "Y"
    if channels == 3 and ("Normal" in name or name in ("Position",)):
        return "XYZ"
    if channels == 4 and name == "Vector":
        return "XYZW"
    return {2: "RG", 3: "RGB", 4: "RGBA"}[channels]


def write(path, passes, layer=None, like=None, pixel_type=None, attributes=None):
    """Write arrays as passes of an image file, atomically.

    passes: {pass name: array (H, W) or (H, W, 1..4)}, or {name: (array,
    "XYZ")} to name the components (default: RGB/RGBA, XYZ for normals, Z
    for depth, Y for one channel).
    like: a file to start from (usually the one read): every layer, pass,
    alpha channel and header entry it has is kept and the given passes
    replace or join them, as `edgewise denoise` keeps a render whole.
    layer: the view layer to write into (default: like's first layer with a
    colour pass, else "ViewLayer" for an EXR, "" for a plain image).
    pixel_type: "half", "float" or "keep" (default: "keep" with like, each
    pass keeps its type, else "half").
    attributes: {name: text} header entries to set.
    PNG, TIFF and JPEG take one pass (the first given), values as they are:
    apply a display transform first (edgewise.run_node("display", ...)) for a
    picture that looks right."""
    if not passes:
        raise ValueError("no passes to write")
    items = []
    for name, v in passes.items():
        comps = None
        if isinstance(v, tuple):
            v, comps = v
        a = np.asarray(v, dtype=np.float32)
        if a.ndim == 2:
            a = a[:, :, None]
        if a.ndim != 3 or not 1 <= a.shape[2] <= 4:
            raise ValueError("pass %r: an array of shape (H, W) or (H, W, 1..4), got %r" % (name, np.shape(v)))
        items.append((name, a, comps))
    h, w = items[0][1].shape[:2]
    is_exr = os.fspath(path).lower().endswith(".exr")
    if like is not None:
        f = _File.read(like)
        info = f.info()
        if (info["width"], info["height"]) != (w, h):
            raise ValueError("the arrays are %dx%d but %s is %dx%d" % (w, h, like, info["width"], info["height"]))
        if layer is None:
            layer = _pick_layer(info, None, like)
        known = info["layers"].get(layer, {}).get("passes", {})
    else:
        f = _File.create(w, h)
        known = {}
        if layer is None:
            layer = "ViewLayer" if is_exr and any(name for name, _, _ in items) else ""
    for name, a, comps in items:
        if comps is None:
            comps = known.get(name) if known.get(name) and len(known[name]) == a.shape[2] else \
                _default_comps(name, a.shape[2])
        f.set(layer, name, comps, a)
    for k, v in (attributes or {}).items():
        f._lib.ew_image_file_set_attribute(f.handle, _e(k), _e(str(v)))
    pt = pixel_type or ("keep" if like is not None else "half")
    if pt not in PIXEL_TYPES:
        raise ValueError("pixel_type is 'half', 'float' or 'keep', got %r" % (pixel_type,))
    f.write(path, pt, layer, items[0][0])
