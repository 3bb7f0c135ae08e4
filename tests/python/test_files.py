"""edgewise.read / write / file_info: the passes of an EXR layer to numpy
arrays and back, every other pass, alpha and the header kept."""
from ewtest import RENDER, TempDirTest, ew, np, unittest


class TestRead(unittest.TestCase):
    def test_info_names_layers_passes_and_samples(self):
        info = ew.file_info(RENDER)
        layer = info["layers"]["ViewLayer"]
        self.assertEqual(layer["passes"]["Combined"], "RGBA")
        self.assertEqual(layer["passes"]["Denoising Normal"], "XYZ")
        self.assertEqual(layer["color"], "Combined")
        self.assertEqual(layer["albedo"], "Denoising Albedo")
        self.assertEqual(info["attributes"]["cycles.ViewLayer.samples"], "4")

    def test_read_every_pass(self):
        p = ew.read(RENDER)
        info = ew.file_info(RENDER)
        self.assertEqual(set(p), set(info["layers"]["ViewLayer"]["passes"]))
        h, w = info["height"], info["width"]
        self.assertEqual(p["Combined"].shape, (h, w, 4))
        self.assertEqual(p["Depth"].shape, (h, w, 1))
        self.assertEqual(p["Combined"].dtype, np.float32)
        # the same pixels as the graph's read node
        from ewtest import read_image
        np.testing.assert_array_equal(p["Combined"][:, :, :3], read_image(RENDER))

    def test_read_some_passes_and_errors(self):
        p = ew.read(RENDER, layer="ViewLayer", passes=["Depth"])
        self.assertEqual(list(p), ["Depth"])
        with self.assertRaises(ew.EdgewiseError):
            ew.read(RENDER, passes=["Nope"])
        with self.assertRaises(ew.EdgewiseError):
            ew.read(RENDER, layer="Nope")
        with self.assertRaises(ew.EdgewiseError) as cm:
            ew.read("/no/such/file.exr")
        self.assertEqual(cm.exception.code_name, "EW_ERR_IO")


class TestWrite(TempDirTest):
    def test_write_like_keeps_the_rest(self):
        p = ew.read(RENDER)
        half = p["Combined"][:, :, :3] * 0.5
        out = self.path("half.exr")
        ew.write(out, {"Combined": half}, like=RENDER, attributes={"edgewise.note": "test"})
        q = ew.read(out)
        self.assertEqual(set(q), set(p))
        np.testing.assert_allclose(q["Combined"][:, :, :3], half, rtol=1e-3, atol=1e-4)
        np.testing.assert_array_equal(q["Combined"][:, :, 3], p["Combined"][:, :, 3])  # alpha kept
        np.testing.assert_array_equal(q["Denoising Normal"], p["Denoising Normal"])
        info = ew.file_info(out)
        self.assertEqual(info["attributes"]["cycles.ViewLayer.samples"], "4")

    def test_write_new_file_round_trip(self):
        rng = np.random.default_rng(1)
        rgba = rng.random((12, 16, 4), dtype=np.float32)
        depth = rng.random((12, 16), dtype=np.float32) * 10
        out = self.path("new.exr")
        ew.write(out, {"Combined": rgba, "Depth": depth}, pixel_type="float")
        q = ew.read(out, layer="ViewLayer")
        np.testing.assert_array_equal(q["Combined"], rgba)
        np.testing.assert_array_equal(q["Depth"][:, :, 0], depth)
        self.assertEqual(ew.file_info(out)["layers"]["ViewLayer"]["passes"]["Depth"], "Z")

    def test_write_png(self):
        rgb = np.full((8, 8, 3), 0.5, np.float32)
        out = self.path("grey.png")
        ew.write(out, {"": rgb})
        q = ew.read(out)
        np.testing.assert_allclose(q[""], rgb, atol=1.0 / 255)

    def test_write_refuses_bad_input(self):
        with self.assertRaises(ValueError):
            ew.write(self.path("x.exr"), {})
        with self.assertRaises(ValueError):
            ew.write(self.path("x.exr"), {"Combined": np.zeros((4, 4, 3), np.float32)}, like=RENDER)


class TestDenoiseArrays(unittest.TestCase):
    def test_denoise_keeps_alpha(self):
        p = ew.read(RENDER)
        rgba = p["Combined"].copy()
        rgba[:, : rgba.shape[1] // 2, 3] = 0.25
        out = ew.run_node("denoise", method="bgrid", color=rgba, albedo=p["Denoising Albedo"])
        self.assertEqual(out.shape, rgba.shape)
        np.testing.assert_array_equal(out[:, :, 3], rgba[:, :, 3])

    def test_unknown_method_is_an_edgewise_error(self):
        with self.assertRaises(ew.EdgewiseError) as cm:
            ew.run_node("denoise", method="oidn", color=np.zeros((4, 4, 3), np.float32))
        self.assertEqual(cm.exception.code_name, "EW_ERR_INVALID_ARGUMENT")
        self.assertIn("oidn", str(cm.exception))


if __name__ == "__main__":
    unittest.main()
