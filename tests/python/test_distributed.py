"""edgewise.distributed: a graph over 8 frames of the committed sequence on a
LocalCluster of 2 worker processes, in chunks of 3, against the single-process
run; temporal filters across chunk borders; a worker killed mid-frame; re-runs
that skip complete frames; the CLI's hand-over. Localhost only."""
import json
import os

from ewtest import CLI, TempDirTest, ew, np, read_image, run, unittest

import distributed

from edgewise import distributed as ewd

SEQ = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "data", "sequence", "g_anim_21_64x64")
FRAMES = (1, 8)


def graph_file(directory, name, out_pattern, temporal=False, method="auto", denoise_params=None):
    """A graph file in `directory` reading the sequence, denoising (with
    `denoise_params` added), maybe accumulating over time, writing
    `out_pattern`."""
    nodes = {
        "render": {"type": "read", "params": {"path": os.path.join(SEQ, "f####_spp0004.exr")}},
        "dn": {"type": "denoise", "params": dict({"method": method}, **(denoise_params or {})),
               "inputs": {"color": "render.color", "albedo": "render.albedo", "normal": "render.normal"}},
        "out": {"type": "write", "params": {"path": out_pattern, "pixel_type": "float"}, "inputs": {"image": "dn"}},
    }
    if temporal:
        nodes["acc"] = {"type": "temporal", "inputs": {"color": "dn", "vector": "render.vector",
                                                       "normal": "render.normal", "depth": "render.depth"}}
        nodes["out"]["inputs"]["image"] = "acc"
    path = os.path.join(directory, name)
    with open(path, "w") as f:
        json.dump({"edgewise_graph": 1, "frames": "%d-%d" % FRAMES, "nodes": nodes}, f, indent=1)
    return path


def single_process(graph, out_pattern):
    """The reference: the whole range in one run of this process."""
    g = ew.Graph.load(graph)
    g.set("out.path=" + out_pattern)
    g.run()
    g.close()


def psnr(a, b):
    """On tone-mapped colour (clip, gamma 1/2.2), as the library's metrics."""
    a, b = np.clip(a[..., :3], 0, 1) ** (1 / 2.2), np.clip(b[..., :3], 0, 1) ** (1 / 2.2)
    mse = float(np.mean((a - b) ** 2))
    return float("inf") if mse == 0 else 10 * np.log10(1.0 / mse)


def files_under(root):
    out = []
    for d, dirs, names in os.walk(root):
        out += [os.path.relpath(os.path.join(d, n), root) for n in names]
        out += [os.path.relpath(os.path.join(d, n), root) + "/" for n in dirs]
    return sorted(out)


_cluster = {}


def setUpModule():
    # one cluster for every test here: starting worker processes is the slow part
    _cluster["cluster"] = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                                   dashboard_address=None)
    _cluster["client"] = distributed.Client(_cluster["cluster"])


def tearDownModule():
    _cluster["client"].close()
    _cluster["cluster"].close()


class DaskTest(TempDirTest):
    @property
    def client(self):
        return _cluster["client"]

    def expect_identical(self, a_pattern, b_pattern):
        for f in range(FRAMES[0], FRAMES[1] + 1):
            a, b = read_image(ewd.frame_path(a_pattern, f)), read_image(ewd.frame_path(b_pattern, f))
            self.assertTrue(np.array_equal(a, b), "frame %d differs" % f)


