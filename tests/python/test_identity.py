"""Done-when check of the node layer: the same denoise + DoF + display graph
gives identical pixels from the graph file (edgewise graph run), from the
Python script (examples/denoise_dof_display.py) and through the C API
(tests/graph/identity_capi.c)."""
import os

from ewtest import CLI, EXAMPLES, SAMPLES, TempDirTest, ew, np, python, read_image, run, unittest


class TestIdentity(TempDirTest):
    def test_file_python_and_c_api_agree(self):
        capi = os.environ.get("EW_IDENTITY_CAPI")
        if not CLI or not capi:
            self.skipTest("EW_CLI / EW_IDENTITY_CAPI not set (run through CTest)")
        if not ew.node_type("dof")["available"]:
            self.skipTest("no dof filter in this libedgewise")
        graph = os.path.join(EXAMPLES, "denoise_dof_display.json")
        r = run([CLI, "graph", "run", graph, "--set", "preview.path=" + self.path("file.png"),
                 "--set", "pixels.path=" + self.path("file.exr")])
        self.assertEqual(r.returncode, 0, r.stderr)
        r = run([python(), os.path.join(EXAMPLES, "denoise_dof_display.py"), self.tmp])
        self.assertEqual(r.returncode, 0, r.stderr)
        r = run([capi, SAMPLES, self.path("capi.exr")])
        self.assertEqual(r.returncode, 0, r.stderr)
        from_file = read_image(self.path("file.exr"))
        from_python = read_image(self.path("denoise_dof_display_py.exr"))
        from_c = read_image(self.path("capi.exr"))
        self.assertEqual(from_file.shape, (256, 256, 3))
        self.assertGreater(float(from_file.std()), 0.01)  # a real image, not a blank
        np.testing.assert_array_equal(from_file, from_python)
        np.testing.assert_array_equal(from_file, from_c)
        # and the in-memory result of the Python graph is the same too
        import importlib.util
        spec = importlib.util.spec_from_file_location("example", os.path.join(EXAMPLES, "denoise_dof_display.py"))
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        g = mod.build(self.tmp, SAMPLES)
        g.run()
        np.testing.assert_array_equal(g.output("shown"), from_file)


if __name__ == "__main__":
    unittest.main()
