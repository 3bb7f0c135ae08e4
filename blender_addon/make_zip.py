"""Build an installable add-on zip with the library bundled:

    /usr/bin/python3 blender_addon/make_zip.py [--lib-dir build/lib] [-o edgewise_denoise.zip]

The zip holds edgewise_denoise/ (the add-on), edgewise_denoise/edgewise/ (the
project's Python package, python/edgewise) and, next to that package,
libedgewise.so(.0), libedgewise_nodes.so(.0) and libedgewise_oiio.so (PNG, TIFF
and JPEG files, loaded when one is read or written) from --lib-dir. The libraries
are for this platform only (Linux x86-64 built here, linking the system's
OpenImageIO/OpenColorIO): build the zip on the platform it is for.
"""
import argparse
import os
import sys
import zipfile

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
LIBS = ("libedgewise.so", "libedgewise.so.0", "libedgewise_nodes.so", "libedgewise_nodes.so.0", "libedgewise_oiio.so")


def main():
    ap = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    ap.add_argument("--lib-dir", default=os.environ.get("EDGEWISE_LIB") or os.path.join(REPO, "build", "lib"))
    ap.add_argument("-o", "--output", default="edgewise_denoise.zip")
    ap.add_argument("--no-lib", action="store_true", help="leave the library out (found by path setting or $EDGEWISE_LIB)")
    a = ap.parse_args()
    libs = []
    if not a.no_lib:
        for n in LIBS:
            p = os.path.join(a.lib_dir, n)
            if n.endswith(".so") and not os.path.exists(p):
                sys.exit("make_zip: %s not found: build the project or pass --lib-dir" % p)
            if os.path.exists(p):
                libs.append((os.path.realpath(p), "edgewise_denoise/edgewise/" + n))
    with zipfile.ZipFile(a.output, "w", zipfile.ZIP_DEFLATED) as z:
        for src_dir, arc_dir in ((os.path.join(HERE, "edgewise_denoise"), "edgewise_denoise"),
                                 (os.path.join(REPO, "python", "edgewise"), "edgewise_denoise/edgewise")):
            for name in sorted(os.listdir(src_dir)):
                if name.endswith(".py"):
                    z.write(os.path.join(src_dir, name), arc_dir + "/" + name)
        for src, arc in libs:
            z.write(src, arc)  # symlinks dereferenced: plain copies
    print("wrote %s (%d libraries bundled)" % (a.output, len(libs)))


if __name__ == "__main__":
    main()
