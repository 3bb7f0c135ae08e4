#!/usr/bin/env python3
"""What a user waits for: the end-to-end path of the CLI, not the warm kernel.

For each method (auto, nbg, pyramid, dof) and size (1280x720, 2560x1440):

- a one-shot CLI run as a user types it, with `--timings`: start-up (process
  creation to main), read, compute, write as the CLI reports them, and from
  the kernel (wait4): wall, user and system time, peak RSS, minor page faults;
  then the same with `--timings=3` for the warm in-process compute (fastest
  of 3 more executes of the same op);
- a `graph run` of the same work over 24 frames (the same file linked as
  frames 1..24): per-frame time (median of frames 2..24, the graph's report);
- `edgewise --version` (start-up alone) and `oiiotool` copying the input.

It prints the ratios the targets are stated in, all measured in this one run
(the machine is shared: ratios within one run, not absolute times, compare):

- compute / warm compute           (one-shot reported compute, target <= 2)
- whole / (oiiotool copy + warm)   (whole process, target <= 1.5)
- graph frame / (read + warm + write)  (per frame in a graph, target <= 1.3)
- sys / user                       (kernel time, target <= 0.15)
- peak RSS / float RGB frame       (target <= 5)

Inputs are made with oiiotool from samples/cornell (4 spp) scaled up, the
colour given Gaussian noise of sigma 0.08 (as incompressible as a render's):
a Cycles multilayer EXR (19 channels; denoisers and dof) and an RGB float
EXR (pyramid, the filter on a plain image).

    /usr/bin/python3 bench/bench_e2e.py --cli build/bin/edgewise --out /tmp/ew_e2e
    # two builds, alternating case by case:
    /usr/bin/python3 bench/bench_e2e.py --cli before=OLD/bin/edgewise --cli after=build/bin/edgewise
    # the one-shot figures as the medians of 5 runs of each build (still one run of the bench):
    /usr/bin/python3 bench/bench_e2e.py --cli before=OLD/bin/edgewise --cli after=build/bin/edgewise --repeat 5
    # peak memory only (one plain one-shot run per case, no warm runs or graphs), e.g. at 4K:
    /usr/bin/python3 bench/bench_e2e.py --peak-rss --sizes 3840x2160 --cli before=... --cli after=...
"""
import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
SAMPLE = os.path.join(HERE, "..", "samples", "cornell", "f0001_spp0004.exr")
ML_OTHER = ("ViewLayer.Combined.A,ViewLayer.Denoising Albedo.R,ViewLayer.Denoising Albedo.G,"
            "ViewLayer.Denoising Albedo.B,ViewLayer.Denoising Depth.Z,ViewLayer.Denoising Normal.X,"
            "ViewLayer.Denoising Normal.Y,ViewLayer.Denoising Normal.Z,ViewLayer.Depth.Z,ViewLayer.Normal.X,"
            "ViewLayer.Normal.Y,ViewLayer.Normal.Z,ViewLayer.Vector.X,ViewLayer.Vector.Y,ViewLayer.Vector.Z,"
            "ViewLayer.Vector.W")

# method -> (input kind, CLI arguments after the input, graph nodes after "in")
METHODS = {
    "auto": ("ml", ["denoise", "--method", "auto"],
             {"dn": {"type": "denoise", "params": {"method": "auto"},
                     "inputs": {"color": "in.color", "albedo": "in.albedo", "normal": "in.normal",
                                "depth": "in.depth"}}}),
    "nbg": ("ml", ["denoise", "--method", "nbg"],
            {"dn": {"type": "denoise", "params": {"method": "nbg"},
                    "inputs": {"color": "in.color", "albedo": "in.albedo", "normal": "in.normal",
                                "depth": "in.depth"}}}),
    "pyramid": ("rgb", ["filter", "--method", "pyramid", "--radius", "24"],
                {"dn": {"type": "pyramid", "params": {"radius": 24}, "inputs": {"color": "in.color"}}}),
    "dof": ("ml", ["dof"],
            {"dn": {"type": "dof", "inputs": {"color": "in.color", "depth": "in.z"}}}),
}

TIMINGS = re.compile(r"timings: start-up (\S+) s, read (\S+) s, compute (\S+) s, write (\S+) s, total (\S+) s"
                     r"(?:, warm compute (\S+) s)?")