class TestChunks(DaskTest):
    def test_chunks_identical_to_one_process_and_rerun_skips(self):
        os.makedirs(self.path("one"))
        os.makedirs(self.path("dask"))
        g = graph_file(self.tmp, "g.json", "unused_####.exr")
        single_process(g, self.path("one/dn_####.exr"))
        out = self.path("dask/dn_####.exr")
        rep = ewd.run_frames(g, "1-8", client=self.client, chunk=3, sets=["out.path=" + out], bar=False)
        self.assertTrue(rep["ok"])
        self.assertEqual((rep["frames_written"], rep["frames_skipped"], rep["chunks_run"]), (8, 0, 3))
        self.assertEqual(rep["warmup"], 0)  # nothing temporal in this graph
        self.assertEqual(set(r["threads"] for r in rep["frames"]), {max(1, ewd._default_workers() // 2)})
        self.expect_identical(self.path("one/dn_####.exr"), out)
        # the report: where each frame ran, what auto chose (the describe text), how long
        workers = set(self.client.scheduler_info()["workers"])
        for r in rep["frames"]:
            self.assertEqual(r["status"], "written")
            self.assertIn(r["where"], workers)
            self.assertTrue(r["methods"]["dn"])
            self.assertGreater(r["seconds"], 0)
        self.assertEqual(sorted(set(r["chunk"] for r in rep["frames"])), [0, 1, 2])
        # only the outputs and the manifest: no scratch directory left
        self.assertEqual(files_under(self.path("dask")),
                         sorted([".edgewise-manifest.json"] + ["dn_%04d.exr" % f for f in range(1, 9)]))
        mtimes = [os.stat(ewd.frame_path(out, f)).st_mtime_ns for f in range(1, 9)]

        # a second run skips every frame: no task, no file touched
        rep2 = ewd.run_frames(g, "1-8", client=self.client, chunk=3, sets=["out.path=" + out], bar=False)
        self.assertEqual((rep2["frames_written"], rep2["frames_skipped"], rep2["chunks_run"]), (0, 8, 0))
        self.assertEqual([os.stat(ewd.frame_path(out, f)).st_mtime_ns for f in range(1, 9)], mtimes)

        # a damaged frame (truncated) and a missing one are redone, the rest skipped
        with open(ewd.frame_path(out, 2), "r+b") as fh:
            fh.truncate(100)
        os.unlink(ewd.frame_path(out, 7))
        rep3 = ewd.run_frames(g, "1-8", client=self.client, chunk=3, sets=["out.path=" + out], bar=False)
        self.assertEqual([r["frame"] for r in rep3["frames"] if r["status"] == "written"], [2, 7])
        self.assertEqual(rep3["chunks_run"], 2)
        self.expect_identical(self.path("one/dn_####.exr"), out)

        # other parameters make other outputs: nothing is skipped
        rep4 = ewd.run_frames(g, "1-8", client=self.client, chunk=3, bar=False,
                              sets=["out.path=" + out, "dn.method=bgrid"])
        self.assertEqual(rep4["frames_written"], 8)

    def test_same_size_damage_is_found_with_verify(self):
        os.makedirs(self.path("dask"))
        g = graph_file(self.tmp, "g.json", self.path("dask/dn_####.exr"), method="bgrid")
        ewd.run_frames(g, "1-4", client=self.client, chunk=2, bar=False)
        victim = self.path("dask/dn_0003.exr")
        st = os.stat(victim)
        with open(victim, "r+b") as fh:  # same size, same mtime, other bytes
            fh.seek(st.st_size // 2)
            b = fh.read(1)
            fh.seek(st.st_size // 2)
            fh.write(bytes([b[0] ^ 0xFF]))
        os.utime(victim, ns=(st.st_atime_ns, st.st_mtime_ns))
        rep = ewd.run_frames(g, "1-4", client=self.client, chunk=2, bar=False)
        self.assertEqual(rep["frames_written"], 0)  # size and mtime cannot see it
        rep = ewd.run_frames(g, "1-4", client=self.client, chunk=2, bar=False, verify=True)
        self.assertEqual([r["frame"] for r in rep["frames"] if r["status"] == "written"], [3])

    def test_graph_object_is_shipped(self):
        g = ew.Graph()
        r = g.add("read", id="render", path=os.path.join(SEQ, "f####_spp0004.exr"))
        d = g.add("denoise", id="dn", method="bgrid", color=r.color, albedo=r.albedo)
        g.add("write", id="out", image=d, path=self.path("obj_####.exr"))
        rep = ewd.run_frames(g, (3, 5), client=self.client, chunk=2, bar=False)
        self.assertEqual(rep["frames_written"], 3)
        g.set_frames(3, 5)
        g.set_param("out", "path", self.path("ref_####.exr"))
        g.run()
        for f in (3, 4, 5):
            self.assertTrue(np.array_equal(read_image(self.path("obj_%04d.exr" % f)),
                                           read_image(self.path("ref_%04d.exr" % f))))
        a = ew.Graph()
        a.add("write", image=a.add_input(np.zeros((4, 4, 3), np.float32)), path=self.path("x_####.exr"))
        with self.assertRaises(ValueError):
            ewd.run_frames(a, "1-2", client=self.client, bar=False)


class TestTemporal(DaskTest):
    def test_temporal_across_chunks(self):
        for d in ("one", "warm", "short", "cold"):
            os.makedirs(self.path(d))
        # The bound below is on the history a chunk misses, measured on bgrid's own output. The
        # do-no-harm blend (on by default) hands the temporal filter frames that keep more of the
        # input's noise (1.5 dB closer to the reference each, 1.5-2.4 dB after the filter), so every
        # frame of history counts more and 6 warm-up frames miss 0.152 dB at frame 8: the default
        # warm-up of 8 is what covers that (docs/distributed.md).
        g = graph_file(self.tmp, "t.json", "unused_####.exr", temporal=True, method="bgrid",
                       denoise_params={"do_no_harm": 0})
        single_process(g, self.path("one/t_####.exr"))
        one = [read_image(self.path("one/t_%04d.exr" % f)) for f in range(1, 9)]
        refs = [read_image(os.path.join(SEQ, "f%04d_ref0256.exr" % f)) for f in range(1, 9)]

        def chunked(d, warmup, chunk):
            rep = ewd.run_frames(g, "1-8", client=self.client, chunk=chunk, warmup=warmup,
                                 sets=["out.path=" + self.path(d + "/t_####.exr")], bar=False)
            self.assertEqual(rep["temporal_nodes"], ["acc"])
            return rep, [read_image(self.path(d + "/t_%04d.exr" % f)) for f in range(1, 9)]

        # 2 chunks with the default warm-up, longer than the second chunk is from frame 1: bit for bit
        rep, warm = chunked("warm", None, 4)
        self.assertEqual(rep["warmup"], ewd.DEFAULT_TEMPORAL_WARMUP)
        self.assertEqual([r["run"][0] for r in rep["frames"]], [1] * 8)
        for f in range(8):
            self.assertTrue(np.array_equal(warm[f], one[f]), "frame %d" % (f + 1))
        # 2 chunks (1-7, 8), 6 frames of warm-up: the second starts at frame 2 and misses frame 1's
        # history; per-frame PSNR within 0.1 dB of the one run (0.083 dB at frame 8)
        rep, short = chunked("short", 6, 7)
        self.assertEqual(sorted(set(tuple(r["run"]) for r in rep["frames"])), [(1, 7), (2, 8)])
        self.assertFalse(np.array_equal(short[7], one[7]))
        for f in range(8):
            diff = abs(psnr(short[f], refs[f]) - psnr(one[f], refs[f]))
            self.assertLessEqual(diff, 0.1, "frame %d: %.3f dB" % (f + 1, diff))
        # without warm-up the chunks' first frames lose their history, visibly
        rep, cold = chunked("cold", 0, 3)
        self.assertTrue(np.array_equal(cold[2], one[2]))
        self.assertGreater(abs(psnr(cold[3], refs[3]) - psnr(one[3], refs[3])), 0.2)


class TestKilledWorker(DaskTest):
    def test_worker_killed_mid_frame(self):
        os.makedirs(self.path("one"))
        os.makedirs(self.path("dask"))
        g = graph_file(self.tmp, "g.json", "unused_####.exr", method="bgrid")
        single_process(g, self.path("one/dn_####.exr"))
        marker = self.path("killed")
        out = self.path("dask/dn_####.exr")
        rep = ewd.run_frames(g, "1-8", client=self.client, chunk=3, sets=["out.path=" + out], bar=False,
                             _fault=[5, marker])
        with open(marker) as fh:
            killed = int(fh.read())
        self.assertTrue(rep["ok"])
        self.assertEqual(rep["frames_written"], 8)
        # frame 5's chunk (4-6) ran again in another process
        self.assertNotEqual(rep["frames"][4]["pid"], killed)
        with self.assertRaises(OSError):
            os.kill(killed, 0)
        self.assertEqual(files_under(self.path("dask")),
                         sorted([".edgewise-manifest.json"] + ["dn_%04d.exr" % f for f in range(1, 9)]))
        self.expect_identical(self.path("one/dn_####.exr"), out)


class TestCommandLine(DaskTest):
    def test_cli_hands_over_to_dask(self):
        if not CLI:
            self.skipTest("EW_CLI not set")
        os.makedirs(self.path("dask"))
        g = graph_file(self.tmp, "g.json", self.path("dask/dn_####.exr"), method="bgrid")
        address = self.client.scheduler.address
        r = run([CLI, "graph", "run", g, "--frames", "2-6", "--scheduler", address, "--chunk", "2", "--report",
                 self.path("r.json")])
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("frame 2:", r.stdout)
        self.assertIn("5 frames: 5 written", r.stdout)
        with open(self.path("r.json")) as fh:
            rep = json.load(fh)
        self.assertEqual([x["frame"] for x in rep["frames"]], [2, 3, 4, 5, 6])
        self.assertEqual(rep["chunks_run"], 3)
        # a local cluster of its own, and everything already there is skipped
        r = run([CLI, "graph", "run", g, "--frames", "1-6", "--workers", "1", "-q", "--report", self.path("r2.json")])
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual(r.stdout, "")
        with open(self.path("r2.json")) as fh:
            rep = json.load(fh)
        self.assertEqual((rep["frames_written"], rep["frames_skipped"], rep["workers"]), (1, 5, 1))
        # the command line's own errors
        r = run([CLI, "graph", "run", g, "--workers", "0"])
        self.assertEqual(r.returncode, 2)
        r = run([CLI, "graph", "run", self.path("nope.json"), "--frames", "1-2", "--scheduler", address])
        self.assertEqual(r.returncode, 1)
        self.assertIn("nope.json", r.stderr)


class TestProgressBar(unittest.TestCase):
    def test_text(self):
        import io
        s = io.StringIO()
        bar = ewd.ProgressBar(10, 2, stream=s, enabled=True, width=10)
        bar.t0 -= 4.0  # 4 s for 4 frames: 1 frame/s, 4 left
        bar.update(6, force=True)
        self.assertIn("[######....] 6/10 frames 1.00 frames/s, 0:00:04 left", s.getvalue())
        self.assertFalse(ewd.ProgressBar(10, 0, stream=s).enabled)  # not a terminal: no bar


if __name__ == "__main__":
    unittest.main()
