"""Single nodes on numpy arrays: read the passes of the bundled render into
arrays, denoise them with one call, measure the result against the
reference. The arrays go into the library without a copy and the result
comes back as a view of the library's memory.

    python3 examples/denoise_numpy.py [OUTPUT_DIR]
"""
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "python"))

import numpy as np  # noqa: E402

import edgewise as ew  # noqa: E402

SAMPLE = os.path.join(HERE, "..", "samples", "cornell")


def read_passes(path, passes):
    """Passes of a render as numpy arrays, through a small graph."""
    g = ew.Graph()
    r = g.add("read", path=path)
    for name in passes:
        g.add("output", id=name, image=r[name])
    g.run()
    return dict((name, g.output(name)) for name in passes)


def psnr(test, reference):
    g = ew.Graph()
    g.add("metrics", id="m", image=g.add_input(test), reference=g.add_input(reference))
    return g.run()["frames"][0]["metrics"]["m"]["psnr"]


def main():
    out_dir = sys.argv[1] if len(sys.argv) > 1 else "."
    noisy = read_passes(os.path.join(SAMPLE, "f0001_spp0004.exr"), ("color", "albedo", "normal", "depth"))
    reference = read_passes(os.path.join(SAMPLE, "f0001_ref1024.exr"), ("color",))["color"]
    denoised = ew.run_node("denoise", method="bgrid", spatial_rate=8.0, **noisy)
    print("input %s, denoised %s %s" % (noisy["color"].shape, denoised.shape, denoised.dtype))
    print("PSNR noisy %.2f dB -> denoised %.2f dB" % (psnr(noisy["color"], reference), psnr(denoised, reference)))
    np.save(os.path.join(out_dir, "denoised.npy"), denoised)


if __name__ == "__main__":
    main()