def run(cmd, env=None):
    """Run cmd; wall seconds, rusage of the child, its stderr."""
    t0 = time.monotonic()
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    # read the pipes before waiting (a full pipe would block the child)
    out, err = p.stdout.read(), p.stderr.read()
    _, status, ru = os.wait4(p.pid, 0)
    wall = time.monotonic() - t0
    p.returncode = os.waitstatus_to_exitcode(status)
    if p.returncode != 0:
        sys.exit("failed (%d): %s\n%s%s" % (p.returncode, " ".join(cmd), out.decode(), err.decode()))
    return wall, ru, err.decode()


# --features: which feature passes of the multilayer input are stored as half
HALF_FEATURES = {"float": [], "blender": ["Denoising Albedo.R", "Denoising Albedo.G", "Denoising Albedo.B"]}
HALF_FEATURES["half"] = HALF_FEATURES["blender"] + ["Denoising Normal.X", "Denoising Normal.Y", "Denoising Normal.Z",
                                                   "Denoising Depth.Z"]


def make_inputs(d, size, features="float"):
    w, h = size
    g = "%dx%d" % (w, h)
    ml, rgb = os.path.join(d, "ml_%s.exr" % g), os.path.join(d, "rgb_%s.exr" % g)
    if features != "float":
        # the float file's values, those feature passes stored as half (a
        # file as Blender writes it: its denoising albedo is half)
        flt = make_inputs(d, size)
        ml = os.path.join(d, "ml_%s_%s.exr" % (g, features))
        if not os.path.exists(ml):
            cmd = [shutil.which("oiiotool"), flt["ml"], "-d", "float"]
            for c in HALF_FEATURES[features]:
                cmd += ["-d", "ViewLayer.%s=half" % c]
            subprocess.check_call(cmd + ["-o", ml])
        return {"ml": ml, "rgb": flt["rgb"]}
    if os.path.exists(ml) and os.path.exists(rgb):
        return {"ml": ml, "rgb": rgb}
    base = os.path.join(d, "base_%s.exr" % g)
    oi = shutil.which("oiiotool")
    subprocess.check_call([oi, SAMPLE, "--resize:filter=box", g, "-o", base])
    subprocess.check_call([oi, base, "--ch", "R=ViewLayer.Combined.R,G=ViewLayer.Combined.G,B=ViewLayer.Combined.B",
                           "-d", "float", "--noise:type=gaussian:stddev=0.08:seed=7", "-o", rgb])
    subprocess.check_call([oi, base, "--ch", ML_OTHER, rgb, "--chnames",
                           "ViewLayer.Combined.R,ViewLayer.Combined.G,ViewLayer.Combined.B", "--chappend", "-o", ml])
    os.remove(base)
    return {"ml": ml, "rgb": rgb}


def timings(cli, method, src, out, flag):
    kind, args, _ = METHODS[method]
    cmd = [cli] + args[:1] + [src, "-o", out, "-q", flag] + args[1:]
    wall, ru, err = run(cmd)
    m = TIMINGS.search(err)
    if not m:
        sys.exit("no timings line from: %s\n%s" % (" ".join(cmd), err))
    return wall, ru, [float(x) if x is not None else float("nan") for x in m.groups()]


def one_shot(cli, method, src, out):
    """The run as a user types it (plus --timings), then one more with
    --timings=3 for the warm in-process compute of the same work."""
    wall, ru, v = timings(cli, method, src, out, "--timings")
    warm = timings(cli, method, src, out, "--timings=3")[2][5]
    return {"wall": wall, "user": ru.ru_utime, "sys": ru.ru_stime, "rss_mb": ru.ru_maxrss / 1024.0,
            "minflt": ru.ru_minflt, "startup": v[0], "read": v[1], "compute": v[2], "write": v[3], "warm": warm}


def median_run(runs):
    """The median of each figure over repeated one-shot runs of one build (one run: itself)."""
    return {k: statistics.median(r[k] for r in runs) for k in runs[0]}


