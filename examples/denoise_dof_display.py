"""The graph of denoise_dof_display.json built in Python: denoise the bundled
Cornell box render, add depth of field, show it through OpenColorIO as
Blender would. Writes denoise_dof_display_py.exr (float) and .png into the
output directory and prints the quality against the reference.

    python3 examples/denoise_dof_display.py [OUTPUT_DIR]

Needs the edgewise package installed (python/README.md: pip install ./python)
or PYTHONPATH=python from the repository.
"""
import os
import sys

import edgewise as ew

HERE = os.path.dirname(os.path.abspath(__file__))


def build(out_dir, samples=os.path.join(HERE, "..", "samples")):
    g = ew.Graph()
    render = g.add("read", id="render", path=os.path.join(samples, "cornell", "f0001_spp0004.exr"))
    reference = g.add("read", id="reference", path=os.path.join(samples, "cornell", "f0001_ref1024.exr"))
    denoised = g.add("denoise", id="denoised", method="bgrid", spatial_rate=8.0, range_rate=8.0,
                     color=render.color, albedo=render.albedo, normal=render.normal, depth=render.depth)
    g.add("metrics", id="quality", image=denoised, reference=reference.color)
    lens = g.add("dof", id="lens", focal_length=50.0, fstop=2.0, focus_distance=4.0, weights="analytic",
                 color=denoised, depth=render.z)
    view = g.add("display", id="view", display="sRGB", view="Standard", color=lens.output)
    g.add("write", id="preview", path=os.path.join(out_dir, "denoise_dof_display_py.png"), image=view)
    g.add("write", id="pixels", path=os.path.join(out_dir, "denoise_dof_display_py.exr"), pixel_type="float",
          image=view)
    g.add("output", id="shown", image=view)
    return g


def main():
    out_dir = sys.argv[1] if len(sys.argv) > 1 else "."
    g = build(out_dir)
    report = g.run()
    q = report["frames"][0]["metrics"]["quality"]
    shown = g.output("shown")
    print("denoised vs reference: PSNR %.2f dB, SSIM %.4f; displayed image %dx%d, mean %.4f"
          % (q["psnr"], q["ssim"], shown.shape[1], shown.shape[0], float(shown.mean())))


if __name__ == "__main__":
    main()
