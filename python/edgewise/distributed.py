"""A graph over a frame range on Dask distributed: chunks of frames as tasks,
resumable, safe to kill, temporal filters carried across chunk borders.

    from edgewise.distributed import run_frames
    report = run_frames("shot.json", "1-240")                               # a LocalCluster on this machine
    report = run_frames("shot.json", "1-240", client="tcp://head:8786")     # a running Dask cluster

    python3 -m edgewise.distributed run shot.json --frames 1-240 --workers 2
    edgewise graph run shot.json --frames 1-240 --scheduler tcp://head:8786  # the CLI hands over to this

Each task runs one chunk of consecutive frames in a Dask worker process
through this package (ctypes over libedgewise_nodes; no process per frame),
on the one edgewise Device of that process. What makes it safe to re-run
and to lose a machine:

* Outputs are written into a hidden scratch directory beside each output
  (.edgewise-part-*) and renamed into place only when the chunk's run has
  finished, so an output file is either absent or complete. A worker killed
  mid-chunk leaves only its scratch directory (removed at the end of the
  run); Dask gives the chunk to another worker.
* A sidecar manifest (.edgewise-manifest.json beside the first write node's
  files) records, per output file, the frame, a hash of the graph and its
  parameters, the size, mtime and SHA-256. A frame whose files are all
  recorded for this graph, with that size and mtime (and SHA-256 with
  verify=True), is skipped on the next run.
* Temporal filters keep history from frame to frame within one run. A chunk
  therefore starts `warmup` frames early (never before the range's first
  frame); those frames run but their outputs are thrown away.

Workers must see the same paths as the client (shared storage), and import
this package with its libraries ($EDGEWISE_LIB, see _lib.py).
"""
import argparse
import hashlib
import json
import math
import os
import re
import shutil
import signal
import socket
import sys
import threading
import time
import uuid

from .graph import Device, EdgewiseError, Graph
from .node_types import node_type

MANIFEST_NAME = ".edgewise-manifest.json"
SCRATCH_PREFIX = ".edgewise-part-"
# Warm-up frames per chunk for a graph with a temporal filter. The filter
# takes the running mean of its first 5 frames, then an exponential average
# with weight alpha_min (0.2) on the new frame, so a chunk's first written
# frame needs at least 5 frames of history behind it; measured on the
# committed sequence, 5 frames leave <= 0.015 dB of PSNR difference, 4 about
# 0.1 dB (docs/distributed.md). 8 leaves a margin.
DEFAULT_TEMPORAL_WARMUP = 8


class DistributedRunError(RuntimeError):
    """Some frames failed (after Dask's retries). `report` is the run's
    report: which frames were written, skipped or failed, and why."""

    def __init__(self, message, report):
        RuntimeError.__init__(self, message)
        self.report = report


# ---- frame ranges and paths ----------------------------------------------

def parse_frames(frames):
    """(first, last) from "A-B", "A", (A, B), [A, B], range or an int."""
    if isinstance(frames, range):
        if len(frames) == 0 or frames.step != 1:
            raise ValueError("a frame range must be consecutive and not empty: %r" % (frames,))
        a, b = frames[0], frames[-1]
    elif isinstance(frames, int):
        a = b = frames
    elif isinstance(frames, str):
        m = re.match(r"^\s*(\d+)\s*(?:-\s*(\d+)\s*)?$", frames)
        if not m:
            raise ValueError("frames: expected A-B or A, got %r" % frames)
        a = int(m.group(1))
        b = int(m.group(2)) if m.group(2) is not None else a
    else:
        a, b = (int(x) for x in frames)
    if a < 0 or b < a:
        raise ValueError("frames: expected 0 <= A <= B, got %d-%d" % (a, b))
    return a, b


def frame_path(pattern, frame):
    """The file of `frame`: the first run of '#' is the zero-padded number
    (as the graph runner does)."""
    m = re.search(r"#+", pattern)
    if not m:
        return pattern
    return pattern[:m.start()] + "%0*d" % (len(m.group()), frame) + pattern[m.end():]


def _frames_on_disk(pattern):
    d, base = os.path.split(pattern)
    m = re.search(r"#+", base)
    if not m:
        return []
    pre, run, suf = base[:m.start()], len(m.group()), base[m.end():]
    rx = re.compile(r"^%s(\d{%d,9})%s$" % (re.escape(pre), run, re.escape(suf)))
    out = []
    for name in os.listdir(d or "."):
        mm = rx.match(name)
        if mm and not (len(mm.group(1)) > run and mm.group(1)[0] == "0"):
            out.append(int(mm.group(1)))
    return sorted(out)


