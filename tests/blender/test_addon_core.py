"""Unit tests of the add-on's pure-Python core (no Blender):

    EDGEWISE_LIB=build/lib /usr/bin/python3 -m unittest -v test_addon_core
(run in tests/blender). Tests that need the library skip when it cannot be loaded.
"""
import os
import shutil
import subprocess
import sys
import tempfile
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


def run_python(code):
    """Run code in a fresh python3 with the add-on's folder importable; stdout+stderr."""
    code = "import sys; sys.path.insert(0, %r)\n" % os.path.join(REPO, "blender_addon") + code
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    return out.stdout + out.stderr


class PureLogic(unittest.TestCase):
    def test_core_has_no_bpy(self):
        self.assertNotIn("bpy", sys.modules)
        with open(core.__file__) as f:
            self.assertNotIn("import bpy", f.read())

    def test_readable_labels(self):
        self.assertEqual(core.readable("firefly_k"), "Firefly K")
        self.assertEqual(core.readable("bgrid-color"), "Bgrid Color")
        self.assertEqual(core.readable("nbg"), "NBG")
        p = {"choices": ["a_b", "c"], "choice_labels": ["Alpha Beta", ""]}
        self.assertEqual(core.enum_items(p), [("a_b", "Alpha Beta", ""), ("c", "C", "")])

    def test_param_labels(self):
        self.assertEqual(core.param_label({"name": "quality", "label": "quality"}), "Quality")
        self.assertEqual(core.param_label({"name": "firefly_k"}), "Firefly K")
        self.assertEqual(core.param_label({"name": "method", "label": "Method"}), "Method")

    def test_enum_saved_by_identifier(self):
        ids = ["auto", "bgrid", "nbg", "kpcn"]
        reordered = ["kpcn", "nbg", "auto", "bgrid"]
        # a saved identifier keeps its choice whatever the library's order
        self.assertEqual(ids[core.stored_enum_index("nbg", ids, "auto")], "nbg")
        self.assertEqual(reordered[core.stored_enum_index("nbg", reordered, "auto")], "nbg")
        # a choice the library no longer has, or nothing saved: the default
        self.assertEqual(core.stored_enum_index("gone", reordered, "auto"), reordered.index("auto"))
        self.assertEqual(core.stored_enum_index(None, reordered, "auto"), reordered.index("auto"))
        self.assertEqual(core.stored_enum_index(None, ids, "missing-default"), 0)
        # files saved before stored Blender's position: read as that position
        self.assertEqual(core.stored_enum_index(2, ids, "auto"), 2)
        self.assertEqual(core.stored_enum_index(9, ids, "auto"), 0)
        self.assertEqual(core.stored_enum_index(-1, ids, "bgrid"), 1)
        self.assertEqual(core.stored_enum_index(True, ids, "bgrid"), 1)

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

    def test_colour_guided_substitute(self):
        inputs = [{"name": "color", "required": True}, {"name": "albedo", "required": True},
                  {"name": "normal", "required": False}]
        self.assertEqual(core.colour_guided_method("bgrid", inputs, ["albedo"]), ("bgrid", ""))
        m, note = core.colour_guided_method("bgrid", inputs, [])
        self.assertEqual(m, "auto")
        self.assertIn("albedo", note)

    def test_box_mean(self):
        import numpy as np
        rng = np.random.default_rng(1)
        img = rng.random((7, 9, 2))
        got = core.box_mean(img, 1)
        pad = np.pad(img, ((1, 1), (1, 1), (0, 0)), mode="edge")
        want = sum(pad[dy:dy + 7, dx:dx + 9] for dy in range(3) for dx in range(3)) / 9.0
        self.assertTrue(np.allclose(got, want))

    def test_history_mismatch(self):
        import numpy as np
        rng = np.random.default_rng(2)
        truth = np.full((40, 40, 3), 0.5)
        cur = truth + rng.normal(0, 0.1, truth.shape)
        single = truth + rng.normal(0, 0.02, truth.shape)
        hist = truth + rng.normal(0, 0.05, truth.shape)
        hist[:, 20:] += 0.3  # history from somewhere else on the right half
        acc = 0.5 * (cur + hist)
        bad = core.history_mismatch(cur, acc, single)
        self.assertLess(bad[:, :17].mean(), 0.02)       # noise alone is not a mismatch
        self.assertGreater(bad[:, 23:].mean(), 0.98)    # a real difference is

    def test_wrong_platform_message(self):
        self.assertIn("another platform", core._explain(OSError("x.so: invalid ELF header")))
        self.assertIn("another platform", core._explain(OSError("x.so: wrong ELF class: ELFCLASS32")))

    def test_symlinked_addon_finds_the_repo(self):
        # a developer install: <scripts>/addons/edgewise_denoise -> <repo>/blender_addon/edgewise_denoise
        d = tempfile.mkdtemp()
        try:
            os.symlink(os.path.join(REPO, "blender_addon", "edgewise_denoise"), os.path.join(d, "edgewise_denoise"))
            out = subprocess.run([sys.executable, "-c", "import sys; sys.path.insert(0, %r)\n"
                                  "from edgewise_denoise import core; print(core.package_dir()); "
                                  "print(core.library_candidates()[-1])" % d],
                                 capture_output=True, text=True, timeout=60)
            lines = out.stdout.split()
            self.assertEqual(lines[0], os.path.join(REPO, "python"), out.stderr)
            self.assertEqual(lines[1], os.path.join(REPO, "build", "lib"))
        finally:
            shutil.rmtree(d)


