"""The package itself: finding the libraries, errors, zero-copy arrays,
progress and cancellation, Python 3.10 compatibility."""
import ast
import glob
import os
import shutil

from ewtest import TempDirTest, ew, np, python, run, unittest

PKG = os.path.dirname(ew.__file__)


class TestLibrary(TempDirTest):
    def test_version_and_location(self):
        self.assertRegex(ew.version(), r"^\d+\.\d+\.\d+$")
        self.assertTrue(os.path.exists(os.path.join(ew.library_dir(), "libedgewise_nodes.so")))

    def test_missing_library_is_a_clear_error(self):
        # a copy of the package far from any build directory
        shutil.copytree(PKG, self.path("edgewise"))
        env = dict(os.environ, EDGEWISE_LIB=self.path("nowhere"), PYTHONPATH=self.tmp)
        r = run([python(), "-c", "import edgewise; edgewise.version()"], env=env, cwd=self.tmp)
        self.assertNotEqual(r.returncode, 0)
        self.assertIn("LibraryNotFoundError", r.stderr)
        self.assertIn("EDGEWISE_LIB", r.stderr)
        # importing alone works (the library is loaded on first use)
        r = run([python(), "-c", "import edgewise"], env=env, cwd=self.tmp)
        self.assertEqual(r.returncode, 0, r.stderr)

    def test_sources_parse_as_python_3_10(self):
        # Blender 3.4 bundles Python 3.10
        files = glob.glob(os.path.join(PKG, "*.py")) + glob.glob(os.path.join(os.path.dirname(__file__), "..", "..",
                                                                                  "examples", "*.py"))
        self.assertTrue(files)
        for f in files:
            with open(f) as fh:
                ast.parse(fh.read(), f, feature_version=(3, 10))


class TestErrors(unittest.TestCase):
    def test_error_carries_the_library_message(self):
        g = ew.Graph()
        a = g.add_input(np.zeros((4, 4, 3), np.float32))
        g.add("bilateral", id="b", color=a, radius=1000)
        with self.assertRaises(ew.EdgewiseError) as cm:
            g.validate()
        self.assertEqual(cm.exception.code_name, "EW_ERR_INVALID_ARGUMENT")
        self.assertIn("node 'b' parameter 'radius' = 1000 is outside [0, 256]", str(cm.exception))

    def test_unknown_type(self):
        g = ew.Graph()
        with self.assertRaises(KeyError):
            g.add("blur")

    def test_load_errors(self):
        with self.assertRaises(ew.EdgewiseError) as cm:
            ew.Graph.loads('{"edgewise_graph": 1, "nodes": {"a": {"type": "add",}}}')
        self.assertIn("graph:1:", str(cm.exception))
        self.assertEqual(cm.exception.code_name, "EW_ERR_INVALID_DATA")


class TestArrays(unittest.TestCase):
    def test_inputs_are_not_copied(self):
        a = np.ones((8, 6, 3), np.float32)
        g = ew.Graph()
        i = g.add_input(a, id="a")
        g.add("output", id="o", image=g.add("add", id="p", a=i, value=(1, 1, 1)))
        g.run()
        np.testing.assert_array_equal(g.output("o"), a + 1)
        a *= 5  # the graph views this memory: no set_input needed
        g.run()
        np.testing.assert_array_equal(g.output("o"), np.full((8, 6, 3), 6, np.float32))

    def test_strided_views_are_used_as_they_are(self):
        big = np.arange(10 * 12 * 4, dtype=np.float32).reshape(10, 12, 4)
        view = big[::2, ::3, :3]  # pixel and row strides, contiguous channels
        view_img, kept = ew.image_view(view)
        self.assertIs(kept, view)  # no copy
        self.assertEqual((view_img.pixel_stride, view_img.row_stride), (3 * 16, 2 * 12 * 16))
        out = ew.run_node("multiply", a=view, value=(2, 2, 2))
        np.testing.assert_array_equal(out, view * 2)

    def test_zero_strides_are_copied_not_read_as_packed(self):
        # numpy's broadcast views repeat one row (row stride 0) or one pixel
        # (pixel stride 0); the C API reads a 0 stride as "packed", so such
        # a view must reach it as a copy with real strides. 4096 wide: read
        # as packed, the rows would run far past the one real row.
        for w in (64, 4096):
            row = np.linspace(0, 1, w * 3, dtype=np.float32).reshape(w, 3)
            rows = np.broadcast_to(row, (5, w, 3))
            self.assertEqual(rows.strides[0], 0)
            view, kept = ew.image_view(rows)
            self.assertNotEqual(view.row_stride, 0)
            self.assertNotEqual(view.pixel_stride, 0)
            np.testing.assert_array_equal(ew.run_node("multiply", a=rows, value=(2, 2, 2)), rows * 2)
        px = np.broadcast_to(np.float32([0.25, 0.5, 1.0]), (6, 7, 3))
        self.assertEqual(px.strides[:2], (0, 0))
        np.testing.assert_array_equal(ew.run_node("multiply", a=px, value=(2, 2, 2)), px * 2)

    def test_outputs_are_views_of_graph_memory(self):
        out = ew.run_node("add", a=np.zeros((5, 7), np.float32), value=0.5)
        self.assertFalse(out.flags.owndata)
        self.assertEqual(out.shape, (5, 7, 1))
        np.testing.assert_array_equal(out, 0.5)

    def test_other_dtypes_are_converted(self):
        out = ew.run_node("add", a=np.zeros((3, 3, 3), np.float64), value=(1, 2, 3))
        self.assertEqual(out.dtype, np.float32)
        np.testing.assert_array_equal(out[1, 1], [1, 2, 3])

    def test_bad_shapes(self):
        with self.assertRaises(ValueError):
            ew.run_node("add", a=np.zeros((3, 3, 5), np.float32))


