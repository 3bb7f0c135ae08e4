"""Single nodes on numpy arrays and graphs built in Python: results against
straightforward numpy, introspection from the library's descriptors."""
from ewtest import REFERENCE, RENDER, TempDirTest, ew, np, read_image, unittest


def rand(*shape, seed=0):
    return np.random.default_rng(seed).random(shape, dtype=np.float32)


class TestMathNodes(unittest.TestCase):
    def test_add_multiply_mix(self):
        a, b = rand(6, 5, 3, seed=1), rand(6, 5, 3, seed=2)
        np.testing.assert_allclose(ew.run_node("add", a=a, b=b), a + b, rtol=0, atol=0)
        np.testing.assert_allclose(ew.run_node("multiply", a=a, b=b), a * b, rtol=0, atol=0)
        np.testing.assert_allclose(ew.run_node("mix", a=a, b=b, factor=0.25), a + (b - a) * np.float32(0.25),
                                   rtol=1e-6, atol=1e-7)
        m = rand(6, 5, 1, seed=3)
        np.testing.assert_allclose(ew.run_node("mix", a=a, b=b, mask=m, factor=1.0), a + (b - a) * m, rtol=1e-6,
                                   atol=1e-7)

    def test_one_channel_b_applies_to_rgb_not_alpha(self):
        a, b = rand(4, 4, 4, seed=1), rand(4, 4, 1, seed=2)
        out = ew.run_node("multiply", a=a, b=b)
        np.testing.assert_array_equal(out[..., :3], a[..., :3] * b)
        np.testing.assert_array_equal(out[..., 3], a[..., 3])

    def test_shuffle(self):
        a = rand(3, 4, 3)
        out = ew.run_node("shuffle", image=a, channels="BGR1")
        np.testing.assert_array_equal(out[..., :3], a[..., ::-1])
        np.testing.assert_array_equal(out[..., 3], 1.0)
        with self.assertRaises(ew.EdgewiseError) as cm:
            ew.run_node("shuffle", image=a, channels="A")
        self.assertIn("needs channel 4 but the image has 3", str(cm.exception))

    def test_demodulate_remodulate_round_trip(self):
        # the denoisers' demodulation: colour / (albedo + EW_ALBEDO_EPSILON),
        # damaged or negative albedo as black
        eps = [p for p in ew.node_type("demodulate")["params"] if p["name"] == "epsilon"][0]["default"]
        self.assertEqual(np.float32(eps), np.float32(0.01))
        c, alb = rand(8, 8, 3, seed=4), rand(8, 8, 3, seed=5)
        alb[0, 0] = (0.0, -1.0, np.nan)
        black = np.where(np.isfinite(alb) & (alb > 0), alb, 0)
        d = ew.run_node("demodulate", color=c, albedo=alb)
        np.testing.assert_allclose(d, c / (black + np.float32(eps)), rtol=1e-6)
        r = ew.run_node("remodulate", color=d, albedo=alb)
        np.testing.assert_allclose(r, c, rtol=1e-5)

    def test_outlier_clamps_a_firefly_and_fixes_nan(self):
        img = np.full((21, 21, 3), 0.5, np.float32) + rand(21, 21, 3) * 0.01
        img[10, 10] = 500.0
        img[3, 3, 1] = np.nan
        out = ew.run_node("outlier", color=img, k=3.0)
        self.assertLess(out[10, 10].max(), 1.0)
        self.assertTrue(np.isfinite(out).all())
        np.testing.assert_array_equal(out[15, 15], img[15, 15])


