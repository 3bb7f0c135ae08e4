#!/usr/bin/python3
"""Would OIDN's output on a cheap render make a good kpcn training target?

For each scene (never one of BENCHMARKS.md's test scenes: pass training scenes only) and each
sample count S it has, this prints the tone-mapped PSNR against the scene's reference of the
noisy S-spp render and of OIDN run on it (../shared/tools/oidn_torch.py, official weights).
Read OIDN(S) against noisy(4S): is OIDN on a cheap render a better target than a render with
4x the samples (the cost of a target is its samples)? The last column checks the rule used
to extrapolate to 256-spp targets: noisy(4S) - noisy(S) is +6.02 dB where the error is noise.

    tools/train/oidn_targets.py [--threads 2] SCENE_DIR...
"""
import argparse
import glob
import math
import os
import sys

import numpy as np

SHARED_TOOLS = os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..', '..', 'shared', 'tools')


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('scenes', nargs='+')
    ap.add_argument('--threads', type=int, default=2)
    ap.add_argument('--tools', default=SHARED_TOOLS, help='the folder of oidn_torch.py and metrics.py')
    a = ap.parse_args()
    sys.path.insert(0, os.path.abspath(a.tools))
    import metrics
    from exrio import read_layer
    from oidn_torch import OIDN, read_passes
    f = OIDN(threads=a.threads)
    spps = (1, 4, 16, 64)
    sums = {}
    print('%-30s %s' % ('scene', ' '.join('%6s %6s' % ('n%d' % s, 'oidn%d' % s) for s in spps)))
    for d in a.scenes:
        refs = sorted(glob.glob(os.path.join(d, 'f0001_ref*.exr')))
        if not refs:
            print('%s: no reference, skipped' % d, file=sys.stderr)
            continue
        ref = read_layer(refs[-1])
        cells = []
        for s in spps:
            path = os.path.join(d, 'f0001_spp%04d.exr' % s)
            if not os.path.exists(path):
                cells.append('%6s %6s' % ('-', '-'))
                continue
            c, al, nr = read_passes(path)
            row = (metrics.psnr(c, ref), metrics.psnr(f(c, al, nr), ref))
            for k, v in zip(('n', 'o'), row):
                sums.setdefault((k, s), []).append(v)
            cells.append('%6.2f %6.2f' % row)
        print('%-30s %s' % (os.path.basename(d.rstrip('/'))[:30], ' '.join(cells)), flush=True)
    mean = {k: float(np.mean(v)) for k, v in sums.items()}
    print('%-30s %s' % ('mean', ' '.join('%6.2f %6.2f' % (mean.get(('n', s), math.nan), mean.get(('o', s), math.nan))
                                          for s in spps)))
    for s in spps[:-1]:
        if ('o', s) in mean and ('n', 4 * s) in mean:
            print('OIDN(%d spp) - noisy(%d spp): %+.2f dB; noisy(%d) - noisy(%d): %+.2f dB (noise alone: +6.02)'
                  % (s, 4 * s, mean[('o', s)] - mean[('n', 4 * s)], 4 * s, s, mean[('n', 4 * s)] - mean[('n', s)]))

if __name__ == '__main__':
    main()
