#!/usr/bin/python3
"""kpcn against OIDN: time on the same frame in the same run, the convolutions' share of the FMA peak,
and optionally the peak memory of a one-shot 3840x2160 denoise.

    bench/bench_kpcn_oidn.py [--size 1280x720] [--input EXR] [--threads 2] [--repeat 1] [--uhd]

The frame: --input (a Cycles multilayer EXR with Denoising Albedo/Normal/Depth; default the committed
samples/cornell 4-spp render) resized to --size with oiiotool. On it, one after the other in this process:
the library's "kpcn" op with each built-in model (kpcn-large, kpcn, kpcn-small; through the Python
package), with the do-no-harm stage (as a user gets it) and without it (the method alone, as OIDN's
figure is its network alone), then OIDN's network (../shared/tools/oidn_torch.py: PyTorch with OIDN's
official rt_hdr_alb_nrm weights, see its docstring), each built once and run once before it is timed
(an ew.Op kept across frames, as a graph run keeps its ops and as OIDN's network object is kept; the
time includes the op's commit for the frame, which then allocates nothing), each the fastest of --repeat runs;
also each kpcn with a new op every call (ew.run_node: built, committed, run and freed each time). Printed: wall and CPU ms per frame (CPU: the process's
threads together, less inflated by other work on a shared machine) and each kpcn's time over OIDN's,
against the targets (the largest, kpcn-large, <= 1/4; the smallest, kpcn-small, <= 1/10). Then `train_kpcn --bench W H THREADS`: the
convolutions' GFLOP/s against the FMA peak it measures in the same run (target >= 50 %).
--uhd: the same input resized to 3840x2160, `edgewise denoise --method kpcn` once per model under
/usr/bin/time -v: peak RSS of the whole CLI (EXR in and out included).

Which build: EW_BUILD_DIR (default build; targets edgewise_cli, edgewise and, for
the FMA-peak line, train_kpcn); the script prints whether it was built without function
multiversioning (-DEW_NO_MULTIVERSION, the helpers' fast-compiling build) or as the release default.
Not a test: speed depends on the machine and its load, which it prints.
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile

import numpy as np
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# built-in kpcn model -> (name, role, the largest fraction of OIDN's time it may take; None: no target)
MODELS = {2: ('kpcn-large', 'largest', 0.25), 0: ('kpcn', 'middle', None), 1: ('kpcn-small', 'smallest', 0.10)}
# what is timed: (model, passes); kpcn-large with 4 mirrored passes is auto's quality high (no target of its own)
CONFIGS = [(2, 1), (0, 1), (1, 1), (2, 4)]


def config_name(m, passes):
    return MODELS[m][0] + ('' if passes == 1 else ' x%d' % passes)


def build_kind(build):
    try:
        cache = open(os.path.join(build, 'CMakeCache.txt')).read()
    except OSError:
        return 'unknown build'
    flags = re.search(r'^CMAKE_C_FLAGS:STRING=(.*)$', cache, re.M)
    btype = re.search(r'^CMAKE_BUILD_TYPE:STRING=(.*)$', cache, re.M)
    mv = 'without multiversioning (EW_NO_MULTIVERSION)' if flags and 'EW_NO_MULTIVERSION' in flags.group(1) \
        else 'multiversioned (the release default)'
    return '%s build, %s' % (btype.group(1) if btype and btype.group(1) else 'default', mv)


def resized(src, size, tmp):
    out = os.path.join(tmp, 'frame_%dx%d.exr' % size)
    subprocess.run(['oiiotool', src, '--resize', '%dx%d' % size, '-o', out], check=True)
    return out


def best_of(repeat, fn):
    """(wall, cpu) seconds of the fastest of `repeat` calls; cpu: this process's threads together, which
    the other work on a shared machine inflates less than the wall time."""
    best = None
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        dt = (time.perf_counter() - t0, time.process_time() - c0)
        best = dt if best is None or dt[0] < best[0] else best
    return best


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--size', default='1280x720')
    ap.add_argument('--input', default=os.path.join(ROOT, 'samples', 'cornell', 'f0001_spp0004.exr'))
    ap.add_argument('--threads', type=int, default=2)
    ap.add_argument('--repeat', type=int, default=1)
    ap.add_argument('--oidn', default=os.environ.get('OIDN_TORCH', os.path.join(ROOT, '..', 'shared', 'tools',
                                                                               'oidn_torch.py')),
                    help='oidn_torch.py (default $OIDN_TORCH, else ../shared/tools/ next to the checkout)')
    ap.add_argument('--weights', default=None, help="OIDN weights (default: oidn_torch.py's)")
    ap.add_argument('--uhd', action='store_true', help='also the peak RSS of a 3840x2160 denoise per model')
    ap.add_argument('--no-oidn', action='store_true', help='kpcn and the FMA peak only')
    a = ap.parse_args()
    w, h = (int(v) for v in a.size.lower().split('x'))
    build = os.environ.get('EW_BUILD_DIR', os.path.join(ROOT, 'build'))
    os.environ.setdefault('EDGEWISE_LIB', os.path.join(build, 'lib'))
    sys.path.insert(0, os.path.join(ROOT, 'python'))
    import edgewise as ew
    print('kpcn vs OIDN at %dx%d, %d threads; %s; load average %s' %
          (w, h, a.threads, build_kind(build), ' '.join('%.1f' % v for v in os.getloadavg())))
    with tempfile.TemporaryDirectory() as tmp:
        frame = resized(a.input, (w, h), tmp)
        p = ew.read(frame)
        color, albedo = p['Combined'][:, :, :3].copy(), p['Denoising Albedo'].copy()
        normal, depth = p['Denoising Normal'].copy(), p['Denoising Depth'].copy()
        dev = ew.Device(threads=a.threads)
        times, fresh = {}, {}
        out = np.zeros_like(color)
        for m, passes in CONFIGS:
            for stage in (1, 0):  # as a user gets it (the do-no-harm stage around it), and the method alone
                # An op kept across frames (ew.Op: its scratch stays allocated from one run to the next, as in a
                # graph run over a frame range), the way OIDN's network below is built once and then run; the
                # fastest of --repeat runs after its first (which allocates, as OIDN's first call does).
                op = ew.Op('kpcn', dev)
                op.set('model', m)
                op.set('passes', passes)
                if not stage:
                    op.set('do_no_harm', 0)
                    op.set('outlier_k', 0.0)
                run = lambda: op.run(color=color, albedo=albedo, normal=normal, depth=depth, output=out)
                run()
                times[m, passes, stage] = best_of(a.repeat, run)
                op.close()
                # and a new op every call (ew.run_node: a one-node graph built, committed, run, freed)
                kw = dict(method='kpcn', model=m, passes=passes, color=color, albedo=albedo, normal=normal,
                          depth=depth, device=dev)
                if not stage:
                    kw.update(do_no_harm=False, outlier_k=0.0)
                fresh[m, passes, stage] = best_of(a.repeat, lambda: ew.run_node('denoise', **kw))
                print('  %-13s (model %d, %s)%s: %8.0f ms wall, %8.0f ms CPU kept; %8.0f ms wall, %8.0f ms CPU '
                      'a new op each call' %
                      (config_name(m, passes), m, MODELS[m][1], ' with the do-no-harm stage' if stage else ' alone',
                       times[m, passes, stage][0] * 1e3, times[m, passes, stage][1] * 1e3,
                       fresh[m, passes, stage][0] * 1e3, fresh[m, passes, stage][1] * 1e3), flush=True)
        net = None
        if not a.no_oidn:
            sys.path.insert(0, os.path.dirname(os.path.abspath(a.oidn)))
            try:
                import oidn_torch
                net = oidn_torch.OIDN(a.weights or oidn_torch.DEFAULT_WEIGHTS, threads=a.threads)
            except (ImportError, OSError, ValueError) as e:
                print('  OIDN not run (%s: %s; see oidn_torch.py\'s docstring)' % (type(e).__name__, e))
        if net is not None:
            net(color, albedo, normal)  # its first call, as each kept op's above
            t_oidn = best_of(a.repeat, lambda: net(color, albedo, normal))
            print('  OIDN (oidn_torch.py, PyTorch %s): %8.0f ms wall, %8.0f ms CPU' %
                  (oidn_torch.torch.__version__, t_oidn[0] * 1e3, t_oidn[1] * 1e3))
            for m, passes in CONFIGS:
                name, _, target = MODELS[m]
                name, target = config_name(m, passes), target if passes == 1 else None
                for stage in (1, 0):
                    rw, rc = times[m, passes, stage][0] / t_oidn[0], times[m, passes, stage][1] / t_oidn[1]
                    verdict = 'no target' if target is None else 'target <= %.2f: %s' % (
                        target, 'met' if max(rw, rc) <= target else 'met in CPU time' if rc <= target else 'NOT met')
                    print('  %-13s%s / OIDN = %.3f wall, %.3f CPU (%s); a new op each call %.3f wall, %.3f CPU' %
                          (name, ' with the stage' if stage else ' alone', rw, rc, verdict,
                           fresh[m, passes, stage][0] / t_oidn[0], fresh[m, passes, stage][1] / t_oidn[1]))
        print('convolutions against the FMA peak (train_kpcn --bench %d %d %d):' % (w, h, a.threads), flush=True)
        trainer = os.path.join(build, 'bin', 'train_kpcn')
        out = ''
        if os.access(trainer, os.X_OK):
            out = subprocess.run([trainer, '--bench', str(w), str(h), str(a.threads)],
                                 check=True, capture_output=True, text=True).stdout
        else:  # the timings above stand without it
            print('  skipped: %s is not built (cmake --build %s --target train_kpcn)' % (trainer, build))
        for line in out.splitlines():
            if 'device memory at 3840x2160' in line:  # its estimate is of an untiled frame: the RSS below is measured
                line = line[:line.index('; device memory')]
            print('  ' + line.strip())
            share = re.search(r'= (\d+) % of the FMA peak', line)
            if share:
                print('    conv share %s %% (target >= 50 %%: %s)' % (share.group(1),
                                                                     'met' if int(share.group(1)) >= 50 else 'NOT met'))
        if a.uhd:
            big = resized(a.input, (3840, 2160), tmp)
            cli = os.path.join(build, 'bin', 'edgewise')
            for m in MODELS:
                r = subprocess.run(['/usr/bin/time', '-v', cli, 'denoise', big, '-o', os.path.join(tmp, 'out.exr'),
                                    '--method', 'kpcn', '--model', MODELS[m][0], '--threads', str(a.threads), '-q'],
                                   capture_output=True, text=True)
                rss = re.search(r'Maximum resident set size \(kbytes\): (\d+)', r.stderr)
                wall = re.search(r'Elapsed \(wall clock\) time.*: (\S+)', r.stderr)
                if r.returncode != 0 or not rss:
                    print('  3840x2160 %s failed:\n%s' % (MODELS[m][0], r.stderr[-2000:]))
                    continue
                print('  3840x2160 %s: peak RSS %.0f MiB, %s wall (edgewise denoise, EXR in and out)' %
                      (MODELS[m][0], int(rss.group(1)) / 1024.0, wall.group(1) if wall else '?'), flush=True)


if __name__ == '__main__':
    main()
