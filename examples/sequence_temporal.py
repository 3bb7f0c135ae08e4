"""A frame sequence, streamed: write five noisy frames of a moving edge as
seq_0001.exr ... seq_0005.exr, then run one graph over the sequence (read
pattern -> denoise -> temporal accumulation -> write pattern) with a
progress callback. One frame is in memory at a time.

    python3 examples/sequence_temporal.py [OUTPUT_DIR]

Needs the edgewise package installed (python/README.md: pip install ./python)
or PYTHONPATH=python from the repository.
"""
import os
import sys

import numpy as np

import edgewise as ew

HERE = os.path.dirname(os.path.abspath(__file__))


def make_frames(out_dir, count=5, width=96, height=64):
    rng = np.random.default_rng(7)
    for f in range(1, count + 1):
        x = np.arange(width)[None, :, None]
        clean = np.where(x < width // 3 + 4 * f, 0.8, 0.2).astype(np.float32) * np.ones((height, 1, 3), np.float32)
        noisy = clean * rng.gamma(2.0, 0.5, size=clean.shape).astype(np.float32)
        g = ew.Graph()
        g.add("write", image=g.add_input(noisy), path=os.path.join(out_dir, "seq_%04d.exr" % f), pixel_type="float")
        g.run()


def main():
    out_dir = sys.argv[1] if len(sys.argv) > 1 else "."
    make_frames(out_dir)
    g = ew.Graph()
    r = g.add("read", path=os.path.join(out_dir, "seq_####.exr"))
    d = g.add("denoise", method="bgrid", color=r.color)
    t = g.add("temporal", alpha_min=0.3, color=d)
    g.add("write", image=t, path=os.path.join(out_dir, "accumulated_####.exr"))
    report = g.run(progress=lambda f: print("\rprogress %3d %%" % round(100 * f), end="") or True)
    print()
    for frame in report["frames"]:
        print("frame %d: %s (%.3f s)" % (frame["frame"], ", ".join(frame["written"]), frame["seconds"]))
    stats = g.stats()
    print("%d frames, %d image buffers (%.1f KiB) reused across frames"
          % (stats["frames_done"], stats["num_buffers"], stats["buffer_bytes"] / 1024.0))


if __name__ == "__main__":
    main()
