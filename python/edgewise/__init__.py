"""edgewise — denoising and edge-aware filtering of Monte Carlo renders.

A pure-Python package over libedgewise and libedgewise_nodes (ctypes, numpy):
build and run node graphs, load graph files, run single nodes on arrays.

    import edgewise as ew
    out = ew.run_node("bilateral", color=image, radius=4)      # numpy in, numpy out
    g = ew.Graph.load("examples/denoise_exr.json"); g.run()

The libraries are found through $EDGEWISE_LIB, next to this package, or in
the repository's build/lib (see _lib.py). Errors raise EdgewiseError with
the library's message.
"""
from ._lib import LibraryNotFoundError, library_dir
from .graph import CancelledError, Device, EdgewiseError, Filter, Graph, Node, Port, default_device, image_view, run_node
from .node_types import color_config, node_type, type_names

__all__ = [
    "CancelledError", "Device", "EdgewiseError", "Filter", "Graph", "LibraryNotFoundError", "Node", "Port",
    "color_config", "default_device", "image_view", "library_dir", "node_type", "run_node", "type_names",
    "version",
]


def version():
    """Version of the libedgewise actually loaded."""
    from . import _lib
    core, _ = _lib.libs()
    return core.ew_version_string().decode()
