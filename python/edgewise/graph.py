"""Graphs of nodes, built in Python or loaded from a graph file, run by
libedgewise_nodes. numpy arrays go in without a copy (float32 with
contiguous channels) and come out as views of graph memory where the graph
is private (run_node), as copies otherwise."""
import ctypes
import json
import os
import threading

import numpy as np

from . import _lib
from .node_types import node_type


EdgewiseError = _lib.EdgewiseError


class CancelledError(EdgewiseError):
    """The progress callback asked to stop (EW_ERR_CANCELLED)."""


def _e(s):
    return s.encode("utf-8") if s is not None else None


class Device(object):
    """A libedgewise device (CPU threads). threads=0: one per core."""

    def __init__(self, threads=0):
        core, _ = _lib.libs()
        self._core = core
        desc = _lib.DeviceDesc(ctypes.sizeof(_lib.DeviceDesc), 0, int(threads))
        handle = ctypes.c_void_p()
        r = core.ew_device_create(ctypes.byref(desc), ctypes.byref(handle))
        if r != 0:
            raise EdgewiseError(r, "cannot create a device: %s" % core.ew_result_string(r).decode())
        self._handle = handle

    @property
    def handle(self):
        return self._handle

    def close(self):
        if self._handle:
            self._core.ew_device_destroy(self._handle)
            self._handle = None

    def __del__(self):
        try:
            self.close()
        except Exception:
            pass


_default = {}
_default_lock = threading.Lock()


def default_device():
    """The device graphs use when none is given (created once)."""
    with _default_lock:
        if "device" not in _default:
            _default["device"] = Device()
        return _default["device"]


def image_view(array):
    """An ew_image viewing a float32 array of shape (H, W) or (H, W, C),
    C = 1..4, and the array it views (the same array when no conversion
    was needed: channels contiguous, float32)."""
    a = np.asarray(array)
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3 or not 1 <= a.shape[2] <= 4 or a.shape[0] < 1 or a.shape[1] < 1:
        raise ValueError("an image is an array of shape (height, width) or (height, width, 1..4), got %r"
                         % (np.shape(array),))
    # The C API reads a stride of 0 as "packed" (EW_STRIDE_PACKED), never as
    # a repeated pixel or row: numpy's broadcast views (stride 0) and views
    # whose rows overlap are copied, so the library only sees real strides.
    if (a.dtype != np.float32 or a.strides[2] != 4 or a.strides[1] < 4 * a.shape[2]
            or abs(a.strides[0]) < a.strides[1] * a.shape[1]):
        a = np.ascontiguousarray(a, dtype=np.float32)
    view = _lib.Image(a.ctypes.data, a.shape[1], a.shape[0], a.shape[2], a.strides[1], a.strides[0], 1)
    return view, a


class Port(object):
    """An output of a node, to connect to an input: node.port_name or node["port"]."""

    def __init__(self, node, name):
        self.node = node
        self.name = name

    def __repr__(self):
        return "Port(%s.%s)" % (self.node.id, self.name)


class Node(object):
    def __init__(self, graph, node_id, type_name):
        self.graph = graph
        self.id = node_id
        self.type = type_name

    def __getitem__(self, port):
        return Port(self, port)

    def __getattr__(self, port):
        if port.startswith("_"):
            raise AttributeError(port)
        return Port(self, port)

    def set(self, **params):
        for k, v in params.items():
            self.graph.set_param(self.id, k, v)
        return self

    def __repr__(self):
        return "Node(%s: %s)" % (self.id, self.type)