class TestProgress(unittest.TestCase):
    def setUp(self):
        rng = np.random.default_rng(1)
        self.img = rng.random((64, 80, 3), dtype=np.float32)

    def test_progress_reaches_one(self):
        seen = []
        ew.run_node("denoise", color=self.img, progress=seen.append)
        self.assertGreater(len(seen), 2)
        self.assertEqual(seen, sorted(seen))
        self.assertEqual(seen[-1], 1.0)

    def test_cancel(self):
        calls = []

        def stop(f):
            calls.append(f)
            return len(calls) < 3

        with self.assertRaises(ew.CancelledError) as cm:
            ew.run_node("denoise", color=self.img, progress=stop)
        self.assertIn("cancelled", str(cm.exception))

    def test_exception_in_callback_propagates(self):
        def boom(f):
            raise RuntimeError("from the callback")

        with self.assertRaises(RuntimeError):
            ew.run_node("outlier", color=self.img, progress=boom)


class TestOp(unittest.TestCase):
    """ew.Op: one op of any kind kept across runs gives what a one-node graph
    gives, frame after frame; enums by name; describe; clear errors."""

    def setUp(self):
        rng = np.random.default_rng(3)
        self.color = rng.random((48, 64, 3), dtype=np.float32)
        self.albedo = np.full((48, 64, 3), 0.5, np.float32)
        self.normal = np.zeros((48, 64, 3), np.float32)
        self.normal[:, :, 2] = 1
        self.depth = np.full((48, 64, 1), 2.0, np.float32)

    def test_kept_op_gives_the_graphs_output_every_frame(self):
        feats = dict(albedo=self.albedo, normal=self.normal, depth=self.depth)
        op = ew.Op("kpcn")
        self.assertEqual(op.kind, "denoiser")
        op.set("model", "kpcn-small")
        out = np.zeros_like(self.color)
        for frame in range(3):  # a new frame each time, into the same op and output array
            color = self.color * (1 + frame)
            op.run(color=color, output=out, **feats)
            ref = ew.run_node("denoise", method="kpcn", model="kpcn-small", color=color, **feats)
            np.testing.assert_array_equal(out, ref)
        self.assertIn("kpcn-small", op.describe())
        op.close()

    def test_filters_and_errors(self):
        op = ew.Op("bilateral")
        self.assertEqual(op.kind, "filter")
        op.set("radius", 3)
        out = np.zeros_like(self.color)
        op.run(color=self.color, output=out)
        np.testing.assert_array_equal(out, ew.run_node("bilateral", color=self.color, radius=3))
        with self.assertRaises(KeyError):
            op.set("no_such_parameter", 1)
        with self.assertRaises(ew.EdgewiseError):
            ew.Op("no_such_method")
        with self.assertRaises(ew.UnknownNameError):
            ew.Filter("kpcn")  # a denoiser is not a filter
        with self.assertRaises(ValueError):
            ew.Op("kpcn").set("model", "no-such-model")


if __name__ == "__main__":
    unittest.main()
