"""tools/bench_report.py's quality-against-time chart: the noisy input is a
horizontal line per spp (it has no time to sit on a log axis), and every
method has its own colour and marker.
usage: test_bench_chart.py BENCH_REPORT_PY"""
import importlib.util
import os
import sys
import tempfile
import unittest

spec = importlib.util.spec_from_file_location("bench_report", sys.argv.pop(1))
br = importlib.util.module_from_spec(spec)
spec.loader.exec_module(br)

METHODS = ["input", "bgrid-features", "bgrid", "nbg", "nbg-1grid", "nbg-7layer", "nbg-1spp", "auto", "auto-noise",
           "atrous", "pyramid-gi", "bilateral-gi"]


def fake_means():
    m = {}
    for si, spp in enumerate((1, 4, 16, 64)):
        for mi, meth in enumerate(METHODS):
            ms = 0.0 if meth == "input" else 5.0 * (mi + 1)
            m[(meth, spp)] = {"psnr": 15.0 + 3 * si + (0 if meth == "input" else mi * 0.5), "ssim": 0.5, "ms": ms,
                              "relmse": 0.1, "smape": 0.1, "n": 3}
    return m


class TestChart(unittest.TestCase):
    def test_input_is_a_line_per_spp(self):
        points, lines = br.chart_layout(fake_means(), "psnr")
        self.assertFalse([p for p in points if p[2] == "input"])
        self.assertEqual([(v, spp) for v, spp, _ in lines], [(15.0, 1), (18.0, 4), (21.0, 16), (24.0, 64)])
        self.assertEqual(len({str(d) for _, _, d in lines}), 4)  # told apart by their dashes
        self.assertGreaterEqual(min(p[0] for p in points), 5.0)  # nothing drawn at a made-up time

    def test_methods_are_told_apart(self):
        points, _ = br.chart_layout(fake_means(), "psnr")
        style = {}
        for _, _, meth, _, colour, _, hollow in points:
            style.setdefault(meth, set()).add((colour, hollow))
        self.assertTrue(all(len(s) == 1 for s in style.values()))  # one look per method
        looks = [next(iter(s)) for s in style.values()]
        self.assertEqual(len(set(looks)), len(METHODS) - 1)
        markers = {(p[3], p[5]) for p in points}
        self.assertEqual(len({mk for _, mk in markers}), 4)  # one marker per spp

    def test_chart_is_drawn(self):
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "c.png")
            br.chart(fake_means(), "psnr", "PSNR (dB)", path)
            self.assertGreater(os.path.getsize(path), 1000)


ANCHOR = """# OIDN
| scene | 1 spp noisy | 1 spp OIDN | 4 spp noisy | 4 spp OIDN |
|---|---:|---:|---:|---:|
| a_cornell_119 | 15.32 | 33.00 | 21.23 | 38.00 |
| b_glossy_112 | 15.80 | 31.00 | 30.55 | – |
| c_glass_113 | 19.94 | 20.00 | 24.38 | 30.00 |
| mean | 18.51 | **32.19** | 26.43 | **36.14** |
"""


class TestOidnAnchor(unittest.TestCase):
    def rows(self, scenes, spps):
        return [{"scene": sc + "_256x256", "spp": spp} for sc in scenes for spp in spps]

    def test_mean_over_the_scenes_benched(self):
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "anchor.md")
            with open(path, "w") as f:
                f.write(ANCHOR)
            # c_glass is in the table but not benched: left out of the mean
            o = br.load_oidn(path, self.rows(["a_cornell_119", "b_glossy_112"], [1]))
            self.assertEqual(o, {1: (32.0, 2)})
            # a scene without a figure at that spp: no mean rather than a partial one
            o = br.load_oidn(path, self.rows(["a_cornell_119", "b_glossy_112"], [1, 4]))
            self.assertEqual(set(o), {1})
            # a scene the table does not have: no mean either
            self.assertEqual(br.load_oidn(path, self.rows(["a_cornell_119", "z_new_1"], [1])), {})

    def test_summary_gives_the_gap(self):
        with tempfile.TemporaryDirectory() as d:
            m = {("kpcn", 1): {"psnr": 30.5, "ssim": 0.9, "ms": 3.0, "relmse": 0.1, "smape": 0.1, "n": 2}}
            path = os.path.join(d, "s.md")
            br.write_summary(m, path, {1: (32.0, 2)})
            with open(path) as f:
                text = f.read()
            self.assertIn("| -1.50 |", text)
            br.chart(m, "psnr", "PSNR (dB)", os.path.join(d, "c.png"), {1: (32.0, 2)})


if __name__ == "__main__":
    unittest.main()
