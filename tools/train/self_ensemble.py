#!/usr/bin/env python3
"""Measure a self-ensemble of a kpcn model: the op on mirrored (or transposed)
frames, mirrored back and averaged, against the single pass.

Usage: EDGEWISE_LIB=build-rel/lib python3 tools/train/self_ensemble.py \
           [--spp 4,16] [--model kpcn-large] [--set transpose|mirrors] SCENE_DIR...

Each SCENE_DIR holds f0001_sppNNNN.exr and f0001_ref1024.exr (the layout of
../shared/data/cycles-train). Prints per scene the PSNR (the anchors' metric,
../shared/tools/metrics.py) of 1, 2 and 4 passes, then the means. Never give
it the test scenes of BENCHMARKS.md to choose anything.
"""
import argparse
import os
import sys

import numpy as np

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(here, "..", "..", "python"))
sys.path.insert(0, os.path.join(here, "..", "..", "..", "shared", "tools"))
import edgewise as ew  # noqa: E402
from metrics import psnr  # noqa: E402

SETS = {
    # each transform is its own inverse
    "transpose": [lambda a: a, lambda a: a[:, ::-1], lambda a: a[::-1, :], lambda a: a.transpose(1, 0, 2)],
    "mirrors": [lambda a: a, lambda a: a[:, ::-1], lambda a: a[::-1, :], lambda a: a[::-1, ::-1]],
}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scenes", nargs="+")
    ap.add_argument("--spp", default="4")
    ap.add_argument("--model", default="kpcn-large")
    ap.add_argument("--set", choices=sorted(SETS), default="transpose")
    a = ap.parse_args()
    op = ew.Op("kpcn")
    op.set("model", a.model)
    for spp in [int(x) for x in a.spp.split(",")]:
        rows = []
        for d in a.scenes:
            path = os.path.join(d, f"f0001_spp{spp:04d}.exr")
            if not os.path.exists(path):
                continue
            p = ew.read(path)
            ref = ew.read(os.path.join(d, "f0001_ref1024.exr"))["Combined"][..., :3]
            outs = []
            for t in SETS[a.set]:
                ins = {k: np.ascontiguousarray(t(p[name][..., :c])) for k, name, c in
                       (("color", "Combined", 3), ("albedo", "Denoising Albedo", 3),
                        ("normal", "Denoising Normal", 3), ("depth", "Denoising Depth", 1))}
                out = np.zeros_like(ins["color"])
                op.run(output=out, **ins)
                outs.append(np.ascontiguousarray(t(out)))
            r = [psnr(outs[0], ref), psnr(np.mean(outs[:2], 0), ref), psnr(np.mean(outs, 0), ref)]
            rows.append(r)
            print(spp, os.path.basename(d.rstrip("/")), " ".join(f"{x:.2f}" for x in r), flush=True)
        if rows:
            print(f"mean {spp} spp, 1 / 2 / 4 passes:", " ".join(f"{x:.3f}" for x in np.mean(rows, 0)), flush=True)


if __name__ == "__main__":
    main()
