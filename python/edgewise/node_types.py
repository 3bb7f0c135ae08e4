"""Node types, their ports and parameters, read from the library's
descriptors (never declared again in Python)."""
from . import _lib

PARAM_TYPES = ("bool", "int", "float", "enum", "string", "color")


def _s(b):
    return b.decode("utf-8") if b is not None else None


def _e(s):
    return s.encode("utf-8") if s is not None else None


def type_names():
    """Names of every node type, in listing order."""
    _, nodes = _lib.libs()
    return [_s(nodes.ew_node_type_name(i)) for i in range(nodes.ew_node_type_count())]


def node_type(name, method=None):
    """A dict describing node type `name` (with `method` for denoise/filter):
    name, version, category, summary, library_kind, library_method, available,
    inputs, outputs (lists of dicts) and params (list of dicts with name,
    type, default, min, max, choices, required, label, hint)."""
    _, nodes = _lib.libs()
    info = _lib.NodeTypeInfo()
    if nodes.ew_node_type_get(_e(name), _e(method), info) != 0:
        raise _lib.UnknownNameError("unknown node type %r%s" % (name, "" if method is None else " with method %r" % method))
    out = {
        "name": _s(info.name),
        "version": info.version,
        "category": _s(info.category),
        "summary": _s(info.summary),
        "library_kind": _s(info.library_kind),
        "library_method": _s(info.library_method),
        "available": bool(info.available),
        "inputs": [],
        "outputs": [],
        "params": [],
    }
    for side, getter, n in (("inputs", nodes.ew_node_type_input, info.num_inputs),
                            ("outputs", nodes.ew_node_type_output, info.num_outputs)):
        for i in range(n):
            p = _lib.PortInfo()
            if getter(_e(name), _e(method), i, p) == 0:
                out[side].append({"name": _s(p.name), "pass": _s(p.pass_), "min_channels": p.min_channels,
                                  "required": bool(p.required), "hint": _s(p.hint)})
    for i in range(info.num_params):
        p = _lib.ParamInfo()
        if nodes.ew_node_type_param(_e(name), _e(method), i, p) != 0:
            continue
        t = PARAM_TYPES[p.type]
        d = {"name": _s(p.name), "type": t, "label": _s(p.label), "hint": _s(p.hint), "required": bool(p.required)}
        if t == "bool":
            d["default"] = bool(p.default_value)
        elif t in ("int", "float"):
            d["default"] = int(p.default_value) if t == "int" else p.default_value
            d["min"], d["max"] = p.min_value, p.max_value
        elif t == "enum":
            choices = []
            for c in range(p.num_choices):
                s = _lib.ctypes.c_char_p()
                if nodes.ew_node_type_param_choice(_e(name), _e(method), i, c, _lib.ctypes.byref(s)) == 0:
                    choices.append(_s(s.value))
            d["choices"] = choices
            d["default"] = _s(p.default_string)
        elif t == "string":
            d["default"] = _s(p.default_string)
        else:
            d["default"] = tuple(p.default_color)
        out["params"].append(d)
    return out


def color_config():
    """Which OpenColorIO config the colour nodes use."""
    _, nodes = _lib.libs()
    buf = _lib.ctypes.create_string_buffer(1024)
    nodes.ew_nodes_color_config(buf, len(buf))
    return _s(buf.value)