# ---- what a graph spec says ------------------------------------------------

def _graph_spec(graph, sets=()):
    """A Graph, or the path of a graph file, as plain data to ship."""
    if isinstance(graph, Graph):
        spec = graph.spec()
    else:
        path = os.path.abspath(os.fspath(graph))
        with open(path, encoding="utf-8") as f:
            text = f.read()
        spec = {"edgewise_graph_spec": 1, "source": {"text": text, "base_dir": os.path.dirname(path)}, "ops": []}
    for s in sets:
        node_param, eq, value = s.partition("=")
        if not eq or "." not in node_param:
            raise ValueError("set: expected NODE.PARAM=VALUE, got %r" % s)
        if node_param.rpartition(".")[2] == "path" and value:
            value = os.path.abspath(value)
        spec["ops"].append(["set", node_param + "=" + value])
    return spec


def _nodes_of(spec):
    """Node id -> {"type", "params"} and the frame range, as the spec leaves
    them (relative paths made absolute)."""
    nodes, frames = {}, None
    src = spec.get("source")
    if src:
        doc = json.loads(src["text"])
        for nid, n in doc.get("nodes", {}).items():
            params = dict(n.get("params", {}))
            if isinstance(params.get("path"), str) and params["path"]:
                params["path"] = os.path.join(src["base_dir"], params["path"])
            nodes[nid] = {"type": n.get("type"), "params": params}
        fr = doc.get("frames")
        if fr is not None:
            frames = parse_frames(fr if not isinstance(fr, float) else int(fr))
    for op in spec.get("ops", ()):
        if op[0] == "add":
            nodes[op[1]] = {"type": op[2], "params": {}}
        elif op[0] == "param" and op[1] in nodes:
            nodes[op[1]]["params"][op[2]] = op[3]
        elif op[0] == "set":
            node_param, _, value = op[1].partition("=")
            nid, _, name = node_param.rpartition(".")
            if nid in nodes:
                nodes[nid]["params"][name] = value
        elif op[0] == "frames":
            frames = (op[1], op[2])
    return nodes, frames


def _type_info(node):
    t = node["type"]
    method = node["params"].get("method") if t == "denoise" else node["params"].get("filter") if t == "filter" else None
    try:
        return node_type(t, method if isinstance(method, str) else None)
    except KeyError:
        return None


def _writers(nodes):
    """Node id -> absolute output pattern of every node that writes files."""
    out = {}
    for nid, n in sorted(nodes.items()):
        info = _type_info(n)
        if info is None or info["category"] != "io" or info["outputs"]:
            continue
        if not any(p["name"] == "path" for p in info["params"]):
            continue
        path = n["params"].get("path")
        if not isinstance(path, str) or not path:
            continue
        if "#" not in os.path.basename(path):
            raise ValueError("node %r writes %r for every frame: a frame range needs a '#' frame pattern in the file "
                             "name" % (nid, path))
        out[nid] = os.path.abspath(path)
    return out


def _temporal_nodes(nodes):
    """Ids of nodes that keep state from frame to frame."""
    out = []
    for nid, n in sorted(nodes.items()):
        info = _type_info(n)
        if info is not None and (info["category"] == "time" or info["library_method"] == "temporal"):
            out.append(nid)
    return out


def _graph_hash(spec):
    """What makes an output what it is: the graph and every parameter, not
    the frame range (nor chunking, nor warm-up)."""
    keep = {"source": spec.get("source"), "ops": [op for op in spec.get("ops", ()) if op[0] != "frames"]}
    return hashlib.sha256(json.dumps(keep, sort_keys=True).encode("utf-8")).hexdigest()[:32]


# ---- manifest --------------------------------------------------------------