def graph(cli, method, src, d, frames):
    _, _, nodes = METHODS[method]
    seq = os.path.join(d, "seq_%s" % os.path.basename(src)[:-4])
    os.makedirs(seq, exist_ok=True)
    for f in range(1, frames + 1):
        link = os.path.join(seq, "f_%04d.exr" % f)
        if not os.path.lexists(link):
            os.symlink(os.path.abspath(src), link)
    spec = {"edgewise_graph": 1, "frames": "1-%d" % frames,
            "nodes": dict({"in": {"type": "read", "params": {"path": os.path.join(seq, "f_####.exr")}}}, **nodes)}
    keep = METHODS[method][0] == "ml"
    spec["nodes"]["out"] = {"type": "write", "inputs": {"image": "dn"},
                            "params": {"path": os.path.join(d, "gout_%s_####.exr" % method),
                                       "keep_source": keep, "pixel_type": "float"}}
    gfile, report = os.path.join(d, "g_%s.json" % method), os.path.join(d, "g_%s_report.json" % method)
    with open(gfile, "w") as fp:
        json.dump(spec, fp, indent=1)
    wall, ru, _ = run([cli, "graph", "run", gfile, "-q", "--report", report])
    with open(report) as fp:
        secs = [fr["seconds"] for fr in json.load(fp)["frames"]]
    for f in range(1, frames + 1):
        os.remove(os.path.join(d, "gout_%s_%04d.exr" % (method, f)))
    return {"frame": statistics.median(secs[1:]) if len(secs) > 1 else secs[0], "first": secs[0], "wall": wall,
            "user": ru.ru_utime, "sys": ru.ru_stime, "rss_mb": ru.ru_maxrss / 1024.0, "minflt": ru.ru_minflt}


