"""Every example in examples/ runs: graph files through `edgewise graph run`
(their write nodes redirected to a temporary directory), Python scripts with
the temporary directory as argument. New examples are picked up by name."""
import glob
import json
import os
import shutil

from ewtest import CLI, EXAMPLES, TempDirTest, python, run, unittest


class TestExamples(TempDirTest):
    def test_graph_files(self):
        if not CLI:
            self.skipTest("EW_CLI not set (run through CTest)")
        files = sorted(glob.glob(os.path.join(EXAMPLES, "*.json")))
        self.assertTrue(files)
        for f in files:
            with self.subTest(example=os.path.basename(f)):
                with open(f) as fh:
                    nodes = json.load(fh)["nodes"]
                sets = []
                for node_id, node in nodes.items():
                    if node["type"] == "write":
                        name = os.path.basename(node["params"]["path"])
                        sets += ["--set", "%s.path=%s" % (node_id, os.path.join(self.tmp, name))]
                r = run([CLI, "graph", "run", f] + sets, cwd=self.tmp)
                self.assertEqual(r.returncode, 0, r.stderr)
                self.assertIn("frame", r.stdout)

    def test_python_scripts(self):
        files = sorted(glob.glob(os.path.join(EXAMPLES, "*.py")))
        self.assertTrue(files)
        for f in files:
            with self.subTest(example=os.path.basename(f)):
                out = os.path.join(self.tmp, os.path.splitext(os.path.basename(f))[0])
                os.makedirs(out)
                r = run([python(), f, out], cwd=self.tmp)
                self.assertEqual(r.returncode, 0, r.stdout + r.stderr)

    def test_inside_blender(self):
        blender = shutil.which("blender")
        if not blender or "asan" in os.environ.get("LD_PRELOAD", ""):
            self.skipTest("Blender is not installed")
        script = os.path.join(EXAMPLES, "denoise_numpy.py")
        # Blender's Python ignores PYTHONPATH: the package's directory goes on its path here
        pkg = os.environ.get("PYTHONPATH") or os.path.join(EXAMPLES, "..", "python")
        code = ("import sys; sys.path.insert(0, %r); sys.argv = [%r, %r]; exec(compile(open(%r).read(), %r, 'exec'), "
                "{'__name__': '__main__', '__file__': %r})" % (pkg, script, self.tmp, script, script, script))
        r = run([blender, "-b", "--factory-startup", "--python-exit-code", "1", "--python-expr", code],
                env=dict(os.environ), timeout=300)
        self.assertEqual(r.returncode, 0, r.stdout[-2000:] + r.stderr[-2000:])
        self.assertIn("PSNR", r.stdout)


if __name__ == "__main__":
    unittest.main()