def _sha256(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _write_atomic(path, text):
    tmp = "%s.tmp-%d-%s" % (path, os.getpid(), uuid.uuid4().hex[:8])
    try:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


class Manifest(object):
    """The sidecar record of complete output files (JSON):
    {"edgewise_manifest": 1, "files": {NAME: {"frame", "graph", "size",
    "mtime_ns", "sha256"}}}, NAME relative to the manifest's directory when
    inside it. Only the client writes it, atomically."""

    def __init__(self, path):
        self.path = os.path.abspath(path)
        self.dir = os.path.dirname(self.path)
        self.files = {}
        try:
            with open(self.path, encoding="utf-8") as f:
                doc = json.load(f)
            if isinstance(doc, dict) and isinstance(doc.get("files"), dict):
                self.files = doc["files"]
        except (OSError, ValueError):
            pass  # no manifest, or not one we can read: every frame runs

    def _key(self, path):
        rel = os.path.relpath(path, self.dir)
        return path if rel.startswith("..") else rel

    def complete(self, path, graph_hash, verify=False):
        e = self.files.get(self._key(path))
        if not isinstance(e, dict) or e.get("graph") != graph_hash:
            return False
        try:
            st = os.stat(path)
        except OSError:
            return False
        if st.st_size != e.get("size") or st.st_mtime_ns != e.get("mtime_ns"):
            return False
        return not verify or _sha256(path) == e.get("sha256")

    def record(self, path, frame, graph_hash, info):
        self.files[self._key(path)] = {"frame": frame, "graph": graph_hash, "size": info["size"],
                                       "mtime_ns": info["mtime_ns"], "sha256": info["sha256"]}

    def save(self):
        _write_atomic(self.path, json.dumps({"edgewise_manifest": 1, "files": self.files}, indent=1,
                                            sort_keys=True) + "\n")


# ---- the worker side -------------------------------------------------------

_worker = {"device": None, "threads": None}
_worker_lock = threading.Lock()  # one device per process, one graph on it at a time


def _keep_freed_memory():
    """Dask starts worker processes with MALLOC_TRIM_THRESHOLD_=65536, which
    also turns off glibc's adaptive mmap threshold: every image-sized scratch
    buffer the library allocates and frees per frame becomes an mmap/munmap
    pair with fresh page faults, measured at 2-4x the CPU time of a frame at
    256x256. Give the allocator the limits the adaptive rule would reach
    (mmap above 32 MiB, trim above 64 MiB). glibc only; a no-op elsewhere."""
    if not sys.platform.startswith("linux"):
        return
    try:
        import ctypes
        libc = ctypes.CDLL("libc.so.6")
        libc.mallopt(-3, 32 << 20)  # M_MMAP_THRESHOLD
        libc.mallopt(-1, 64 << 20)  # M_TRIM_THRESHOLD
    except (OSError, AttributeError):
        pass


def _worker_device(threads):
    if _worker["device"] is None:
        _keep_freed_memory()
    if _worker["device"] is None or _worker["threads"] != threads:
        if _worker["device"] is not None:
            _worker["device"].close()
        _worker["device"] = Device(threads)
        _worker["threads"] = threads
    return _worker["device"]


def _this_worker():
    try:
        from distributed import get_worker
        return get_worker()
    except (ImportError, ValueError):
        return None


def _kill_once(fault, frame):
    """The tests' stand-in for a machine lost mid-frame: fault = [FRAME,
    MARKER]; the first worker inside FRAME writes its pid to MARKER (which
    must not exist yet) and kills itself with SIGKILL."""
    if not fault or int(fault[0]) != frame:
        return
    try:
        fd = os.open(fault[1], os.O_CREAT | os.O_EXCL | os.O_WRONLY)
    except FileExistsError:
        return
    os.write(fd, str(os.getpid()).encode())
    os.close(fd)
    os.kill(os.getpid(), signal.SIGKILL)


def run_chunk(job):
    """One chunk, in this process: the Dask task. `job` is the plain dict
    run_frames builds (graph spec, runs of frames, frames to write, final
    output patterns, device threads). Returns one record per written frame."""
    with _worker_lock:
        return _run_chunk(job)


def _run_chunk(job):
    worker = _this_worker()
    where, host, pid = worker.address if worker is not None else "local", socket.gethostname(), os.getpid()
    # frames done go to the client as worker events (batched, no round trip): the progress bar only
    topic = job.get("topic") if worker is not None else None
    threads = job["threads"]
    if threads is None:  # the host's cores shared among the worker processes on it
        here = worker.ip if worker is not None else None
        threads = max(1, _default_workers() // max(1, job.get("workers_per_host", {}).get(here, 1)))
    device = _worker_device(threads)
    writers = job["writers"]
    write = set(job["write"])
    tag = "%s%s-c%d-%s" % (SCRATCH_PREFIX, job["run_id"], job["chunk"], uuid.uuid4().hex[:8])
    scratch_roots, scratch = [], {}
    records = []
    g = Graph.from_spec(job["spec"], device=device)
    try:
        for wid, pattern in sorted(writers.items()):
            root = os.path.join(os.path.dirname(pattern), tag)
            if root not in scratch_roots:
                os.makedirs(root)
                scratch_roots.append(root)
            os.makedirs(os.path.join(root, wid))
            scratch[wid] = os.path.join(root, wid, os.path.basename(pattern))
            g.set_param(wid, "path", scratch[wid])
        for first, last in job["runs"]:
            g.set_frames(first, last)
            count = last - first + 1
            seen = [first]  # next frame not yet announced as done

            def progress(fraction, first=first, count=count, seen=seen):
                pos = fraction * count + 1e-9
                running = first + min(int(pos), count - 1)
                if fraction >= 1.0:
                    running = first + count
                while seen[0] < running:
                    if topic and seen[0] in write:
                        worker.log_event(topic, {"frame": seen[0], "where": where})
                    seen[0] += 1
                if pos - int(pos) > 1e-6:  # inside a frame: nodes past the first one
                    _kill_once(job.get("fault"), running)
                return True

            t0 = time.time()
            rep = g.run(progress)
            wall = time.time() - t0
            warm = sum(1 for fr in rep["frames"] if fr["frame"] not in write)
            for fr in rep["frames"]:
                f = fr["frame"]
                if f not in write:
                    continue  # warm-up frame: its outputs are thrown away with the scratch directory
                outputs = {}
                for wid, pattern in sorted(writers.items()):
                    src, dst = frame_path(scratch[wid], f), frame_path(pattern, f)
                    digest = _sha256(src)
                    os.replace(src, dst)
                    st = os.stat(dst)
                    outputs[dst] = {"size": st.st_size, "mtime_ns": st.st_mtime_ns, "sha256": digest}
                records.append({"frame": f, "status": "written", "where": where, "host": host, "pid": pid,
                                "chunk": job["chunk"], "run": [first, last], "warmup_frames": warm, "threads": threads,
                                "methods": fr.get("methods", {}), "metrics": fr.get("metrics", {}),
                                "seconds": fr.get("seconds"), "run_seconds": wall, "written": sorted(outputs),
                                "outputs": outputs})
    finally:
        g.close()
        for root in scratch_roots:
            shutil.rmtree(root, ignore_errors=True)
    return records


# ---- the client side -------------------------------------------------------

class ProgressBar(object):
    """frames done / total and time left, redrawn in place on a terminal."""

    def __init__(self, total, already, stream=None, enabled=None, width=30):
        self.total, self.already = total, already
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = enabled if enabled is not None else self.stream.isatty()
        self.width = width
        self.t0 = time.time()
        self.last = 0.0
        self.done = already

    def update(self, done, force=False):
        self.done = done
        now = time.time()
        if not self.enabled or (not force and now - self.last < 0.1):
            return
        self.last = now
        self.stream.write("\r" + self.text(now))
        self.stream.flush()

    def text(self, now=None):
        now = time.time() if now is None else now
        ran, elapsed = self.done - self.already, now - self.t0
        todo = self.total - self.done
        if ran > 0 and elapsed > 0:
            left = todo * elapsed / ran
            eta = "%d:%02d:%02d left" % (left // 3600, left // 60 % 60, left % 60)
            rate = " %.2f frames/s" % (ran / elapsed)
        else:
            eta, rate = "--:--:-- left", ""
        fill = int(self.width * self.done / self.total) if self.total else self.width
        return "[%s%s] %d/%d frames%s, %s " % ("#" * fill, "." * (self.width - fill), self.done, self.total, rate,
                                                eta)

    def close(self):
        if self.enabled:
            self.update(self.done, force=True)
            self.stream.write("\n")
            self.stream.flush()


def _chunks(first, last, chunk):
    out, s = [], first
    while s <= last:
        e = min(last, s + chunk - 1)
        out.append((s, e))
        s = e + 1
    return out


def _default_workers():
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:
        return max(1, os.cpu_count() or 1)


def run_frames(graph, frames=None, client=None, chunk=None, warmup=None, workers=None, threads=None, sets=(),
               manifest=None, verify=False, report=None, progress=None, retries=2, validate=True, bar=None,
               _fault=None):
    """Run `graph` (a graph file's path or a Graph built from files) over
    `frames` ("A-B", (A, B), range; default: the graph's own range, else
    every frame of the first read pattern on disk) as Dask tasks.

    client: None starts a LocalCluster here (`workers` processes, default
      one per core) and closes it after; a scheduler address
      ("tcp://host:8786") or a distributed.Client uses that cluster.
    chunk: frames per task (default: about four tasks per worker, and at
      least 8 * warmup frames so warm-up adds at most 1/8 to the work).
    warmup: frames each chunk runs before its first written one (default:
      DEFAULT_TEMPORAL_WARMUP when the graph has a temporal node, else 0).
    threads: device threads per worker process (default: the cores of its
      machine shared among the worker processes Dask has there).
    sets: "NODE.PARAM=VALUE" assignments, as --set.
    manifest: the sidecar manifest's path (default: .edgewise-manifest.json
      beside the first write node's files). verify: check SHA-256, not only
      size and mtime, before skipping a frame.
    report: also write the report (JSON) to this path.
    progress: progress(done, total) after each frame; bar: draw a progress
      bar on stderr (default: when stderr is a terminal).

    Returns the report: {"frames": [per frame: status ("written",
    "skipped"), where (worker address), host, pid, methods (what `auto`
    chose, as ew_denoiser_describe says), seconds, written, ...], ...}.
    Raises DistributedRunError when frames failed (after `retries`)."""
    t_start = time.time()
    spec = _graph_spec(graph, sets)
    nodes, graph_frames = _nodes_of(spec)
    writers = _writers(nodes)
    if not writers:
        raise ValueError("the graph writes no files (no write node with a path): nothing to distribute")
    if frames is not None:
        first, last = parse_frames(frames)
    elif graph_frames is not None:
        first, last = graph_frames
    else:
        found = []
        for nid, n in nodes.items():  # the first read pattern, in the file's order
            p = n["params"].get("path")
            if nid not in writers and isinstance(p, str) and "#" in os.path.basename(p):
                found = _frames_on_disk(p)
                break
        if not found:
            raise ValueError("no frame range: give frames (A-B) or a '#' pattern in a read path matching files")
        first, last = found[0], found[-1]
    temporal = _temporal_nodes(nodes)
    if warmup is None:
        warmup = DEFAULT_TEMPORAL_WARMUP if temporal else 0
    warmup = max(0, int(warmup))
    if validate:
        g = Graph.from_spec(spec)
        try:
            g.set_frames(first, last)
            g.validate()
        finally:
            g.close()
    ghash = _graph_hash(spec)
    man = Manifest(manifest or os.path.join(os.path.dirname(sorted(writers.items())[0][1]), MANIFEST_NAME))
    all_frames = list(range(first, last + 1))
    done = set(f for f in all_frames
               if all(man.complete(frame_path(p, f), ghash, verify) for p in writers.values()))

    own_cluster = own_client = None
    import distributed  # noqa: the optional dependency, only now
    try:
        if client is None and len(done) == len(all_frames):
            pass  # nothing to do: no cluster to start
        elif client is None:
            nw = int(workers) if workers else _default_workers()
            own_cluster = distributed.LocalCluster(n_workers=nw, threads_per_worker=1, processes=True,
                                                   dashboard_address=None)
            client = own_client = distributed.Client(own_cluster)
        elif isinstance(client, str):
            client = own_client = distributed.Client(client)
        info = client.scheduler_info().get("workers", {}) if client is not None else {}
        nworkers = max(1, len(info)) if client is not None else 0
        per_host = {}
        for w in info.values():
            per_host[w.get("host")] = per_host.get(w.get("host"), 0) + 1
        if chunk is None:  # about four tasks per worker; warm-up at most 1/8 of a chunk's frames
            chunk = max(1, int(math.ceil(len(all_frames) / (4.0 * max(1, nworkers)))), 8 * warmup)
        chunk = max(1, int(chunk))
        run_id = "%s-%s" % (time.strftime("%Y%m%d%H%M%S"), uuid.uuid4().hex[:6])
        topic = "edgewise-progress-" + run_id
        jobs = []
        for k, (s, e) in enumerate(_chunks(first, last, chunk)):
            todo = [f for f in range(s, e + 1) if f not in done]
            if not todo:
                continue
            if warmup > 0:
                runs = [(max(first, todo[0] - warmup), todo[-1])]
            else:
                runs, a = [], todo[0]
                for i in range(1, len(todo) + 1):
                    if i == len(todo) or todo[i] != todo[i - 1] + 1:
                        runs.append((a, todo[i - 1]))
                        if i < len(todo):
                            a = todo[i]
            jobs.append({"spec": spec, "run_id": run_id, "chunk": k, "chunk_frames": [s, e], "runs": runs,
                         "write": todo, "writers": writers, "threads": None if threads is None else int(threads),
                         "workers_per_host": per_host, "topic": topic,
                         "fault": _fault})
        records = {}
        errors = []
        shown = set(done)
        bar_ = ProgressBar(len(all_frames), len(done), enabled=bar)
        bar_.update(len(shown), force=True)
        if progress is not None:
            progress(len(shown), len(all_frames))
        events = []  # appended on the client's event loop thread, read here (list.append is atomic)
        if jobs:
            client.subscribe_topic(topic, events.append)
        futures = {}
        for job in jobs:
            fut = client.submit(run_chunk, job, key="edgewise-%s-chunk%d" % (run_id, job["chunk"]), pure=False,
                                retries=retries)
            futures[fut] = job
        ac = distributed.as_completed(list(futures))
        try:
            while not ac.is_empty() or ac.has_ready():
                finished = ac.next_batch(block=False) if ac.has_ready() else []
                for fut in finished:
                    job = futures[fut]
                    try:
                        recs = fut.result()
                    except Exception as e:  # the chunk failed for good (retries spent, or a lost worker)
                        errors.append({"chunk": job["chunk"], "frames": job["write"], "error": "%s: %s"
                                       % (type(e).__name__, e)})
                        continue
                    for r in recs:
                        records[r["frame"]] = r
                        for path, info in r["outputs"].items():
                            man.record(path, r["frame"], ghash, info)
                        shown.add(r["frame"])
                    man.save()
                while events:
                    ev = events.pop(0)
                    msg = ev[1] if isinstance(ev, tuple) and len(ev) == 2 else ev
                    if isinstance(msg, dict) and msg.get("frame") in range(first, last + 1):
                        shown.add(msg["frame"])
                bar_.update(len(shown))
                if progress is not None:
                    progress(len(shown), len(all_frames))
                if not finished:
                    time.sleep(0.05)
        finally:
            bar_.close()
            if jobs:
                client.unsubscribe_topic(topic)
            for fut in futures:
                fut.release()
            for root in set(os.path.dirname(p) for p in writers.values()):
                try:
                    names = os.listdir(root)
                except OSError:
                    continue
                for name in names:
                    if name.startswith("%s%s-" % (SCRATCH_PREFIX, run_id)):
                        shutil.rmtree(os.path.join(root, name), ignore_errors=True)
        if client is not None:
            nworkers = max(1, len(client.scheduler_info().get("workers", {})))
    finally:
        if own_client is not None:
            own_client.close()
        if own_cluster is not None:
            own_cluster.close()

    failed = {}
    for e in errors:
        for f in e["frames"]:
            failed[f] = e["error"]
    out_frames = []
    for f in all_frames:
        if f in records:
            out_frames.append(records[f])
        elif f in done:
            out_frames.append({"frame": f, "status": "skipped", "written": sorted(frame_path(p, f)
                                                                               for p in writers.values())})
        else:
            out_frames.append({"frame": f, "status": "failed", "error": failed.get(f, "not run")})
    n_written = sum(1 for r in out_frames if r["status"] == "written")
    seconds = time.time() - t_start
    rep = {"frames": out_frames, "frames_written": n_written, "frames_skipped": len(done),
           "frames_failed": len(out_frames) - n_written - len(done), "first": first, "last": last,
           "chunk": chunk, "warmup": warmup, "temporal_nodes": temporal, "chunks_run": len(jobs),
           "workers": nworkers, "threads_per_worker": threads if threads is not None else "auto", "manifest": man.path, "seconds": seconds,
           "ok": not errors}
    if errors:
        rep["errors"] = errors
    if report:
        _write_atomic(os.fspath(report), json.dumps(rep, indent=2) + "\n")
    if errors:
        raise DistributedRunError("%d of %d frames failed: %s" % (rep["frames_failed"], len(all_frames),
                                                                    errors[0]["error"]), rep)
    return rep


# ---- command line ----------------------------------------------------------

def _summary_line(r):
    if r["status"] == "skipped":
        return "frame %d: complete, skipped" % r["frame"]
    if r["status"] == "failed":
        return "frame %d: FAILED: %s" % (r["frame"], r.get("error", ""))
    parts = ["frame %d:" % r["frame"]]
    for nid, what in sorted(r.get("methods", {}).items()):
        parts.append(" %s: %s;" % (nid, what))
    for w in r.get("written", []):
        parts.append(" wrote %s;" % w)
    for nid, m in sorted(r.get("metrics", {}).items()):
        p = m.get("psnr")
        parts.append(" %s: PSNR %s dB SSIM %.4f;" % (nid, "inf" if p is None else "%.2f" % p, m.get("ssim", 0.0)))
    parts.append(" %.3f s on %s (%s pid %d)" % (r.get("seconds") or 0.0, r["where"], r["host"], r["pid"]))
    return "".join(parts)


def main(argv=None):
    p = argparse.ArgumentParser(
        prog="edgewise graph run (Dask)",
        description="Run a node graph file over a frame range as Dask tasks (docs/distributed.md).")
    p.add_argument("command", nargs="?", choices=["run"], help=argparse.SUPPRESS)
    p.add_argument("file", help="graph file (JSON)")
    p.add_argument("--frames", help="frames to run, A-B or A (default: the file's, else every frame on disk)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--scheduler", metavar="ADDRESS", help="a Dask scheduler, e.g. tcp://head:8786")
    where.add_argument("--workers", type=int, metavar="N", help="a LocalCluster of N worker processes (default: "
                       "one per core)")
    p.add_argument("--threads", type=int, metavar="N", help="device threads per worker process (default: its "
                   "machine's cores / the worker processes there)")
    p.add_argument("--chunk", type=int, metavar="N", help="frames per task")
    p.add_argument("--warmup", type=int, metavar="N", help="frames run before each chunk for temporal filters")
    p.add_argument("--set", action="append", default=[], metavar="NODE.PARAM=VALUE", help="set a parameter")
    p.add_argument("--report", metavar="FILE", help="write the per-frame report (JSON)")
    p.add_argument("--manifest", metavar="FILE", help="the sidecar manifest of complete frames")
    p.add_argument("--verify", action="store_true", help="check the SHA-256 of complete frames before skipping")
    p.add_argument("--retries", type=int, default=2, help="times a failing chunk is retried (default 2)")
    p.add_argument("-q", "--quiet", action="store_true", help="print errors only")
    a = p.parse_args(argv)
    if a.workers is not None and a.workers < 1:
        p.error("--workers must be at least 1")
    for name in ("threads", "chunk", "warmup", "retries"):
        v = getattr(a, name)
        if v is not None and v < (1 if name == "chunk" else 0):
            p.error("--%s: %d is out of range" % (name, v))
    import logging
    import warnings
    # Dask's own chatter (a busy default HTTP port, a worker restarted after a crash) is not the
    # user's business here; failures still reach the report and the exit status.
    logging.getLogger("distributed").setLevel(logging.ERROR)
    warnings.filterwarnings("ignore", module="distributed")
    try:
        rep = run_frames(a.file, a.frames, client=a.scheduler, chunk=a.chunk, warmup=a.warmup, workers=a.workers,
                         threads=a.threads, sets=a.set, manifest=a.manifest, verify=a.verify, report=a.report,
                         retries=a.retries, bar=None if not a.quiet else False)
    except DistributedRunError as e:
        if not a.quiet:
            for r in e.report["frames"]:
                print(_summary_line(r))
        sys.stderr.write("edgewise: %s\n" % e)
        return 1
    except (EdgewiseError, ValueError, OSError) as e:
        sys.stderr.write("edgewise: %s\n" % e)
        return 1
    if not a.quiet:
        for r in rep["frames"]:
            print(_summary_line(r))
        print("%d frames: %d written, %d skipped; %d chunks of %d (warm-up %d) on %d workers; %.2f s"
              % (len(rep["frames"]), rep["frames_written"], rep["frames_skipped"], rep["chunks_run"], rep["chunk"],
                 rep["warmup"], rep["workers"], rep["seconds"]))
    return 0


if __name__ == "__main__":
    # run as edgewise.distributed, not __main__: Dask pickles run_chunk by reference to its module
    from edgewise.distributed import main as _main
    sys.exit(_main())
