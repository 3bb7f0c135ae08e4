"""kpcn's CPU convolutions with Winograd (the default where the processor has AVX2 + FMA) against
the direct ones (EW_CPU_CONV=direct) on the committed Cornell frame, every built-in model: the
same image to rounding (PSNR of one against the other above 80 dB; a wrong transform or a tile
stored in the wrong place gives far less), and not the same bits (Winograd did run)."""
import json
import os
import sys

from ewtest import RENDER, np, python, run, unittest, TempDirTest

SCRIPT = r'''
import sys, numpy as np, edgewise as ew
p = ew.read(sys.argv[1])
color, albedo = p['Combined'][:, :, :3].copy(), p['Denoising Albedo'].copy()
normal, depth = p['Denoising Normal'].copy(), p['Denoising Depth'].copy()
dev = ew.Device(threads=2)
for m in (1, 0, 2):
    out = ew.run_node('denoise', method='kpcn', model=m, color=color, albedo=albedo, normal=normal, depth=depth,
                      device=dev, do_no_harm=False, outlier_k=0.0)
    np.save(sys.argv[2] + '_%d.npy' % m, np.asarray(out, np.float32))
'''


def psnr(a, b):
    """PSNR of the tone-mapped images (x / (1 + x)), peak 1."""
    ta, tb = a / (1.0 + np.maximum(a, 0)), b / (1.0 + np.maximum(b, 0))
    mse = float(np.mean((ta.astype(np.float64) - tb) ** 2))
    return float('inf') if mse == 0 else 10 * np.log10(1.0 / mse)


class TestKpcnWinograd(TempDirTest):
    def test_winograd_matches_direct_on_a_real_frame(self):
        script = self.path('run.py')
        with open(script, 'w') as f:
            f.write(SCRIPT)
        outs = {}
        for kind in ('direct', 'auto'):
            env = dict(os.environ)
            env.pop('EW_CPU_CONV', None)
            if kind == 'direct':
                env['EW_CPU_CONV'] = 'direct'
            r = run([python(), script, RENDER, self.path(kind)], env=env)
            self.assertEqual(r.returncode, 0, r.stderr)
            outs[kind] = {m: np.load(self.path('%s_%d.npy' % (kind, m))) for m in (0, 1, 2)}
        for m in (0, 1, 2):
            d, w = outs['direct'][m], outs['auto'][m]
            p = psnr(w, d)
            rel = float(np.max(np.abs(w - d)) / np.max(np.abs(d)))
            sys.stderr.write('  model %d: Winograd against direct %.1f dB, worst difference %.2e of the peak\n'
                             % (m, p, rel))
            self.assertGreater(p, 80.0)
            if sys.platform.startswith('linux') and 'avx2' in open('/proc/cpuinfo').read():
                self.assertFalse(np.array_equal(w, d), 'Winograd did not run')


if __name__ == '__main__':
    unittest.main()