class Graph(object):
    """A node graph. Build with add(), or Graph.load(path); run() it.

    g = Graph()
    rd = g.add("read", path="render.exr")
    dn = g.add("denoise", method="bgrid", color=rd.color, albedo=rd.albedo)
    g.add("write", image=dn, path="out.exr")
    g.run()
    """

    def __init__(self, device=None):
        _, self._nodes_lib = _lib.libs()
        self._device = device if device is not None else default_device()
        handle = ctypes.c_void_p()
        r = self._nodes_lib.ew_graph_create(self._device.handle, ctypes.byref(handle))
        if r != 0:
            raise EdgewiseError(r, "cannot create a graph")
        self._handle = handle
        self._nodes = {}
        self._arrays = {}  # keeps caller arrays alive while the graph views them
        self._counter = 0
        # what built this graph, replayable in another process (spec())
        self._source = None
        self._ops = []

    # ---- life cycle ----
    def close(self):
        if getattr(self, "_handle", None):
            self._nodes_lib.ew_graph_destroy(self._handle)
            self._handle = None

    def __del__(self):
        try:
            self.close()
        except Exception:
            pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _check(self, r):
        if r != 0:
            msg = self._nodes_lib.ew_graph_last_error(self._handle).decode("utf-8", "replace")
            if not msg:
                msg = _lib.RESULT_NAMES.get(r, str(r))
            raise (CancelledError if r == 6 else EdgewiseError)(r, msg)

    # ---- loading ----
    @classmethod
    def load(cls, path, device=None):
        """A graph from a graph file (relative paths in it are relative to the file)."""
        g = cls(device)
        g._check(g._nodes_lib.ew_graph_load_file(g._handle, _e(os.fspath(path))))
        with open(os.fspath(path), encoding="utf-8") as f:
            g._source = {"text": f.read(), "base_dir": os.path.dirname(os.path.abspath(os.fspath(path)))}
        return g

    @classmethod
    def loads(cls, text, base_dir=None, device=None):
        """A graph from graph-file text; relative paths are relative to base_dir (default: cwd)."""
        g = cls(device)
        g._check(g._nodes_lib.ew_graph_load_string(g._handle, _e(text), _e(base_dir)))
        g._source = {"text": text, "base_dir": os.path.abspath(base_dir if base_dir is not None else os.getcwd())}
        return g

    def node(self, node_id):
        """The Node called node_id (also for nodes loaded from a file)."""
        if node_id in self._nodes:
            return self._nodes[node_id]
        return Node(self, node_id, None)

    # ---- building ----
    def add(self, type_name, id=None, **kwargs):
        """Add a node. Keyword arguments naming an input port of the type are
        connections (a Port, a Node for its main output, or a numpy array,
        which becomes an "input" node); the others are parameters."""
        method = kwargs.get("method") if type_name == "denoise" else kwargs.get("filter") if type_name == "filter" else None
        if isinstance(method, str):
            info = node_type(type_name, method)
        else:
            info = node_type(type_name)
        inputs = set(p["name"] for p in info["inputs"])
        if id is None:
            self._counter += 1
            id = "%s%d" % (type_name, self._counter)
            while id in self._nodes:
                self._counter += 1
                id = "%s%d" % (type_name, self._counter)
        self._check(self._nodes_lib.ew_graph_add_node(self._handle, _e(id), _e(type_name)))
        self._ops.append(["add", id, type_name])
        node = Node(self, id, type_name)
        self._nodes[id] = node
        for k, v in kwargs.items():
            if isinstance(v, (Port, Node)) or (k in inputs and not isinstance(v, (str, bool, int, float))):
                self.connect(v, node[k])
            else:
                self.set_param(id, k, v)
        return node

    def connect(self, src, dst):
        """Connect src (a Port, a Node, or a numpy array) to dst (a Port)."""
        if isinstance(src, np.ndarray) or (not isinstance(src, (Port, Node)) and hasattr(src, "__array__")):
            src = self.add_input(src)
        if isinstance(src, Node):
            src_node, src_port = src.id, None
        else:
            src_node, src_port = src.node.id, src.name
        self._check(self._nodes_lib.ew_graph_connect(self._handle, _e(src_node), _e(src_port), _e(dst.node.id),
                                                     _e(dst.name)))
        self._ops.append(["connect", src_node, src_port, dst.node.id, dst.name])

    def add_input(self, array, id=None):
        """An "input" node viewing `array` (not copied when float32 with
        contiguous channels; the graph keeps a reference)."""
        node = self.add("input", id=id)
        self.set_input(node.id, array)
        return node

    def set_input(self, node_id, array):
        view, kept = image_view(array)
        self._arrays[node_id] = kept
        self._check(self._nodes_lib.ew_graph_set_input(self._handle, _e(node_id), ctypes.byref(view)))
        self._ops.append(["array", node_id])

    def set_param(self, node_id, name, value):
        lib, h, n, p = self._nodes_lib, self._handle, _e(node_id), _e(name)
        if isinstance(value, (bool, np.bool_)):
            r = lib.ew_graph_set_bool(h, n, p, int(bool(value)))
        elif isinstance(value, (int, np.integer)):
            if -2 ** 31 <= int(value) < 2 ** 31:
                r = lib.ew_graph_set_int(h, n, p, int(value))
            else:
                r = lib.ew_graph_set_float(h, n, p, float(value))
        elif isinstance(value, (float, np.floating)):
            r = lib.ew_graph_set_float(h, n, p, float(value))
        elif isinstance(value, str):
            r = lib.ew_graph_set_string(h, n, p, _e(value))
        elif isinstance(value, os.PathLike):
            r = lib.ew_graph_set_string(h, n, p, _e(os.fspath(value)))
        elif isinstance(value, (list, tuple, np.ndarray)):
            r = lib.ew_graph_set_param(h, n, p, _e(",".join(repr(float(x)) for x in value)))
        else:
            raise TypeError("node %r parameter %r: cannot pass a %s" % (node_id, name, type(value).__name__))
        self._check(r)
        self._ops.append(["param", node_id, name, _plain(name, value)])

    def set(self, assignment):
        """Set a parameter from text, "node.param=value" (as --set does)."""
        self._check(self._nodes_lib.ew_graph_set_assignment(self._handle, _e(assignment)))
        node_param, _, value = assignment.partition("=")
        self._ops.append(["set", node_param + "=" + _plain(node_param.rpartition(".")[2], value)])

    def set_frames(self, first, last=None):
        last = first if last is None else last
        self._check(self._nodes_lib.ew_graph_set_frames(self._handle, int(first), int(last)))
        self._ops.append(["frames", int(first), int(last)])

    # ---- shipping to other processes ----
    def spec(self):
        """What built this graph as plain data (JSON-able): the graph file's
        text and directory, then every add, connect, parameter and frame
        range since, with relative paths made absolute. Graph.from_spec()
        rebuilds the same graph in another process or on another machine
        (edgewise.distributed ships graphs this way). A graph viewing numpy
        arrays ("input" nodes) cannot be shipped: ValueError."""
        for op in self._ops:
            if op[0] == "array":
                raise ValueError("node %r views a numpy array: only a graph that reads its images from files can "
                                 "run in another process" % op[1])
        return {"edgewise_graph_spec": 1, "source": dict(self._source) if self._source else None,
                "ops": [list(op) for op in self._ops]}

    @classmethod
    def from_spec(cls, spec, device=None):
        """The graph spec() described."""
        src = spec.get("source")
        g = cls.loads(src["text"], src["base_dir"], device) if src else cls(device)
        for op in spec.get("ops", ()):
            kind = op[0]
            if kind == "add":
                g._check(g._nodes_lib.ew_graph_add_node(g._handle, _e(op[1]), _e(op[2])))
                g._nodes[op[1]] = Node(g, op[1], op[2])
                g._ops.append(list(op))
            elif kind == "connect":
                g.connect(Port(g.node(op[1]), op[2]) if op[2] is not None else g.node(op[1]), Port(g.node(op[3]), op[4]))
            elif kind == "param":
                g.set_param(op[1], op[2], op[3])
            elif kind == "set":
                g.set(op[1])
            elif kind == "frames":
                g.set_frames(op[1], op[2])
            else:
                raise ValueError("unknown graph spec operation %r" % (kind,))
        return g

    # ---- running ----
    def validate(self):
        self._check(self._nodes_lib.ew_graph_validate(self._handle))

    def run(self, progress=None):
        """Run every frame. progress(fraction) may return False to cancel
        (CancelledError is raised). Returns the report (a dict)."""
        errors = []
        if progress is not None:
            def tramp(user, fraction):
                try:
                    return 0 if progress(fraction) is False else 1
                except BaseException as e:  # stop the run, re-raise below
                    errors.append(e)
                    return 0
            cb = _lib.PROGRESS_FN(tramp)
        else:
            cb = _lib.PROGRESS_FN()
        self._nodes_lib.ew_graph_set_progress(self._handle, cb, None)
        try:
            r = self._nodes_lib.ew_graph_run(self._handle)
        finally:
            self._nodes_lib.ew_graph_set_progress(self._handle, _lib.PROGRESS_FN(), None)
        if errors:
            raise errors[0]
        self._check(r)
        return self.report()

    def report(self):
        return json.loads(self._nodes_lib.ew_graph_report(self._handle).decode("utf-8"))

    def stats(self):
        s = _lib.GraphStats()
        self._check(self._nodes_lib.ew_graph_get_stats(self._handle, ctypes.byref(s)))
        return dict((name, getattr(s, name)) for name, _ in s._fields_)

    def output(self, node_id, copy=True):
        """The result of "output" node node_id after run(): a (H, W, C)
        float32 array. copy=False gives a view of graph memory, valid until
        the next run (the array keeps the graph alive)."""
        view = _lib.Image()
        self._check(self._nodes_lib.ew_graph_get_output(self._handle, _e(node_id), ctypes.byref(view)))
        n = view.width * view.height * view.channels
        buf = (ctypes.c_float * n).from_address(view.data)
        buf._edgewise_graph = self  # the memory belongs to the graph
        a = np.frombuffer(buf, dtype=np.float32).reshape(view.height, view.width, view.channels)
        return a.copy() if copy else a


