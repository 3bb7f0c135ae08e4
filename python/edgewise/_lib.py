"""ctypes declarations of libedgewise and libedgewise_nodes.

All foreign calls live here. The libraries are looked for, in order:
  1. $EDGEWISE_LIB: a directory holding them, or the path of one of them;
  2. next to this package (an installed copy);
  3. build/lib of the repository this package sits in (a developer build).
They are loaded on first use, so importing the package never fails.
"""
import ctypes
import os

_LIB_NAMES = ("libedgewise.so", "libedgewise_nodes.so")


class LibraryNotFoundError(OSError):
    """libedgewise / libedgewise_nodes could not be found or loaded."""


class EdgewiseError(Exception):
    """A failure of the library: `code` is the ew_result value, `code_name`
    its name, str(e) the library's message."""

    def __init__(self, code, message):
        self.code = int(code)
        self.code_name = RESULT_NAMES.get(self.code, str(code))
        Exception.__init__(self, message)

    def __str__(self):
        return Exception.__str__(self)


class UnknownNameError(EdgewiseError, KeyError):
    """An unknown node type, method or pass name (EW_ERR_INVALID_ARGUMENT).
    Also a KeyError, for code written when that was what it raised."""

    def __init__(self, message):
        EdgewiseError.__init__(self, 1, message)


# ---- C structures (edgewise.h, nodes.h) -----------------------------------

class Image(ctypes.Structure):
    _fields_ = [
        ("data", ctypes.c_void_p),
        ("width", ctypes.c_int32),
        ("height", ctypes.c_int32),
        ("channels", ctypes.c_int32),
        ("pixel_stride", ctypes.c_int64),
        ("row_stride", ctypes.c_int64),
        ("format", ctypes.c_int32),
    ]


class DeviceDesc(ctypes.Structure):
    _fields_ = [("size", ctypes.c_size_t), ("type", ctypes.c_int32), ("num_threads", ctypes.c_int32)]


class NodeTypeInfo(ctypes.Structure):
    _fields_ = [
        ("name", ctypes.c_char_p),
        ("version", ctypes.c_int32),
        ("category", ctypes.c_char_p),
        ("summary", ctypes.c_char_p),
        ("library_kind", ctypes.c_char_p),
        ("library_method", ctypes.c_char_p),
        ("available", ctypes.c_int32),
        ("num_inputs", ctypes.c_int32),
        ("num_outputs", ctypes.c_int32),
        ("num_params", ctypes.c_int32),
    ]


class PortInfo(ctypes.Structure):
    _fields_ = [
        ("name", ctypes.c_char_p),
        ("pass_", ctypes.c_char_p),
        ("min_channels", ctypes.c_int32),
        ("required", ctypes.c_int32),
        ("hint", ctypes.c_char_p),
    ]


class ParamInfo(ctypes.Structure):
    _fields_ = [
        ("name", ctypes.c_char_p),
        ("type", ctypes.c_int32),
        ("default_value", ctypes.c_double),
        ("min_value", ctypes.c_double),
        ("max_value", ctypes.c_double),
        ("default_string", ctypes.c_char_p),
        ("default_color", ctypes.c_float * 4),
        ("num_choices", ctypes.c_int32),
        ("required", ctypes.c_int32),
        ("label", ctypes.c_char_p),
        ("hint", ctypes.c_char_p),
    ]


class GraphStats(ctypes.Structure):
    _fields_ = [
        ("num_nodes", ctypes.c_int32),
        ("planned_buffers", ctypes.c_int32),
        ("num_buffers", ctypes.c_int32),
        ("buffer_bytes", ctypes.c_int64),
        ("frames_done", ctypes.c_int32),
        ("validate_seconds", ctypes.c_double),
        ("run_seconds", ctypes.c_double),
        ("overhead_seconds", ctypes.c_double),
    ]


PROGRESS_FN = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_double)

