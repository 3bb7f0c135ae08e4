"""Frames per second of a graph over a frame range: the single-process
`edgewise graph run` against the same graph on Dask (edgewise.distributed)
on the same cores, and the figures a farm plan needs (per-frame cost, bytes
read and written per frame, the scheduler's cost per task).

    /usr/bin/python3 bench/bench_distributed.py --cli build/bin/edgewise [--frames 96] [--repeat 3]

The sequence is samples/cornell/f0001_spp0004.exr (256x256, Cycles
multilayer EXR) linked as frames 1..N, so every frame costs the same and
reads come from the page cache for both runs alike. Graph: read -> denoise
(--method, default auto) -> write EXR (half). Runs alternate (single, Dask,
single, ...) and the fastest of --repeat is kept for each: other jobs on a
shared machine only ever add time.

Dask is timed two ways: "steady" runs on a LocalCluster started beforehand
(the farm's case: the cluster outlives a run), "cold" is the whole
`edgewise graph run --workers N` command, cluster start-up included.
Prints a Markdown table (BENCHMARKS.md) and writes --json if given.
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "python"))

import distributed  # noqa: E402

from edgewise import distributed as ewd  # noqa: E402

SAMPLE = os.path.join(HERE, "..", "samples", "cornell", "f0001_spp0004.exr")


def write_graph(path, seq, out_pattern, method):
    g = {"edgewise_graph": 1, "nodes": {
        "render": {"type": "read", "params": {"path": os.path.join(seq, "f####.exr")}},
        "dn": {"type": "denoise", "params": {"method": method},
               "inputs": {"color": "render.color", "albedo": "render.albedo", "normal": "render.normal"}},
        "out": {"type": "write", "params": {"path": out_pattern}, "inputs": {"image": "dn"}}}}
    with open(path, "w") as f:
        json.dump(g, f, indent=1)


def fresh(d):
    shutil.rmtree(d, ignore_errors=True)
    os.makedirs(d)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--cli", required=True, help="the edgewise program (build/bin/edgewise)")
    p.add_argument("--frames", type=int, default=96)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--threads", type=int, default=2, help="cores: single-process threads; workers * threads each")
    p.add_argument("--chunk", type=int, default=None)
    p.add_argument("--method", default="auto")
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--tasks", type=int, default=400, help="no-op tasks for the scheduler's cost per task")
    p.add_argument("--json", help="also write the figures here")
    a = p.parse_args()

    tmp = tempfile.mkdtemp(prefix="ew_bench_dask_")
    try:
        seq = os.path.join(tmp, "seq")
        os.makedirs(seq)
        for f in range(1, a.frames + 1):
            os.symlink(os.path.abspath(SAMPLE), os.path.join(seq, "f%04d.exr" % f))
        graph = os.path.join(tmp, "g.json")
        out_dir = os.path.join(tmp, "out")
        write_graph(graph, seq, os.path.join(out_dir, "dn_####.exr"), a.method)
        rng = "1-%d" % a.frames
        env = dict(os.environ)

        def single():
            fresh(out_dir)
            t0 = time.perf_counter()
            r = subprocess.run([a.cli, "graph", "run", graph, "--frames", rng, "--threads", str(a.threads), "-q"],
                               env=env)
            if r.returncode:
                sys.exit("single-process run failed")
            return time.perf_counter() - t0

        per_worker = max(1, a.threads // a.workers)
        cluster = distributed.LocalCluster(n_workers=a.workers, threads_per_worker=1, processes=True,
                                           dashboard_address=None)
        client = distributed.Client(cluster)

        def steady():
            fresh(out_dir)
            t0 = time.perf_counter()
            rep = ewd.run_frames(graph, rng, client=client, chunk=a.chunk, threads=per_worker, bar=False)
            t = time.perf_counter() - t0
            steady.report = rep
            return t

        def cold():
            fresh(out_dir)
            t0 = time.perf_counter()
            cmd = [a.cli, "graph", "run", graph, "--frames", rng, "--workers", str(a.workers), "--threads",
                   str(per_worker), "-q"]
            if a.chunk:
                cmd += ["--chunk", str(a.chunk)]
            r = subprocess.run(cmd, env=env)
            if r.returncode:
                sys.exit("Dask run failed")
            return time.perf_counter() - t0

        times = {"single": [], "steady": [], "cold": []}
        steady()  # workers import numpy and load the libraries once
        for _ in range(a.repeat):
            times["single"].append(single())
            times["steady"].append(steady())
            times["cold"].append(cold())
        rep = steady.report
        in_bytes = os.path.getsize(SAMPLE)
        out_bytes = sum(os.path.getsize(os.path.join(out_dir, n)) for n in os.listdir(out_dir)
                        if n.endswith(".exr")) / float(a.frames)
        frame_s = sorted(r["seconds"] for r in rep["frames"])
        median_frame = frame_s[len(frame_s) // 2]

        # the scheduler's cost per task: no-op tasks through the same cluster
        def noop(i):
            return i
        client.gather(client.map(noop, range(50), pure=False))
        t0 = time.perf_counter()
        client.gather(client.map(noop, range(a.tasks), pure=False))
        per_task = (time.perf_counter() - t0) / a.tasks
        client.close()
        cluster.close()

        best = dict((k, min(v)) for k, v in times.items())
        fps = dict((k, a.frames / v) for k, v in best.items())
        res = {"frames": a.frames, "size": "256x256", "method": a.method, "workers": a.workers,
               "threads_per_worker": per_worker, "single_threads": a.threads, "chunk": rep["chunk"],
               "seconds": best, "all_seconds": times, "frames_per_s": fps,
               "overhead_steady": best["steady"] / best["single"] - 1.0,
               "overhead_cold": best["cold"] / best["single"] - 1.0,
               "median_frame_s_in_worker": median_frame, "input_bytes_per_frame": in_bytes,
               "output_bytes_per_frame": out_bytes, "scheduler_s_per_task": per_task,
               "loadavg": os.getloadavg(), "auto_chose": rep["frames"][0]["methods"].get("dn")}
        print("| run | cores | seconds (best of %d) | frames/s | vs single |" % a.repeat)
        print("|---|---|---|---|---|")
        print("| `graph run` one process | %d threads | %.2f | %.1f | — |" % (a.threads, best["single"], fps["single"]))
        print("| Dask, cluster running | %d workers × %d thread | %.2f | %.1f | %+.1f %% |"
              % (a.workers, per_worker, best["steady"], fps["steady"], 100 * res["overhead_steady"]))
        print("| Dask, `--workers %d` (start-up included) | %d workers × %d thread | %.2f | %.1f | %+.1f %% |"
              % (a.workers, a.workers, per_worker, best["cold"], fps["cold"], 100 * res["overhead_cold"]))
        print()
        print("%d frames of 256x256, method %s (auto chose: %s), chunk %d; all runs (s): %s"
              % (a.frames, a.method, res["auto_chose"], rep["chunk"],
                 ", ".join("%s %s" % (k, "/".join("%.2f" % x for x in v)) for k, v in times.items())))
        print("per frame in a worker: %.1f ms (median); read %.0f KB, write %.0f KB; scheduler: %.2f ms per "
              "no-op task; load average %.1f" % (1000 * median_frame, in_bytes / 1024.0, out_bytes / 1024.0,
                                                 1000 * per_task, res["loadavg"][0]))
        if a.json:
            with open(a.json, "w") as f:
                json.dump(res, f, indent=1)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
