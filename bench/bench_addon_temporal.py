"""Per-frame PSNR of the Blender add-on's temporal path against per-frame denoising.

    EDGEWISE_LIB=build/lib /usr/bin/python3 bench/bench_addon_temporal.py [DATA] [--scenes a,b] [--spp 1,4]
        [--methods auto,nbg,bgrid]

DATA is a folder of scene folders as the project's generator writes them (default
../shared/data/cycles-train), each with frames fNNNN_sppSSSS.exr (Combined, Denoising Data,
Vector) and fNNNN_ref*.exr. Runs the add-on's own code (edgewise_denoise.core: denoise_arrays
for per-frame, denoise_frame with a TemporalHistory for temporal) on the frames in order and
prints, per scene / spp / method, both PSNR rows (tone-mapped: clip, gamma 1/2.2) and their
difference per frame: the add-on's rule is that no frame is more than 0.2 dB below per-frame.
"""
import argparse
import glob
import math
import os
import sys

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(REPO, "blender_addon"))
from edgewise_denoise import core  # noqa: E402


def tm(x):
    return np.clip(np.nan_to_num(np.asarray(x, np.float64)[..., :3]), 0, 1) ** (1 / 2.2)


def psnr(a, b):
    return 10 * math.log10(1.0 / max(float(np.mean((tm(a) - tm(b)) ** 2)), 1e-12))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("data", nargs="?", default=os.path.join(REPO, "..", "shared", "data", "cycles-train"))
    ap.add_argument("--scenes", default="g_anim_111_256x256,g_anim_123_256x256")
    ap.add_argument("--spp", default="1,4")
    ap.add_argument("--methods", default="auto,nbg,bgrid")
    a = ap.parse_args()
    ew = core.load_edgewise()
    worst_all = 0.0
    for scene in a.scenes.split(","):
        folder = os.path.join(a.data, scene)
        for spp in [int(s) for s in a.spp.split(",")]:
            frames = sorted(glob.glob(os.path.join(folder, "f*_spp%04d.exr" % spp)))
            if len(frames) < 2:
                print("%s: fewer than 2 frames at %d spp, skipped" % (scene, spp))
                continue
            for method in a.methods.split(","):
                settings = core.Settings(method, samples=spp)
                hist = core.TemporalHistory(ew)
                rows = []
                for i, path in enumerate(frames):
                    p = ew.run_node("read", path=path, outputs=["color", "albedo", "normal", "depth", "vector"])
                    p = dict((k, np.array(v)) for k, v in p.items())
                    ref_path = glob.glob(path.replace("_spp%04d.exr" % spp, "_ref*.exr"))[0]
                    ref = np.array(ew.run_node("read", path=ref_path, outputs="color"))
                    single, _ = core.denoise_arrays(p, settings)
                    temp, _ = core.denoise_frame(p, settings, i + 1, hist)
                    rows.append((psnr(single, ref), psnr(temp, ref)))
                hist.close()
                d = [t - s for s, t in rows]
                worst_all = min(worst_all, min(d))
                print("%s %d spp %-6s per-frame %s | temporal %s | diff %s | worst %+.2f mean %+.2f" % (
                    scene, spp, method, " ".join("%.2f" % s for s, _ in rows), " ".join("%.2f" % t for _, t in rows),
                    " ".join("%+.2f" % x for x in d), min(d), sum(d) / len(d)))
                sys.stdout.flush()
    print("worst frame, temporal minus per-frame: %+.2f dB (rule: >= -0.20)" % worst_all)


if __name__ == "__main__":
    main()