RESULT_NAMES = {
    0: "EW_OK",
    1: "EW_ERR_INVALID_ARGUMENT",
    2: "EW_ERR_OUT_OF_MEMORY",
    3: "EW_ERR_UNSUPPORTED",
    4: "EW_ERR_BACKEND_UNAVAILABLE",
    5: "EW_ERR_IO",
    6: "EW_ERR_CANCELLED",
    7: "EW_ERR_INVALID_STATE",
    8: "EW_ERR_INVALID_DATA",
}


def _candidate_dirs():
    dirs = []
    env = os.environ.get("EDGEWISE_LIB")
    if env:
        dirs.append(env if os.path.isdir(env) else os.path.dirname(os.path.abspath(env)))
    here = os.path.dirname(os.path.abspath(__file__))
    dirs.append(here)
    # where the installer said the libraries are: `cmake --install` writes the
    # install's library directory, `pip install ./python` the clone's build/lib
    try:
        from . import _install
        dirs.extend(d for d in getattr(_install, "LIBRARY_DIRS", ()) if d)
    except ImportError:
        pass
    dirs.append(os.path.join(os.path.dirname(os.path.dirname(here)), "build", "lib"))
    return dirs


class _Libs(object):
    core = None
    nodes = None
    where = None


_libs = _Libs()