class BadLibrary(unittest.TestCase):
    """The Library setting is the only library used when set: a bad one is refused with the reason."""

    def test_missing_folder(self):
        text = run_python("from edgewise_denoise import core\nprint(core.library_status('/nonexistent/ew/lib'))")
        self.assertIn("False", text)
        self.assertIn("does not exist", text)

    def test_empty_folder_is_refused_not_replaced(self):
        d = tempfile.mkdtemp()
        try:
            text = run_python("from edgewise_denoise import core\nprint(core.library_status(%r))" % d)
            self.assertIn("False", text)
            self.assertIn("Library setting refused: no libedgewise.so", text)
        finally:
            shutil.rmtree(d)

    def test_library_for_another_platform(self):
        d = tempfile.mkdtemp()
        try:
            for n in core.LIB_NAMES:
                with open(os.path.join(d, n), "w") as f:
                    f.write("MZ" + "x" * 8192)  # a Windows-like file, not ELF
            text = run_python("from edgewise_denoise import core\nprint(core.library_status(%r))" % d)
            self.assertIn("False", text)
            self.assertIn("another platform", text)
        finally:
            shutil.rmtree(d)


@unittest.skipUnless(have_library(), "libedgewise not loadable")
class WithLibrary(unittest.TestCase):
    def test_no_sys_path_pollution(self):
        text = run_python("import importlib.util\nbefore = list(sys.path)\nfrom edgewise_denoise import core\n"
                          "ew = core.load_edgewise()\nprint('same_path', sys.path == before)\n"
                          "print('global_edgewise', 'edgewise' in sys.modules or "
                          "importlib.util.find_spec('edgewise') is not None)\nprint(ew.__name__)")
        self.assertIn("same_path True", text)
        self.assertIn("global_edgewise False", text)
        self.assertIn("edgewise_denoise._edgewise", text)

    def test_setting_honoured_at_once(self):
        good = os.path.realpath(os.environ.get("EDGEWISE_LIB") or os.path.join(REPO, "build", "lib"))
        d = tempfile.mkdtemp()
        try:
            text = run_python(
                "from edgewise_denoise import core\nprint('A', core.library_status()[0])\n"
                "print('B', core.library_status(%r)[0])\ncore.reset()\nprint('C', core.library_status(%r))\n"
                % (d, good))
            self.assertIn("A True", text)
            self.assertIn("B False", text)
            self.assertIn("C (True", text)
            self.assertIn(good, text)
        finally:
            shutil.rmtree(d)

    def test_methods_from_descriptors(self):
        names = core.method_names()
        self.assertIn("auto", names)
        self.assertGreaterEqual(len(names), 2)
        items = core.method_items()
        self.assertEqual([i[0] for i in items], list(names))
        for ident, label, desc in items:
            self.assertNotIn("_", label)
            self.assertTrue(desc)
        # tooltips: each method's own description from the library (ew_method_get)
        descs = dict((i[0], i[2]) for i in items)
        self.assertIn("bilateral grid", descs["nbg"])
        self.assertNotEqual(descs["nbg"], descs["bgrid"])
        for m in names:
            self.assertNotIn("method", [p["name"] for p in core.method_params(m)])

    def test_needed_passes(self):
        self.assertEqual(sorted(core.needed_passes("nbg")), ["albedo", "depth", "normal"])
        self.assertIn("vector", core.needed_passes("auto", temporal=True))

    def _sample(self):
        ew = core.load_edgewise()
        out = ew.run_node("read", path=SAMPLE, outputs=["color", "albedo", "normal", "depth"])
        return dict((k, v.copy()) for k, v in out.items())

    @unittest.skipUnless(os.path.isfile(SAMPLE), "no sample EXR")
    def test_every_method_without_denoising_data(self):
        import numpy as np
        color = self._sample()["color"]
        rgba = np.concatenate([color[:, :, :3], np.full(color.shape[:2] + (1,), 0.25, np.float32)], axis=2)
        for m in core.method_names():
            out, ran = core.denoise_arrays({"color": rgba}, core.Settings(m, samples=1))
            self.assertEqual(out.shape, rgba.shape, m)
            self.assertTrue(np.isfinite(out).all(), m)
            self.assertTrue((out[:, :, 3] == 0.25).all(), "%s: alpha kept" % m)
            self.assertGreater(float(np.abs(out[:, :, :3] - rgba[:, :, :3]).mean()), 1e-3, "%s denoised" % m)

    @unittest.skipUnless(os.path.isfile(SAMPLE), "no sample EXR")
    def test_auto_says_what_it_ran(self):
        p = self._sample()
        _, ran = core.denoise_arrays(p, core.Settings("auto", samples=1))
        self.assertEqual(ran, "kpcn kpcn-large (1 spp, quality balanced)")
        _, ran = core.denoise_arrays(p, core.Settings("auto", params={"quality": "fast"}, samples=1))
        self.assertEqual(ran, "nbg 2layer-3grid-1spp (1 spp)")

    def test_temporal_follows_blender_vectors(self):
        """A pattern moving across the frame in x and y; Blender's Vector pass
        for it (as read from its files, rows top first) is what Cycles writes
        for this motion: X = the previous column minus the current one, Y = the
        current row minus the previous one (Cycles' y axis points up). With it,
        history lands on the same content and the static pattern stays exact."""
        import numpy as np
        ew = core.load_edgewise()
        h, w = 24, 32
        hist = core.TemporalHistory(ew)
        for dx, dy in ((2, 0), (0, 2), (-1, 3)):
            hist = core.TemporalHistory(ew)
            worst = 0.0
            for fr in range(5):
                yy, xx = np.mgrid[0:h, 0:w]
                pat = ((((xx - dx * fr) // 4) + ((yy - dy * fr) // 4)) % 2).astype(np.float32)
                color = np.repeat(pat[:, :, None], 3, axis=2)
                vec = np.zeros((h, w, 4), np.float32)
                vec[:, :, 0] = -dx   # previous x = x - dx
                vec[:, :, 1] = dy    # previous row = row - dy: up by dy, Blender's +Y
                out = hist.accumulate(fr + 1, color, None, None, vec)
                inner = (slice(4, h - 4), slice(4, w - 4))
                worst = max(worst, float(np.abs(out[inner] - color[inner]).max()))
            self.assertLess(worst, 1e-5, "motion (%d, %d) px/frame" % (dx, dy))
            hist.close()

    def test_temporal_rejects_wrong_history(self):
        """Vectors pointing the wrong way (history from 6 px away on an 8 px
        checker) must not pull any frame more than 0.2 dB below per-frame
        denoising. (With 6 px squares, where the wrong history is the exact
        inverse and differences cancel in every window, frame 3 was 0.25 dB
        below: the limit of the windowed test.)"""
        import numpy as np
        ew = core.load_edgewise()
        h, w = 48, 64
        rng = np.random.default_rng(5)
        hist = core.TemporalHistory(ew)
        settings = core.Settings("auto", samples=4)
        for fr in range(1, 6):
            yy, xx = np.mgrid[0:h, 0:w]
            truth = np.where((((xx - 3 * fr) // 8) + (yy // 8)) % 2 == 0, 0.2, 0.8).astype(np.float32)
            truth = np.repeat(truth[:, :, None], 3, axis=2)
            noisy = np.clip(truth + rng.normal(0, 0.15, truth.shape), 0, None).astype(np.float32)
            vec = np.zeros((h, w, 4), np.float32)
            vec[:, :, 0] = 3.0   # wrong: the content came from x - 3
            passes = {"color": noisy, "vector": vec}
            single, _ = core.denoise_arrays(passes, settings)
            temporal, ran = core.denoise_frame(passes, settings, fr, hist)
            mse = lambda a: float(np.mean((a[:, :, :3] - truth) ** 2))  # noqa: E731
            p_s, p_t = -10 * np.log10(mse(single)), -10 * np.log10(mse(temporal))
            self.assertIn("temporal", ran)
            self.assertGreaterEqual(p_t, p_s - 0.2, "frame %d: temporal %.2f dB, per-frame %.2f dB" % (fr, p_t, p_s))
        hist.close()

    def test_error_text_has_library_message(self):
        ew = core.load_edgewise()
        try:
            ew.run_node("read", path="/nonexistent.exr", outputs="color")
        except Exception as e:
            self.assertIn("nonexistent", core.error_text(e))
            self.assertTrue(core.error_text(e).startswith("Edgewise: "))
        else:
            self.fail("reading a missing file succeeded")


if __name__ == "__main__":
    unittest.main()
