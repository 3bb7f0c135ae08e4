"""edgewise — denoising and edge-aware filtering of Monte Carlo renders.

A pure-Python package over libedgewise and libedgewise_nodes (ctypes, numpy):
build and run node graphs, load graph files, run single nodes on arrays.

    import edgewise as ew
    passes = ew.read("render.exr")                              # {pass name: (H, W, C) float32}
    out = ew.run_node("bilateral", color=passes["Combined"], radius=4)   # numpy in, numpy out
    ew.write("filtered.exr", {"Combined": out}, like="render.exr")     # every other pass kept
    g = ew.Graph.load("examples/denoise_dof_display.json"); g.run()
    op = ew.Op("auto"); op.run(color=c, albedo=a, normal=n, depth=z, output=out)   # kept across frames

Install: `pip install ./python` from a built clone, or `cmake --install`
(python/README.md). The libraries are found through $EDGEWISE_LIB, next to
this package, where the installer recorded them, or in the repository's
build/lib (see _lib.py). Errors raise EdgewiseError with the library's
message.
"""
from ._lib import EdgewiseError, LibraryNotFoundError, UnknownNameError, library_dir
from .files import file_info, read, write
from .graph import CancelledError, Device, Filter, Graph, Node, Op, Port, default_device, image_view, run_node
from .node_types import color_config, node_type, type_names

__all__ = [
    "CancelledError", "Device", "EdgewiseError", "Filter", "Graph", "LibraryNotFoundError", "Node", "Op", "Port",
    "UnknownNameError", "color_config", "default_device", "file_info", "image_view", "library_dir", "node_type",
    "read", "run_node", "type_names", "version", "write",
]


def version():
    """Version of the libedgewise actually loaded."""
    from . import _lib
    core, _ = _lib.libs()
    return core.ew_version_string().decode()