def _declare(core, nodes):
    c_char_p, c_int32, c_void_p = ctypes.c_char_p, ctypes.c_int32, ctypes.c_void_p
    P = ctypes.POINTER

    def fn(lib, name, restype, *argtypes):
        f = getattr(lib, name)
        f.restype = restype
        f.argtypes = list(argtypes)

    fn(core, "ew_version_string", c_char_p)
    fn(core, "ew_result_string", c_char_p, c_int32)
    fn(core, "ew_device_create", c_int32, P(DeviceDesc), P(c_void_p))
    fn(core, "ew_device_destroy", None, c_void_p)
    fn(core, "ew_device_last_error", c_char_p, c_void_p)
    fn(core, "ew_op_create", c_int32, c_void_p, c_char_p, P(c_void_p))
    fn(core, "ew_op_destroy", None, c_void_p)
    fn(core, "ew_op_set_image", c_int32, c_void_p, c_char_p, P(Image))
    fn(core, "ew_op_set_int", c_int32, c_void_p, c_char_p, c_int32)
    fn(core, "ew_op_set_float", c_int32, c_void_p, c_char_p, ctypes.c_float)
    fn(core, "ew_op_commit", c_int32, c_void_p)
    fn(core, "ew_op_execute", c_int32, c_void_p)
    fn(core, "ew_op_describe", c_char_p, c_void_p)
    fn(core, "ew_op_kind", c_char_p, c_void_p)

    fn(nodes, "ew_node_type_count", c_int32)
    fn(nodes, "ew_node_type_name", c_char_p, c_int32)
    fn(nodes, "ew_node_type_get", c_int32, c_char_p, c_char_p, P(NodeTypeInfo))
    fn(nodes, "ew_node_type_input", c_int32, c_char_p, c_char_p, c_int32, P(PortInfo))
    fn(nodes, "ew_node_type_output", c_int32, c_char_p, c_char_p, c_int32, P(PortInfo))
    fn(nodes, "ew_node_type_param", c_int32, c_char_p, c_char_p, c_int32, P(ParamInfo))
    fn(nodes, "ew_node_type_param_choice", c_int32, c_char_p, c_char_p, c_int32, c_int32, P(c_char_p))
    fn(nodes, "ew_graph_create", c_int32, c_void_p, P(c_void_p))
    fn(nodes, "ew_graph_destroy", None, c_void_p)
    fn(nodes, "ew_graph_last_error", c_char_p, c_void_p)
    fn(nodes, "ew_graph_load_file", c_int32, c_void_p, c_char_p)
    fn(nodes, "ew_graph_load_string", c_int32, c_void_p, c_char_p, c_char_p)
    fn(nodes, "ew_graph_add_node", c_int32, c_void_p, c_char_p, c_char_p)
    fn(nodes, "ew_graph_set_param", c_int32, c_void_p, c_char_p, c_char_p, c_char_p)
    fn(nodes, "ew_graph_set_assignment", c_int32, c_void_p, c_char_p)
    fn(nodes, "ew_graph_set_bool", c_int32, c_void_p, c_char_p, c_char_p, c_int32)
    fn(nodes, "ew_graph_set_int", c_int32, c_void_p, c_char_p, c_char_p, c_int32)
    fn(nodes, "ew_graph_set_float", c_int32, c_void_p, c_char_p, c_char_p, ctypes.c_double)
    fn(nodes, "ew_graph_set_string", c_int32, c_void_p, c_char_p, c_char_p, c_char_p)
    fn(nodes, "ew_graph_connect", c_int32, c_void_p, c_char_p, c_char_p, c_char_p, c_char_p)
    fn(nodes, "ew_graph_set_frames", c_int32, c_void_p, c_int32, c_int32)
    fn(nodes, "ew_graph_set_input", c_int32, c_void_p, c_char_p, P(Image))
    fn(nodes, "ew_graph_set_output", c_int32, c_void_p, c_char_p, P(Image))
    fn(nodes, "ew_graph_get_output", c_int32, c_void_p, c_char_p, P(Image))
    fn(nodes, "ew_graph_set_progress", c_int32, c_void_p, PROGRESS_FN, c_void_p)
    fn(nodes, "ew_graph_validate", c_int32, c_void_p)
    fn(nodes, "ew_graph_run", c_int32, c_void_p)
    fn(nodes, "ew_graph_report", c_char_p, c_void_p)
    fn(nodes, "ew_graph_get_stats", c_int32, c_void_p, P(GraphStats))
    fn(nodes, "ew_nodes_color_config", c_int32, c_char_p, ctypes.c_size_t)
    sz = ctypes.c_size_t
    fn(nodes, "ew_image_file_read", c_int32, c_char_p, P(c_void_p), c_char_p, sz)
    fn(nodes, "ew_image_file_create", c_int32, c_int32, c_int32, P(c_void_p), c_char_p, sz)
    fn(nodes, "ew_image_file_destroy", None, c_void_p)
    fn(nodes, "ew_image_file_describe", c_char_p, c_void_p)
    fn(nodes, "ew_image_file_get_pass", c_int32, c_void_p, c_char_p, c_char_p, c_char_p, P(Image), c_char_p, sz)
    fn(nodes, "ew_image_file_set_pass", c_int32, c_void_p, c_char_p, c_char_p, c_char_p, P(Image), c_char_p, sz)
    fn(nodes, "ew_image_file_set_attribute", c_int32, c_void_p, c_char_p, c_char_p)
    fn(nodes, "ew_image_file_write", c_int32, c_void_p, c_char_p, c_int32, c_char_p, c_char_p, c_char_p, sz)


def libs():
    """(core, nodes) ctypes libraries, loaded on first call."""
    if _libs.nodes is not None:
        return _libs.core, _libs.nodes
    tried = []
    for d in _candidate_dirs():
        paths = [os.path.join(d, n) for n in _LIB_NAMES]
        if not all(os.path.exists(p) for p in paths):
            tried.append(d)
            continue
        try:
            core = ctypes.CDLL(paths[0])
            nodes = ctypes.CDLL(paths[1])
            _declare(core, nodes)
        except (OSError, AttributeError) as e:
            raise LibraryNotFoundError("cannot load the edgewise libraries from %s: %s" % (d, e))
        _libs.core, _libs.nodes, _libs.where = core, nodes, d
        return core, nodes
    raise LibraryNotFoundError(
        "libedgewise.so and libedgewise_nodes.so not found (looked in: %s). Build the project "
        "(cmake -S . -B build && cmake --build build) or set EDGEWISE_LIB to the directory that "
        "holds them." % ", ".join(tried))


def library_dir():
    libs()
    return _libs.where