def peak_rss(a, clis, sizes, methods):
    """One plain one-shot run per case and build (no --timings runs, no graph), builds alternating:
    peak RSS against the float RGB frame, user and system time, minor faults."""
    rows = []
    for size in sizes:
        inputs = make_inputs(a.out, size, a.features)
        rgb_mb = size[0] * size[1] * 3 * 4 / 1e6
        for method in methods:
            kind, args, _ = METHODS[method]
            for rep in range(a.repeat):
                for label, cli in clis:
                    out = os.path.join(a.out, "out_%s_%s.exr" % (method, label))
                    wall, ru, _ = run([cli] + args[:1] + [inputs[kind], "-o", out, "-q"] + args[1:])
                    r = {"build": label, "method": method, "size": "%dx%d" % size, "wall": wall,
                         "user": ru.ru_utime, "sys": ru.ru_stime, "rss_mb": ru.ru_maxrss * 1024 / 1e6,
                         "minflt": ru.ru_minflt, "rgb_mb": rgb_mb}
                    rows.append(r)
                    print("%-8s %-8s %-9s peak RSS %5.0f MB (%.1fx RGB) user %.2f sys %.2f wall %.2f faults %d"
                          % (label, method, r["size"], r["rss_mb"], r["rss_mb"] / rgb_mb, r["user"], r["sys"],
                             wall, r["minflt"]), flush=True)
    print("\nload average at end: %.2f %.2f %.2f" % os.getloadavg())
    print("\n| method | size | build | peak RSS (MB = 10^6 B) | x float RGB (<= 5) | user + sys s | minor faults |")
    print("|---|---|---|---:|---:|---|---:|")
    for r in rows:
        print("| %s | %s | %s | %.0f | %.1f | %.2f + %.2f | %d |" % (r["method"], r["size"], r["build"], r["rss_mb"],
              r["rss_mb"] / r["rgb_mb"], r["user"], r["sys"], r["minflt"]))
    if a.json:
        with open(a.json, "w") as fp:
            json.dump({"rows": rows, "load": os.getloadavg()}, fp, indent=1)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cli", action="append",
                    help="the edgewise program, or LABEL=PATH, repeatable: builds compared case by case in one run "
                         "(default build/bin/edgewise)")
    ap.add_argument("--out", default="/tmp/ew_e2e")
    ap.add_argument("--sizes", default="1280x720,2560x1440")
    ap.add_argument("--methods", default="auto,nbg,pyramid,dof")
    ap.add_argument("--frames", default="24", help="graph frames, one number or one per size (24,8)")
    ap.add_argument("--json", help="also write the figures here")
    ap.add_argument("--peak-rss", action="store_true",
                    help="only the plain one-shot run of each case (as a user types it): peak RSS, CPU time, faults")
    ap.add_argument("--features", choices=sorted(HALF_FEATURES), default="float",
                    help="how the multilayer input stores its feature passes: float (every channel, as scaling "
                         "leaves them; the default), blender (the denoising albedo half, as Blender writes it), "
                         "half (albedo, normal and depth half); the CLI holds passes stored as half as halves for "
                         "a run that reads them so (kpcn's streamed tiles)")
    ap.add_argument("--repeat", type=int, default=1,
                    help="runs of each one-shot case, builds alternating: the figures are their medians (a single "
                         "one-shot's compute moves +-15%% from run to run on a shared machine); with --peak-rss, "
                         "each run is printed")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    clis = []
    for c in a.cli or [os.path.join(HERE, "..", "build", "bin", "edgewise")]:
        label, _, path = c.rpartition("=")
        clis.append((label or "run", os.path.abspath(path)))
    sizes = [tuple(int(v) for v in s.split("x")) for s in a.sizes.split(",")]
    frames = [int(f) for f in a.frames.split(",")]
    frames += [frames[-1]] * (len(sizes) - len(frames))
    methods = a.methods.split(",")
    print("load average at start: %.2f %.2f %.2f" % os.getloadavg())

    startup = {}
    for label, cli in clis:
        ver = min((run([cli, "--version"]) for _ in range(3)), key=lambda r: r[0])
        startup[label] = {"wall": ver[0], "rss_mb": ver[1].ru_maxrss / 1024.0, "minflt": ver[1].ru_minflt}
        print("%s: edgewise --version: %.3f s, peak RSS %.0f MB, %d minor faults"
              % (label, ver[0], startup[label]["rss_mb"], startup[label]["minflt"]))

    if a.peak_rss:
        peak_rss(a, clis, sizes, methods)
        return

    rows = []
    for size, nframes in zip(sizes, frames):
        inputs = make_inputs(a.out, size, a.features)
        rgb_mb = size[0] * size[1] * 3 * 4 / 2**20
        copies = {}
        for kind, src in inputs.items():
            dst = os.path.join(a.out, "copy.exr")
            copies[kind] = run([shutil.which("oiiotool"), src, "-o", dst])[0]
            os.remove(dst)
        for method in methods:
            kind = METHODS[method][0]
            out = os.path.join(a.out, "out_%s.exr" % method)
            runs = {label: [] for label, _ in clis}
            for _ in range(a.repeat):
                for label, cli in clis:  # builds alternate case by case: the same load for both
                    runs[label].append(one_shot(cli, method, inputs[kind], out))
                    os.remove(out)
            for label, cli in clis:
                o = median_run(runs[label])
                g = graph(cli, method, inputs[kind], a.out, nframes)
                r = {"build": label, "method": method, "size": "%dx%d" % size, "input": kind, "rgb_mb": rgb_mb,
                     "copy": copies[kind], "frames": nframes, "one": o, "one_runs": runs[label], "graph": g}
                r["ratios"] = {
                    "compute/warm": o["compute"] / o["warm"],
                    "whole/(copy+warm)": o["wall"] / (copies[kind] + o["warm"]),
                    "graph/(read+warm+write)": g["frame"] / (o["read"] + o["warm"] + o["write"]),
                    "sys/user one-shot": o["sys"] / o["user"],
                    "sys/user graph": g["sys"] / g["user"],
                    "RSS/RGB": o["rss_mb"] / rgb_mb,
                }
                rows.append(r)
                print("%-6s %-8s %-9s one-shot wall %6.2f s (start-up %.2f, read %.2f, compute %.2f, write %.2f;"
                      " warm %.3f) user %.2f sys %.2f RSS %4.0f MB faults %7d | oiiotool copy %.2f |"
                      " graph %.3f s/frame of %d (first %.2f) user %.1f sys %.1f RSS %4.0f MB faults %7d"
                      % (label, method, r["size"], o["wall"], o["startup"], o["read"], o["compute"], o["write"],
                         o["warm"], o["user"], o["sys"], o["rss_mb"], o["minflt"], copies[kind], g["frame"],
                         nframes, g["first"], g["user"], g["sys"], g["rss_mb"], g["minflt"]), flush=True)

    print("\nload average at end: %.2f %.2f %.2f" % os.getloadavg())
    print("\n| build | method | size | compute / warm (<= 2) | whole / (copy + warm) (<= 1.5) "
          "| graph frame / (read + warm + write) (<= 1.3) | sys / user one-shot, graph (<= 0.15) "
          "| peak RSS / RGB float (<= 5) | graph s/frame | one-shot faults |")
    print("|---|---|---|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        q = r["ratios"]
        print("| %s | %s | %s | %.2f | %.2f | %.2f | %.2f, %.2f | %.1f (%.0f MB) | %.2f | %d |"
              % (r["build"], r["method"], r["size"], q["compute/warm"], q["whole/(copy+warm)"],
                 q["graph/(read+warm+write)"], q["sys/user one-shot"], q["sys/user graph"], q["RSS/RGB"],
                 r["one"]["rss_mb"], r["graph"]["frame"], r["one"]["minflt"]))
    if a.json:
        with open(a.json, "w") as fp:
            json.dump({"startup": startup, "rows": rows, "load": os.getloadavg()}, fp, indent=1)


if __name__ == "__main__":
    main()