def _plain(name, value):
    """A parameter value as plain data for spec(); a relative "path" is made
    absolute here, as the library reads it relative to this process's
    current directory."""
    if isinstance(value, os.PathLike):
        value = os.fspath(value)
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value)
    if isinstance(value, str):
        return os.path.abspath(value) if name == "path" and value else value
    return [float(x) for x in value]


def run_node(type_name, outputs=None, device=None, progress=None, **kwargs):
    """Run one node on numpy arrays: inputs and parameters as keyword
    arguments (see Graph.add). Returns the main output as a (H, W, C)
    float32 array, or a dict when `outputs` names several ports. The
    arrays are views of the private graph's memory: no copy."""
    g = Graph(device)
    node = g.add(type_name, id="node", **kwargs)
    names = [outputs] if isinstance(outputs, str) else list(outputs) if outputs else None
    if names is None:
        method = kwargs.get("method") if type_name == "denoise" else kwargs.get("filter") if type_name == "filter" else None
        info = node_type(type_name, method if isinstance(method, str) else None)
        if not info["outputs"]:
            raise ValueError("node type %r has no outputs" % type_name)
        names = [info["outputs"][0]["name"]]
    for i, name in enumerate(names):
        g.add("output", id="out%d" % i, image=node[name])
    g.run(progress)
    result = dict((name, g.output("out%d" % i, copy=False)) for i, name in enumerate(names))
    # A denoiser works on RGB; alpha goes through, as the filters carry it.
    color = kwargs.get("color")
    if type_name == "denoise" and "output" in result and isinstance(color, np.ndarray) and color.ndim == 3 \
            and color.shape[2] == 4 and result["output"].shape[2] == 3:
        result["output"] = np.concatenate((result["output"], np.asarray(color[:, :, 3:4], np.float32)), axis=2)
    if outputs is None or isinstance(outputs, str):
        return result[names[0]]
    return result


