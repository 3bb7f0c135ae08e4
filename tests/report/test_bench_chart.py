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


if __name__ == "__main__":
    unittest.main()