class TestLibraryNodes(unittest.TestCase):
    def test_every_filter_runs_on_arrays(self):
        img = rand(40, 48, 3)
        depth = np.full((40, 48, 1), 3.0, np.float32)
        for name in ("bilateral", "pyramid", "atrous"):
            info = ew.node_type(name)
            if not info["available"]:
                continue
            # weights 0: the analytic pyramid weights (no trained table needed)
            kw = {"radius": 4, "weights": "analytic"} if name == "pyramid" else {"radius": 4} if name == "bilateral" else {}
            out = ew.run_node(name, color=img, **kw)
            self.assertEqual(out.shape, img.shape, name)
            self.assertLess(float(out.std()), float(img.std()), name)  # it smooths
        if ew.node_type("dof")["available"]:
            res = ew.run_node("dof", color=img, depth=depth, focus_distance=3.0, weights=0, outputs=("output", "coc"))
            self.assertEqual(res["coc"].shape, (40, 48, 1))
            self.assertLess(float(np.abs(res["coc"]).max()), 1e-3)  # all in focus
            np.testing.assert_allclose(res["output"], img, atol=1e-5)

    def test_denoise_node_matches_the_library_defaults(self):
        info = ew.node_type("denoise", "bgrid")
        names = [p["name"] for p in info["params"]]
        self.assertEqual(names[0], "method")
        self.assertIn("spatial_rate", names)
        sr = [p for p in info["params"] if p["name"] == "spatial_rate"][0]
        self.assertEqual((sr["type"], sr["default"], sr["min"], sr["max"]), ("float", 8.0, 1.0, 256.0))
        self.assertIn("bgrid", info["params"][0]["choices"])

    def test_temporal_accumulates_over_frames(self):
        if not ew.node_type("temporal")["available"]:
            self.skipTest("no temporal filter in this libedgewise")
        frames = [rand(16, 16, 3, seed=s) for s in range(6)]
        g = ew.Graph()
        i = g.add_input(frames[0], id="in")
        g.add("output", id="o", image=g.add("temporal", id="t", color=i, alpha_min=0.2))
        outs = []
        for f in frames:
            g.set_input("in", f)
            g.run()
            outs.append(g.output("o"))
        # each run starts a new history: one frame per run gives the frame itself
        np.testing.assert_allclose(outs[-1], frames[-1], atol=1e-6)


class TestGraphs(TempDirTest):
    def test_metrics_in_report(self):
        g = ew.Graph()
        r = g.add("read", path=RENDER)
        ref = g.add("read", path=REFERENCE)
        g.add("metrics", id="noisy", image=r.color, reference=ref.color)
        d = g.add("denoise", color=r.color, albedo=r.albedo, normal=r.normal, depth=r.depth)
        g.add("metrics", id="denoised", image=d, reference=ref.color)
        rep = g.run()
        m = rep["frames"][0]["metrics"]
        self.assertGreater(m["denoised"]["psnr"], m["noisy"]["psnr"] + 3)
        st = g.stats()
        self.assertEqual(st["frames_done"], 1)
        self.assertGreaterEqual(st["planned_buffers"], 1)

    def test_report_says_what_auto_picked(self):
        g = ew.Graph()
        r = g.add("read", path=RENDER)
        g.add("denoise", id="given", samples=4, color=r.color, albedo=r.albedo, normal=r.normal, depth=r.depth)
        # the file's sample count travels with the read colour; an array has none
        g.add("denoise", id="from_file", color=r.color, albedo=r.albedo, normal=r.normal, depth=r.depth)
        g.add("denoise", id="estimated", color=g.add_input(read_image(RENDER)), albedo=r.albedo, normal=r.normal,
              depth=r.depth)
        g.add("denoise", id="plain", method="bgrid", color=r.color, albedo=r.albedo)
        for n in ("given", "from_file", "estimated", "plain"):
            g.add("output", id="o_" + n, image=g.node(n)["output"])
        methods = g.run()["frames"][0]["methods"]
        self.assertEqual(methods["given"], "kpcn kpcn-large (4 spp, quality balanced)")
        self.assertEqual(methods["from_file"], "kpcn kpcn-large (4 spp, quality balanced)")
        self.assertIn("noise estimate", methods["estimated"])
        self.assertEqual(methods["plain"], "bgrid")

    def test_write_and_read_back(self):
        img = rand(12, 10, 3)
        g = ew.Graph()
        g.add("write", image=g.add_input(img), path=self.path("x.exr"), pixel_type="float")
        g.run()
        np.testing.assert_array_equal(read_image(self.path("x.exr")), img)

    def test_loads_and_set(self):
        g = ew.Graph.loads('{"edgewise_graph": 1, "nodes": {"in": {"type": "input"},'
                           '"p": {"type": "add", "params": {"value": 1}, "inputs": {"a": "in"}},'
                           '"o": {"type": "output", "inputs": {"image": "p"}}}}')
        g.set_input("in", np.zeros((2, 2, 3), np.float32))
        g.set("p.value=2")
        g.run()
        np.testing.assert_array_equal(g.output("o"), 2.0)

    def test_display_default_view(self):
        out = ew.run_node("display", color=np.full((2, 2, 3), 0.18, np.float32), view="Standard")
        np.testing.assert_allclose(out, 0.4613, atol=2e-3)
        self.assertTrue(ew.color_config())


if __name__ == "__main__":
    unittest.main()
