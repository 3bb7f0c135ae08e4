"""Single nodes on numpy arrays: read the passes of the bundled render into
arrays (edgewise.read), denoise them with one call, measure the result
against the reference, write it back into a copy of the render
(edgewise.write). The arrays go into the library without a copy and the result
comes back as a view of the library's memory.

    python3 examples/denoise_numpy.py [OUTPUT_DIR]

Needs the edgewise package installed (python/README.md: pip install ./python)
or PYTHONPATH=python from the repository.
"""
import os
import sys

import numpy as np

import edgewise as ew

HERE = os.path.dirname(os.path.abspath(__file__))

SAMPLE = os.path.join(HERE, "..", "samples", "cornell")


def psnr(test, reference):
    g = ew.Graph()
    g.add("metrics", id="m", image=g.add_input(test), reference=g.add_input(reference))
    return g.run()["frames"][0]["metrics"]["m"]["psnr"]


def main():
    out_dir = sys.argv[1] if len(sys.argv) > 1 else "."
    render = os.path.join(SAMPLE, "f0001_spp0004.exr")
    passes = ew.read(render)  # {pass name: (H, W, C) float32}, the first view layer
    reference = ew.read(os.path.join(SAMPLE, "f0001_ref1024.exr"), passes=["Combined"])["Combined"]
    noisy = passes["Combined"]  # RGBA: alpha goes through the denoiser
    denoised = ew.run_node("denoise", method="bgrid", spatial_rate=8.0, color=noisy,
                           albedo=passes["Denoising Albedo"], normal=passes["Denoising Normal"],
                           depth=passes["Denoising Depth"])
    print("input %s, denoised %s %s" % (noisy.shape, denoised.shape, denoised.dtype))
    print("PSNR noisy %.2f dB -> denoised %.2f dB" % (psnr(noisy[:, :, :3], reference[:, :, :3]),
                                                      psnr(denoised[:, :, :3], reference[:, :, :3])))
    # every other pass, alpha and the header of the render stay; the noisy
    # colour is kept as Blender keeps it
    ew.write(os.path.join(out_dir, "denoised.exr"), {"Combined": denoised, "Noisy Image": noisy}, like=render)
    np.save(os.path.join(out_dir, "denoised.npy"), denoised)


if __name__ == "__main__":
    main()
