"""Unit tests of the add-on's pure-Python core (no Blender):

    PYTHONPATH=python:blender_addon EDGEWISE_LIB=build/lib /usr/bin/python3 -m unittest -v test_addon_core
(run in tests/blender). Tests that need the library skip when it cannot be loaded.
"""
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(REPO, "blender_addon"))

from edgewise_denoise import core  # noqa: E402  (no bpy inside)

SAMPLE = os.path.join(os.environ.get("EW_SAMPLE_DIR", os.path.join(REPO, "samples")), "cornell", "f0001_spp0001.exr")


def have_library():
    try:
        core.load_edgewise()
        return True
    except core.AddonLibraryError:
        return False


class PureLogic(unittest.TestCase):
    def test_core_has_no_bpy(self):
        self.assertNotIn("bpy", sys.modules)
        with open(core.__file__) as f:
            self.assertNotIn("import bpy", f.read())

    def test_denoised_path(self):
        self.assertEqual(core.denoised_path("/r/frame_0001.exr"), "/r/frame_0001_denoised.exr")
        self.assertEqual(core.denoised_path("/r/frame_0001.exr", "View Layer", True),
                         "/r/frame_0001_denoised_View_Layer.exr")
        self.assertEqual(core.denoised_path("/r/out", "A", False), "/r/out_denoised.exr")

    def test_sequence_pattern(self):
        self.assertEqual(core.sequence_pattern("/r2024/shot_0007.exr", 7), "/r2024/shot_####.exr")
        self.assertEqual(core.sequence_pattern("/r/v2_0012_x.exr", 12), "/r/v2_####_x.exr")
        self.assertEqual(core.sequence_pattern("/r/0003.exr", 3), "/r/####.exr")
        self.assertIsNone(core.sequence_pattern("/r/shot.exr", 3))

    def test_result_image_name(self):
        self.assertEqual(core.result_image_name("ViewLayer", 1), "Edgewise Denoised")
        self.assertEqual(core.result_image_name("Second", 2), "Edgewise Denoised - Second")

    def test_missing_passes(self):
        need = ["albedo", "normal", "depth", "vector"]
        self.assertEqual(core.missing_passes(need, {"denoising_store_passes": True, "use_pass_vector": True}), [])
        self.assertEqual(core.missing_passes(need, {"denoising_store_passes": True}), ["Vector"])
        self.assertEqual(core.missing_passes(["albedo"], {}), ["Denoising Albedo"])

    def test_coerce_params(self):
        params = [{"name": "k", "type": "float", "min": 0.0, "max": 10.0},
                  {"name": "n", "type": "int", "min": 0.0, "max": 2.0},
                  {"name": "e", "type": "enum", "choices": ["a", "b"]},
                  {"name": "b", "type": "bool"}]
        got = core.coerce_params(params, {"k": 20, "n": 1.6, "e": "c", "b": 1, "unknown": 3})
        self.assertEqual(got, {"k": 10.0, "n": 2, "b": True})

    def test_wrong_platform_message(self):
        self.assertIn("another platform", core._explain(OSError("x.so: invalid ELF header")))
        self.assertIn("another platform", core._explain(OSError("x.so: wrong ELF class: ELFCLASS32")))

    def test_bad_library_path(self):
        with self.assertRaises(core.AddonLibraryError) as cm:
            core.load_edgewise("/nonexistent/edgewise/lib")
        self.assertIn("does not exist", str(cm.exception))

    def test_library_for_another_platform(self):
        d = tempfile.mkdtemp()
        try:
            for n in ("libedgewise.so", "libedgewise_nodes.so"):
                with open(os.path.join(d, n), "w") as f:
                    f.write("MZ" + "x" * 8192)  # a Windows-like file, not ELF
            code = ("import sys; sys.path.insert(0, %r)\nfrom edgewise_denoise import core\n"
                    "print(core.library_status(%r)[1])" % (os.path.join(REPO, "blender_addon"), d))
            out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
            self.assertIn("another platform", out.stdout + out.stderr)
        finally:
            shutil.rmtree(d)

    def test_package_dirs_finds_repo(self):
        self.assertIn(os.path.join(REPO, "python"), core.package_dirs())


@unittest.skipUnless(have_library(), "libedgewise not loadable")
class WithLibrary(unittest.TestCase):
    def test_methods_from_descriptors(self):
        names = core.method_names()
        self.assertIn("auto", names)
        self.assertGreaterEqual(len(names), 2)
        for m in names:
            self.assertNotIn("method", [p["name"] for p in core.method_params(m)])

    def test_needed_passes(self):
        self.assertEqual(sorted(core.needed_passes("nbg")), ["albedo", "depth", "normal"])
        self.assertIn("vector", core.needed_passes("auto", temporal=True))

    @unittest.skipUnless(os.path.isfile(SAMPLE), "no sample EXR")
    def test_denoise_file(self):
        import numpy as np
        out = core.denoise_file(SAMPLE, [""], core.Settings("nbg", samples=1))
        img = out[""]
        self.assertEqual(img.shape, (256, 256, 4))
        self.assertTrue(np.isfinite(img).all())
        self.assertTrue((img[:, :, 3] == 1).all())

    @unittest.skipUnless(os.path.isfile(SAMPLE), "no sample EXR")
    def test_denoise_file_says_what_auto_picked(self):
        methods = {}
        core.denoise_file(SAMPLE, [""], core.Settings("auto", samples=1), methods=methods)
        self.assertEqual(methods, {"": "nbg 2layer-3grid-1spp (1 spp)"})

    @unittest.skipUnless(os.path.isfile(SAMPLE), "no sample EXR")
    def test_threads_setting(self):
        import numpy as np
        a = core.denoise_file(SAMPLE, [""], core.Settings("bgrid", threads=1))[""]
        b = core.denoise_file(SAMPLE, [""], core.Settings("bgrid", threads=2))[""]
        self.assertTrue(np.allclose(a, b, atol=1e-5))

    @unittest.skipUnless(os.path.isfile(SAMPLE), "no sample EXR")
    def test_denoise_file_to_files(self):
        d = tempfile.mkdtemp()
        try:
            src = os.path.join(d, "frame_0001.exr")
            shutil.copy(SAMPLE, src)
            seen = []
            written = core.denoise_file_to_files(src, [""], core.Settings("auto", samples=1), progress=seen.append)
            self.assertEqual(written, [os.path.join(d, "frame_0001_denoised.exr")])
            self.assertTrue(os.path.getsize(written[0]) > 0)
            self.assertTrue(seen and 0.0 <= min(seen) and max(seen) <= 1.0)
        finally:
            shutil.rmtree(d)

    @unittest.skipUnless(os.path.isfile(SAMPLE), "no sample EXR")
    def test_job_and_cancel(self):
        job = core.Job(core.denoise_file, SAMPLE, [""], core.Settings("auto", samples=1)).start()
        self.assertTrue(job.wait(60))
        self.assertIsNone(job.error)
        self.assertIn("", job.result)
        job = core.Job(core.denoise_file, SAMPLE, [""], core.Settings("auto", samples=1))
        job.cancel()
        job.start().wait(60)
        self.assertTrue(job.done and job.cancelled)
        self.assertIsNotNone(job.error)
        self.assertEqual(getattr(job.error, "code_name", ""), "EW_ERR_CANCELLED")

    def test_error_text_has_library_message(self):
        job = core.Job(core.denoise_file, "/nonexistent.exr", [""], core.Settings("auto")).start()
        job.wait(60)
        self.assertIsNotNone(job.error)
        self.assertIn("nonexistent", core.error_text(job.error))


if __name__ == "__main__":
    unittest.main()