class Op(object):
    """One libedgewise op (any denoiser or filter: "kpcn", "auto",
    "temporal", ...) used directly, outside a graph, and kept across calls:
    its scratch and device memory stay allocated from one frame to the next
    of the same size, as a graph keeps its ops over a frame range (run_node
    builds a new one every call), and the "temporal" filter keeps its
    history between run()s. Parameters are set by name (types from the
    descriptors; an enum also by its choice's name); run() takes numpy
    arrays; describe() says what the last run ran."""

    _node = {"denoiser": "denoise", "filter": "filter"}

    def __init__(self, method, device=None):
        core, _ = _lib.libs()
        self._core = core
        self._device = device or default_device()
        handle = ctypes.c_void_p()
        r = core.ew_op_create(self._device.handle, _e(method), ctypes.byref(handle))
        self._handle = handle if r == 0 else None
        self._check(r)
        self.method = method
        self.kind = core.ew_op_kind(self._handle).decode()
        self._params = dict((p["name"], p) for p in node_type(self._node[self.kind], method)["params"])
        self._kept = []

    def _check(self, r):
        if r != 0:
            msg = self._core.ew_device_last_error(self._device.handle)
            msg = msg.decode("utf-8", "replace") if msg else ""
            raise EdgewiseError(r, msg or self._core.ew_result_string(r).decode())

    def set(self, name, value):
        p = self._params.get(name)
        if p is None:
            raise KeyError("%s has no parameter %r (it has %s)" % (self.method, name, ", ".join(sorted(self._params))))
        if isinstance(value, str):
            choices = list(p.get("choices") or [])
            if value not in choices:
                raise ValueError("%r is not a choice of %s's %r (%s)" % (value, self.method, name, ", ".join(choices)))
            value = choices.index(value)
        if p["type"] == "float":
            self._check(self._core.ew_op_set_float(self._handle, _e(name), float(value)))
        else:
            self._check(self._core.ew_op_set_int(self._handle, _e(name), int(value)))

    def run(self, **images):
        """Set the images (None unsets one), commit and execute. An output
        array must be float32 with contiguous channels (it is written in place)."""
        kept = []
        for name, a in images.items():
            if a is None:
                self._check(self._core.ew_op_set_image(self._handle, _e(name), None))
                continue
            view, arr = image_view(a)
            if arr is not a and isinstance(a, np.ndarray) and name == "output":
                raise ValueError("output array must be float32 with contiguous channels")
            kept.append((view, arr))
            self._check(self._core.ew_op_set_image(self._handle, _e(name), ctypes.byref(view)))
        self._kept = kept
        self._check(self._core.ew_op_commit(self._handle))
        self._check(self._core.ew_op_execute(self._handle))

    def describe(self):
        """What the last run ran, in words (for "auto": the method and model it picked)."""
        d = self._core.ew_op_describe(self._handle) if self._handle else None
        return d.decode("utf-8", "replace") if d else None

    def close(self):
        if self._handle:
            self._core.ew_op_destroy(self._handle)
            self._handle = None

    def __del__(self):
        try:
            self.close()
        except Exception:
            pass


class Filter(Op):
    """An Op whose method is a filter (the class of earlier versions)."""

    def __init__(self, method, device=None):
        Op.__init__(self, method, device)
        if self.kind != "filter":
            self.close()
            raise _lib.UnknownNameError("unknown node type 'filter' with method %r" % method)
