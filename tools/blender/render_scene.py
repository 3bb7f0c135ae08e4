"""Edgewise procedural Cycles scene generator.

Run inside Blender (headless):

    blender -b --factory-startup --python tools/blender/render_scene.py -- \
        --family cornell --seed 100 --width 256 --height 256 \
        --spp 1,4,16,64 --ref-spp 1024 --frames 1 --out DIR

Builds a procedural scene of the given family (no downloaded assets; only
Blender's bundled studio-light HDRIs), auto-exposes it to a mean brightness of
about 0.18, and writes per frame N:

    DIR/fNNNN_sppSSSS.exr   noisy inputs (multilayer EXR, ZIP, half colour):
                            Combined, Denoising Albedo/Normal/Depth, Depth,
                            Normal, Vector (not for the motionblur family)
    DIR/fNNNN_refRRRR.exr   reference, Combined only, half
    DIR/meta.json           scene/render description (written last)

Every output file is written to a temporary name in DIR and then renamed with
os.replace, so a reader never sees a partial file.  See tools/blender/README.md.
"""

import argparse
import colorsys
import glob
import json
import math
import os
import random
import shutil
import sys
import tempfile
import time
import traceback

try:
    import bpy
    from mathutils import Vector
except ImportError:  # pragma: no cover - only meaningful inside Blender
    bpy = None

PROG = "render_scene.py"
USAGE = ("blender -b --factory-startup --python tools/blender/render_scene.py -- "
         "--family FAMILY --out DIR [options]")

# family name -> (letter prefix used by the dataset directories, description)
FAMILIES = {
    "cornell": ("a", "diffuse room lit by an area light"),
    "glossy": ("b", "glossy/metal objects on procedural textures"),
    "glass": ("c", "transmissive objects and caustics"),
    "firefly": ("d", "tiny very bright light, sample clamping off (raw fireflies)"),
    "dof": ("e", "camera depth of field"),
    "motionblur": ("f", "motion blur on, no Vector pass"),
    "anim": ("g", "4-frame camera/object animation, motion blur off, Vector pass on"),
    "hdri": ("h", "world lighting: bundled HDRIs or a Nishita sky"),
    # stability families, scenes where denoisers fail: not in the shared dataset or make_dataset.sh's default
    "volume": ("i", "room filled with fog and a smoke blob, lit by a spot (volume scattering)"),
    "texture": ("j", "high-frequency procedural textures and bump at sub-pixel scale (moire)"),
    "thin": ("k", "thin geometry: a wire fence, loose wires and grass blades"),
}
HDRI_DIR_CANDIDATES = [
    "/usr/share/blender/datafiles/studiolights/world",
]

LOG_PREFIX = "[render_scene]"


def log(msg):
    sys.stderr.write("%s %s\n" % (LOG_PREFIX, msg))
    sys.stderr.flush()


class UsageError(Exception):
    pass


# --------------------------------------------------------------------------
# argument parsing


def parse_family(text):
    t = text.strip().lower()
    for name, (letter, _) in FAMILIES.items():
        if t in (name, letter, "%s_%s" % (letter, name)):
            return name
    raise argparse.ArgumentTypeError(
        "unknown family %r (choose from: %s)" % (text, ", ".join(FAMILIES)))


def parse_spp_list(text):
    parts = [p.strip() for p in text.split(",")]
    if not parts or any(p == "" for p in parts):
        raise argparse.ArgumentTypeError(
            "bad spp list %r: expected comma-separated positive integers, e.g. 1,4,16,64" % text)
    vals = []
    for p in parts:
        try:
            v = int(p)
        except ValueError:
            raise argparse.ArgumentTypeError(
                "bad spp list %r: %r is not an integer" % (text, p))
        if v < 1 or v > 1 << 24:
            raise argparse.ArgumentTypeError(
                "bad spp list %r: %d is out of range 1..16777216" % (text, v))
        if v in vals:
            raise argparse.ArgumentTypeError("bad spp list %r: %d repeated" % (text, v))
        vals.append(v)
    return vals


def int_range(lo, hi, what):
    def conv(text):
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError("%s must be an integer, got %r" % (what, text))
        if v < lo or v > hi:
            raise argparse.ArgumentTypeError("%s must be in %d..%d, got %d" % (what, lo, hi, v))
        return v
    return conv


def pos_float(what):
    def conv(text):
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError("%s must be a number, got %r" % (what, text))
        if not (v > 0 and math.isfinite(v)):
            raise argparse.ArgumentTypeError("%s must be > 0, got %r" % (what, text))
        return v
    return conv


def build_parser():
    fam_lines = "\n".join("  %-11s (%s_) %s" % (n, l, d) for n, (l, d) in FAMILIES.items())
    p = argparse.ArgumentParser(
        prog=PROG, usage=USAGE,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Render one procedural Cycles scene: noisy inputs with feature passes "
                    "at several sample counts plus a high-sample reference.",
        epilog="families:\n" + fam_lines + "\n\n"
               "output, per frame N (1-based, --frame-start):\n"
               "  fNNNN_sppSSSS.exr  multilayer EXR (ZIP, half colour, float data passes):\n"
               "                     Combined, Denoising Albedo/Normal/Depth, Depth, Normal,\n"
               "                     Vector (omitted for motionblur)\n"
               "  fNNNN_refRRRR.exr  reference, ViewLayer.Combined only, half\n"
               "  meta.json          written last; its presence means the scene is complete\n\n"
               "exit status: 0 ok, 2 bad arguments / unwritable output, 1 render failure.")
    p.add_argument("--family", required=True, type=parse_family,
                   help="scene family (name, letter or letter_name)")
    p.add_argument("--seed", type=int_range(0, 2**31 - 1, "--seed"), default=0,
                   help="scene variant seed; same seed -> same scene and same noise (default 0)")
    p.add_argument("--width", type=int_range(8, 8192, "--width"), default=256)
    p.add_argument("--height", type=int_range(8, 8192, "--height"), default=256)
    p.add_argument("--spp", type=parse_spp_list, default=[1, 4, 16, 64],
                   help="comma-separated samples per pixel of the noisy inputs (default 1,4,16,64)")
    p.add_argument("--ref-spp", type=int_range(0, 1 << 24, "--ref-spp"), default=1024,
                   help="samples per pixel of the reference; 0 = no reference (default 1024)")
    p.add_argument("--frames", type=int_range(1, 10000, "--frames"), default=None,
                   help="number of frames (default: 4 for anim, 1 otherwise)")
    p.add_argument("--frame-start", type=int_range(0, 100000, "--frame-start"), default=1)
    p.add_argument("--out", required=True, help="output directory (created if missing)")
    p.add_argument("--target-mean", type=pos_float("--target-mean"), default=0.18,
                   help="auto-exposure target for the mean luminance (default 0.18)")
    p.add_argument("--preview-spp", type=int_range(1, 4096, "--preview-spp"), default=32,
                   help="samples of the auto-exposure preview render (default 32)")
    p.add_argument("--style", choices=("busy", "simple"), default="busy",
                   help="busy: many objects on procedural floors, emitters in view, a clipped "
                        "two-pass exposure (the render cache's scenes); simple: few large objects "
                        "near the camera, plain/checker/brick floors, lamps out of view, one "
                        "unclipped exposure preview (the look of the shared cycles-train set; "
                        "families cornell..hdri only; tools/blender/scenes_simple.py) (default busy)")
    p.add_argument("--no-autoexpose", action="store_true",
                   help="keep the built-in light strengths")
    p.add_argument("--threads", type=int_range(0, 1024, "--threads"), default=0,
                   help="Cycles render threads, 0 = all cores (default 0)")
    p.add_argument("--save-blend", metavar="PATH", default=None,
                   help="also save the built scene as a .blend (debugging)")
    p.add_argument("--verbose", action="store_true",
                   help="let Blender print its per-sample render log to stdout")
    return p


def script_argv():
    argv = sys.argv
    if "--" in argv:
        return argv[argv.index("--") + 1:]
    if bpy is None:          # plain python3: allow --help / argument checks
        return argv[1:]
    return []


def check_out_dir(path):
    """Create the output directory and prove it is writable (os.access lies for root)."""
    try:
        os.makedirs(path, exist_ok=True)
        if not os.path.isdir(path):
            raise OSError("not a directory")
        fd, probe = tempfile.mkstemp(prefix=".write-test-", dir=path)
        os.close(fd)
        os.remove(probe)
    except OSError as e:
        raise UsageError("output directory %r is not writable: %s" % (path, e))


# --------------------------------------------------------------------------
# scene-building helpers


def hsv(h, s, v):
    return colorsys.hsv_to_rgb(h % 1.0, s, v)


def rand_color(rng, s=(0.3, 0.9), v=(0.3, 0.85)):
    return hsv(rng.random(), rng.uniform(*s), rng.uniform(*v))


def clear_scene():
    for ob in list(bpy.data.objects):
        bpy.data.objects.remove(ob, do_unlink=True)
    for coll in (bpy.data.meshes, bpy.data.materials, bpy.data.lights, bpy.data.cameras):
        for x in list(coll):
            coll.remove(x)


def link(ob):
    bpy.context.scene.collection.objects.link(ob)
    return ob


def set_smooth(ob, angle_deg=35.0):
    me = ob.data
    for poly in me.polygons:
        poly.use_smooth = True
    me.use_auto_smooth = True
    me.auto_smooth_angle = math.radians(angle_deg)


def assign(ob, mat):
    ob.data.materials.clear()
    ob.data.materials.append(mat)


def add_plane(name, center, rot, sx, sy, mat):
    bpy.ops.mesh.primitive_plane_add(size=1.0, location=center, rotation=rot)
    ob = bpy.context.active_object
    ob.name = name
    for v in ob.data.vertices:  # bake the size so Object texture coords are metres
        v.co.x *= sx
        v.co.y *= sy
    assign(ob, mat)
    return ob


# height of the object's centre above the floor when resting on it, per unit size
REST_Z = {"sphere": 1.0, "cube": 1.0, "cylinder": 1.0, "cone": 1.0, "torus": 0.35,
          "monkey": 0.75, "tallbox": 2.0, "ico": 1.0}


def add_obj(kind, loc, size, rot_z=0.0, mat=None, name=None):
    """Add a primitive resting at floor point loc (x, y, floor_z); size ~ radius in metres."""
    x, y, z0 = loc
    z = z0 + REST_Z[kind] * size
    rot = (0.0, 0.0, rot_z)
    o = bpy.ops.mesh
    if kind == "sphere":
        o.primitive_uv_sphere_add(segments=48, ring_count=24, radius=size, location=(x, y, z))
    elif kind == "ico":
        o.primitive_ico_sphere_add(subdivisions=3, radius=size, location=(x, y, z))
    elif kind == "cube":
        o.primitive_cube_add(size=2 * size, location=(x, y, z), rotation=rot)
    elif kind == "tallbox":
        o.primitive_cube_add(size=2 * size, location=(x, y, z), rotation=rot)
    elif kind == "cylinder":
        o.primitive_cylinder_add(vertices=48, radius=size, depth=2 * size,
                                 location=(x, y, z), rotation=rot)
    elif kind == "cone":
        o.primitive_cone_add(vertices=48, radius1=size, depth=2 * size,
                             location=(x, y, z), rotation=rot)
    elif kind == "torus":
        o.primitive_torus_add(major_radius=size * 0.65, minor_radius=size * 0.35,
                              major_segments=64, minor_segments=24,
                              location=(x, y, z), rotation=rot)
    elif kind == "monkey":
        o.primitive_monkey_add(size=1.5 * size, location=(x, y, z),
                               rotation=(0.0, 0.0, rot_z))
    else:
        raise ValueError(kind)
    ob = bpy.context.active_object
    if kind == "tallbox":
        # bake the scale into the mesh so Object coordinates are metres
        for v in ob.data.vertices:
            v.co.z *= 2.0
            v.co.x *= 0.6
            v.co.y *= 0.6
        ob.scale = (1.0, 1.0, 1.0)
    if kind == "monkey":
        mod = ob.modifiers.new("subsurf", "SUBSURF")
        mod.levels = 1
        mod.render_levels = 1
    set_smooth(ob)
    if name:
        ob.name = name
    if mat is not None:
        assign(ob, mat)
    return ob


TEX_KINDS = ("checker", "noise", "voronoi", "wave", "brick", "magic")


def proc_texture(nt, rng, c1, c2, scale, kind=None):
    """Procedural texture in object space; returns (colour socket, fac socket, kind)."""
    N, L = nt.nodes, nt.links
    kind = kind or rng.choice(TEX_KINDS)
    tc = N.new("ShaderNodeTexCoord")
    mp = N.new("ShaderNodeMapping")
    mp.inputs["Location"].default_value = (rng.uniform(-5, 5), rng.uniform(-5, 5),
                                           rng.uniform(-5, 5))
    mp.inputs["Rotation"].default_value = (0.0, 0.0, rng.uniform(0, 2 * math.pi))
    L.new(tc.outputs["Object"], mp.inputs["Vector"])
    col = None
    if kind == "checker":
        t = N.new("ShaderNodeTexChecker")
        t.inputs["Color1"].default_value = (*c1, 1.0)
        t.inputs["Color2"].default_value = (*c2, 1.0)
        t.inputs["Scale"].default_value = scale
        col, fac = t.outputs["Color"], t.outputs["Fac"]
    elif kind == "noise":
        t = N.new("ShaderNodeTexNoise")
        t.inputs["Scale"].default_value = scale * 1.5
        t.inputs["Detail"].default_value = rng.uniform(1.0, 8.0)
        t.inputs["Roughness"].default_value = rng.uniform(0.4, 0.7)
        t.inputs["Distortion"].default_value = rng.uniform(0.0, 2.0)
        fac = t.outputs["Fac"]
    elif kind == "voronoi":
        t = N.new("ShaderNodeTexVoronoi")
        t.feature = rng.choice(["F1", "F2", "SMOOTH_F1"])
        t.inputs["Scale"].default_value = scale * 1.5
        fac = t.outputs["Distance"]
    elif kind == "wave":
        t = N.new("ShaderNodeTexWave")
        t.wave_type = rng.choice(["BANDS", "RINGS"])
        t.inputs["Scale"].default_value = scale * 0.5
        t.inputs["Distortion"].default_value = rng.uniform(0.0, 8.0)
        t.inputs["Detail"].default_value = rng.uniform(0.0, 4.0)
        fac = t.outputs["Fac"]
    elif kind == "brick":
        t = N.new("ShaderNodeTexBrick")
        t.inputs["Color1"].default_value = (*c1, 1.0)
        t.inputs["Color2"].default_value = (*c2, 1.0)
        m = [0.5 * (a + b) * 0.3 for a, b in zip(c1, c2)]
        t.inputs["Mortar"].default_value = (*m, 1.0)
        t.inputs["Scale"].default_value = scale
        col, fac = t.outputs["Color"], t.outputs["Fac"]
    elif kind == "magic":
        t = N.new("ShaderNodeTexMagic")
        t.turbulence_depth = rng.randint(1, 4)
        t.inputs["Scale"].default_value = scale * 0.5
        fac = t.outputs["Fac"]
    else:
        raise ValueError(kind)
    L.new(mp.outputs["Vector"], t.inputs["Vector"])
    if col is None:
        ramp = N.new("ShaderNodeValToRGB")
        ramp.color_ramp.elements[0].color = (*c1, 1.0)
        ramp.color_ramp.elements[1].color = (*c2, 1.0)
        ramp.color_ramp.elements[0].position = rng.uniform(0.0, 0.35)
        ramp.color_ramp.elements[1].position = rng.uniform(0.65, 1.0)
        L.new(fac, ramp.inputs["Fac"])
        col = ramp.outputs["Color"]
    return col, fac, kind


def mat_diffuse(name, color, rng=None, tex=None):
    """Pure diffuse (Diffuse BSDF).  tex = (c2, scale[, kind]) adds a procedural texture."""
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nt = m.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (*color, 1.0)
    d.inputs["Roughness"].default_value = 0.0
    nt.links.new(d.outputs["BSDF"], nt.nodes["Material Output"].inputs["Surface"])
    if tex is not None:
        col, _, _ = proc_texture(nt, rng, color, tex[0], tex[1], *tex[2:])
        nt.links.new(col, d.inputs["Color"])
    return m


def mat_emission(name, color, strength):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nt = m.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    e = nt.nodes.new("ShaderNodeEmission")
    e.inputs["Color"].default_value = (*color, 1.0)
    e.inputs["Strength"].default_value = strength
    nt.links.new(e.outputs["Emission"], nt.nodes["Material Output"].inputs["Surface"])
    return m


def mat_principled(name, color, rough=0.5, metal=0.0, spec=0.5, transmission=0.0,
                   ior=1.45, clearcoat=0.0, rng=None, tex=None, rough_tex=None):
    """Principled BSDF.  tex = (c2, scale[, kind]); rough_tex = (r_lo, r_hi) drives
    roughness from the texture's fac."""
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nt = m.node_tree
    p = nt.nodes["Principled BSDF"]
    p.inputs["Base Color"].default_value = (*color, 1.0)
    p.inputs["Roughness"].default_value = rough
    p.inputs["Metallic"].default_value = metal
    p.inputs["Specular"].default_value = spec
    p.inputs["Transmission"].default_value = transmission
    p.inputs["Transmission Roughness"].default_value = 0.0
    p.inputs["IOR"].default_value = ior
    p.inputs["Clearcoat"].default_value = clearcoat
    if tex is not None:
        col, fac, _ = proc_texture(nt, rng, color, tex[0], tex[1], *tex[2:])
        nt.links.new(col, p.inputs["Base Color"])
        if rough_tex is not None:
            mr = nt.nodes.new("ShaderNodeMapRange")
            mr.inputs["To Min"].default_value = rough_tex[0]
            mr.inputs["To Max"].default_value = rough_tex[1]
            nt.links.new(fac, mr.inputs["Value"])
            nt.links.new(mr.outputs["Result"], p.inputs["Roughness"])
    return m


def random_surface(rng, name, allow_glass=False, allow_metal=True):
    """A random 'object' material: diffuse, plastic, textured plastic, metal, glass."""
    kinds = ["diffuse", "plastic", "textured"]
    if allow_metal:
        kinds.append("metal")
    if allow_glass:
        kinds.append("glass")
    k = rng.choice(kinds)
    c = rand_color(rng)
    if k == "diffuse":
        return mat_diffuse(name, c), k
    if k == "plastic":
        return mat_principled(name, c, rough=rng.uniform(0.05, 0.5), spec=rng.uniform(0.3, 0.8)), k
    if k == "textured":
        return mat_principled(name, c, rough=rng.uniform(0.1, 0.6), rng=rng,
                              tex=(rand_color(rng), rng.uniform(2, 8))), k
    if k == "metal":
        return mat_principled(name, metal_color(rng), rough=rng.uniform(0.02, 0.4),
                              metal=1.0), k
    return mat_principled(name, hsv(rng.random(), rng.uniform(0, 0.3), 1.0), rough=0.0,
                          transmission=1.0, ior=rng.uniform(1.4, 1.6)), k


def metal_color(rng):
    presets = [(0.95, 0.93, 0.88), (1.0, 0.78, 0.34), (0.95, 0.64, 0.54),
               (0.91, 0.92, 0.92), (0.56, 0.57, 0.58)]
    if rng.random() < 0.7:
        return rng.choice(presets)
    return hsv(rng.random(), rng.uniform(0.2, 0.6), rng.uniform(0.6, 0.95))


def add_light(kind, name, loc, energy, color=(1.0, 1.0, 1.0), size=0.5, target=None,
              rot=None, **kw):
    ld = bpy.data.lights.new(name, kind)
    ld.energy = energy
    ld.color = color
    if kind == "AREA":
        ld.size = size
        ld.shape = kw.get("shape", "SQUARE")
    elif kind in ("POINT", "SPOT"):
        ld.shadow_soft_size = size
        if kind == "SPOT":
            ld.spot_size = kw.get("spot_size", math.radians(60))
            ld.spot_blend = kw.get("spot_blend", 0.2)
    elif kind == "SUN":
        ld.angle = size
    ob = link(bpy.data.objects.new(name, ld))
    ob.location = loc
    if target is not None:
        look_at(ob, target)
    elif rot is not None:
        ob.rotation_euler = rot
    return ob


def look_at(ob, target):
    d = Vector(target) - Vector(ob.location)
    ob.rotation_euler = d.to_track_quat("-Z", "Y").to_euler()


def add_camera(loc, target, lens=40.0):
    cd = bpy.data.cameras.new("Cam")
    cd.lens = lens
    cd.sensor_fit = "AUTO"
    cd.sensor_width = 36.0
    cd.clip_start = 0.05
    cd.clip_end = 1000.0
    ob = link(bpy.data.objects.new("Cam", cd))
    ob.location = loc
    look_at(ob, target)
    bpy.context.scene.camera = ob
    return ob


def orbit_point(target, dist, az_deg, el_deg):
    az, el = math.radians(az_deg), math.radians(el_deg)
    # azimuth 0 = camera on the -Y side looking towards +Y
    return (target[0] + dist * math.cos(el) * math.sin(az),
            target[1] - dist * math.cos(el) * math.cos(az),
            target[2] + dist * math.sin(el))


def world_nodes():
    w = bpy.context.scene.world
    if w is None:
        w = bpy.data.worlds.new("World")
        bpy.context.scene.world = w
    w.use_nodes = True
    nt = w.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    out = nt.nodes.new("ShaderNodeOutputWorld")
    bg = nt.nodes.new("ShaderNodeBackground")
    nt.links.new(bg.outputs["Background"], out.inputs["Surface"])
    return nt, bg


def set_world_color(color, strength):
    _, bg = world_nodes()
    bg.inputs["Color"].default_value = (*color, 1.0)
    bg.inputs["Strength"].default_value = strength


def hdri_files():
    for d in HDRI_DIR_CANDIDATES:
        files = sorted(glob.glob(os.path.join(d, "*.exr")))
        if files:
            return files
    return []


def set_world_hdri(path, rot_z, strength):
    nt, bg = world_nodes()
    tc = nt.nodes.new("ShaderNodeTexCoord")
    mp = nt.nodes.new("ShaderNodeMapping")
    mp.inputs["Rotation"].default_value = (0.0, 0.0, rot_z)
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(path, check_existing=True)
    nt.links.new(tc.outputs["Generated"], mp.inputs["Vector"])
    nt.links.new(mp.outputs["Vector"], env.inputs["Vector"])
    nt.links.new(env.outputs["Color"], bg.inputs["Color"])
    bg.inputs["Strength"].default_value = strength


def set_world_sky(rng, strength):
    nt, bg = world_nodes()
    sky = nt.nodes.new("ShaderNodeTexSky")
    sky.sky_type = "NISHITA"
    # >= 22 deg keeps the sun disc above the frame (camera pitch >= 5 deg, half fov <= 24 deg)
    sky.sun_elevation = math.radians(rng.uniform(22.0, 65.0))
    sky.sun_rotation = rng.uniform(0.0, 2 * math.pi)
    sky.altitude = rng.uniform(0.0, 500.0)
    sky.air_density = rng.uniform(0.5, 2.0)
    sky.dust_density = rng.uniform(0.0, 3.0)
    sky.ozone_density = rng.uniform(0.5, 2.0)
    sky.sun_disc = True
    sky.sun_size = math.radians(rng.uniform(0.5, 2.0))
    nt.links.new(sky.outputs["Color"], bg.inputs["Color"])
    bg.inputs["Strength"].default_value = strength
    return {"sun_elevation_deg": math.degrees(sky.sun_elevation)}


def scatter(rng, n, xr, yr, size_r, kinds, floor_z=0.0, placed=None, gap=0.08, tries=400):
    """Non-overlapping (x, y, size, kind) on the floor."""
    placed = [] if placed is None else placed
    out = []
    for _ in range(n):
        for _try in range(tries):
            s = rng.uniform(*size_r)
            k = rng.choice(kinds)
            x = rng.uniform(xr[0] + s, xr[1] - s)
            y = rng.uniform(yr[0] + s, yr[1] - s)
            if all(math.hypot(x - px, y - py) > s + ps + gap for px, py, ps in placed):
                placed.append((x, y, s))
                out.append((x, y, s, k))
                break
    return out


def key_linear(ob):
    ad = ob.animation_data
    if ad is None or ad.action is None:
        return
    for fc in ad.action.fcurves:
        fc.extrapolation = "LINEAR"
        for kp in fc.keyframe_points:
            kp.interpolation = "LINEAR"


def animate_linear(ob, f0, f1, loc0, loc1, rot0=None, rot1=None):
    ob.location = loc0
    ob.keyframe_insert("location", frame=f0)
    ob.location = loc1
    ob.keyframe_insert("location", frame=f1)
    if rot0 is not None:
        ob.rotation_euler = rot0
        ob.keyframe_insert("rotation_euler", frame=f0)
        ob.rotation_euler = rot1
        ob.keyframe_insert("rotation_euler", frame=f1)
    key_linear(ob)


def floor_material(rng, name="Floor", glossy=False):
    c1 = rand_color(rng, s=(0.0, 0.6), v=(0.4, 0.85))
    c2 = rand_color(rng, s=(0.0, 0.6), v=(0.05, 0.4))
    if glossy:
        return mat_principled(name, c1, rough=rng.uniform(0.1, 0.5), spec=0.5, rng=rng,
                              tex=(c2, rng.uniform(0.5, 3.0)),
                              rough_tex=(rng.uniform(0.05, 0.3), rng.uniform(0.3, 0.8))
                              if rng.random() < 0.5 else None)
    return mat_diffuse(name, c1, rng=rng, tex=(c2, rng.uniform(0.5, 3.0)))


# --------------------------------------------------------------------------
# families.  Each builder gets (rng, ctx) and returns a dict of meta extras
# (ctx: width, height, frame_start, frames).


def build_room(rng, colorful_walls=True, glossy_floor=False):
    W = rng.uniform(1.8, 2.6)
    D = rng.uniform(1.8, 2.8)
    H = rng.uniform(1.8, 2.4)
    white = rng.uniform(0.65, 0.85)
    wcol = (white, white * rng.uniform(0.95, 1.0), white * rng.uniform(0.9, 1.0))
    h1 = rng.random()
    if colorful_walls:
        lcol = hsv(h1, rng.uniform(0.55, 0.9), rng.uniform(0.45, 0.75))
        rcol = hsv(h1 + rng.uniform(0.25, 0.5), rng.uniform(0.55, 0.9), rng.uniform(0.45, 0.75))
    else:
        lcol = rcol = wcol
    m_white = mat_diffuse("White", wcol)
    if glossy_floor:
        m_floor = mat_principled("Floor", rand_color(rng, s=(0, 0.4), v=(0.3, 0.7)),
                                 rough=rng.uniform(0.03, 0.2), spec=0.6, rng=rng,
                                 tex=(rand_color(rng, v=(0.1, 0.4)), rng.uniform(1, 4)))
    elif rng.random() < 0.35:
        m_floor = mat_diffuse("Floor", wcol, rng=rng,
                              tex=(rand_color(rng, v=(0.2, 0.6)), rng.uniform(1, 4)))
    else:
        m_floor = m_white
    add_plane("Floor", (0, D / 2, 0), (0, 0, 0), W, D, m_floor)
    add_plane("Ceiling", (0, D / 2, H), (math.pi, 0, 0), W, D, m_white)
    add_plane("Back", (0, D, H / 2), (math.pi / 2, 0, 0), W, H, m_white)
    add_plane("Left", (-W / 2, D / 2, H / 2), (0, math.pi / 2, 0), H, D, mat_diffuse("Left", lcol))
    add_plane("Right", (W / 2, D / 2, H / 2), (0, -math.pi / 2, 0), H, D, mat_diffuse("Right", rcol))
    return W, D, H


def room_camera(rng, W, D, H, ctx):
    d = rng.uniform(2.4, 3.4)
    aspect = ctx["width"] / ctx["height"]
    # fit the front opening (W x H) into the frame
    half_w = 0.5 * W * 0.97
    half_h = 0.5 * H * 0.97
    # Blender's sensor_fit AUTO applies sensor_width to the larger image dimension
    if aspect >= 1.0:
        half_fov = min(math.atan(half_w / d), math.atan(half_h * aspect / d))
    else:
        half_fov = min(math.atan(half_w / aspect / d), math.atan(half_h / d))
    lens = 18.0 / math.tan(half_fov)
    cam = add_camera((0.0, -d, H / 2), (0.0, D / 2, H / 2 - rng.uniform(0.0, 0.1)), lens=lens)
    return cam


def build_cornell(rng, ctx):
    W, D, H = build_room(rng)
    n = rng.randint(2, 4)
    items = scatter(rng, n, (-W / 2 + 0.05, W / 2 - 0.05), (0.25, D - 0.05), (0.2, 0.42),
                    ["cube", "tallbox", "sphere", "cylinder", "cube"])
    for i, (x, y, s, k) in enumerate(items):
        if k == "tallbox":
            s = min(s, H / 4.5)
        c = (rand_color(rng, s=(0.0, 0.6), v=(0.5, 0.85)) if rng.random() < 0.5
             else (0.75, 0.75, 0.75))
        add_obj(k, (x, y, 0.0), s, rot_z=rng.uniform(0, math.pi / 2),
                mat=mat_diffuse("Obj%d" % i, c), name="Obj%d" % i)
    # the area light: an emissive ceiling panel (a mesh light, so unlike a Blender
    # area lamp it is visible to the camera, as in the classic Cornell box)
    lsx = rng.uniform(0.25, 0.45) * W
    lsy = rng.uniform(0.25, 0.45) * D
    add_plane("CeilingLight",
              (rng.uniform(-0.2, 0.2) * W, D / 2 + rng.uniform(-0.15, 0.15) * D, H - 0.002),
              (math.pi, 0, 0), lsx, lsy,
              mat_emission("CeilingLight",
                           hsv(rng.uniform(0.05, 0.15), rng.uniform(0, 0.25), 1.0), 15.0))
    set_world_color((1.0, 1.0, 1.0), 0.02)
    room_camera(rng, W, D, H, ctx)
    return {}


def build_firefly(rng, ctx):
    W, D, H = build_room(rng, colorful_walls=rng.random() < 0.5, glossy_floor=True)
    items = scatter(rng, rng.randint(2, 4), (-W / 2 + 0.05, W / 2 - 0.05), (0.25, D - 0.05),
                    (0.18, 0.4), ["sphere", "cube", "cylinder", "torus", "monkey"])
    for i, (x, y, s, k) in enumerate(items):
        if i == 0 or rng.random() < 0.4:   # at least one near-mirror: caustic paths
            m = mat_principled("Obj%d" % i, metal_color(rng), rough=rng.uniform(0.0, 0.08),
                               metal=1.0)
        else:
            m, _ = random_surface(rng, "Obj%d" % i)
        add_obj(k, (x, y, 0.0), s, rot_z=rng.uniform(0, 2 * math.pi), mat=m, name="Obj%d" % i)
    # a tiny, very bright point light near the ceiling, mostly hidden by a shade
    # below it, so most of the room is lit indirectly
    lx = rng.uniform(-0.3, 0.3) * W
    ly = rng.uniform(0.3, 0.8) * D
    lz = H - rng.uniform(0.15, 0.35)
    radius = rng.uniform(0.002, 0.01)
    add_light("POINT", "TinyLight", (lx, ly, lz), energy=30.0, size=radius,
              color=hsv(rng.uniform(0.05, 0.15), rng.uniform(0.0, 0.3), 1.0))
    # The light shines up at a slightly glossy ceiling from above a metal shade: paths
    # diffuse -> glossy ceiling (or mirror object) -> tiny light cannot be light-sampled
    # and come out as fireflies.  (Without the shade the light is mostly sampled
    # directly and the fireflies are rare and mild.)
    w = rng.uniform(0.65, 0.85)
    ceil_rough = rng.uniform(0.05, 0.25)
    assign(bpy.data.objects["Ceiling"],
           mat_principled("GlossyCeiling", (w, w, w), rough=ceil_rough, spec=0.5))
    shade_r = rng.uniform(0.12, 0.25)
    bpy.ops.mesh.primitive_cylinder_add(vertices=48, radius=shade_r, depth=0.01,
                                        location=(lx, ly, lz - 0.04))
    ob = bpy.context.active_object
    ob.name = "Shade"
    assign(ob, mat_principled("Shade", (0.8, 0.8, 0.8), rough=rng.uniform(0.1, 0.4), metal=1.0))
    set_world_color((1.0, 1.0, 1.0), 0.005)
    room_camera(rng, W, D, H, ctx)
    return {"firefly_light_radius": radius, "firefly_shade_radius": shade_r,
            "firefly_ceiling_roughness": ceil_rough}


def stage(rng, back_wall_p=0.5, glossy_floor=None):
    """Large textured floor (and maybe a back wall) around the origin."""
    if glossy_floor is None:
        glossy_floor = rng.random() < 0.5
    add_plane("Floor", (0, 0, 0), (0, 0, 0), 60.0, 60.0, floor_material(rng, glossy=glossy_floor))
    if rng.random() < back_wall_p:
        y = rng.uniform(3.0, 6.0)
        add_plane("BackWall", (0, y, 15.0), (math.pi / 2, 0, 0), 60.0, 30.0,
                  floor_material(rng, "BackWall", glossy=False))


def stage_camera(rng, target=(0.0, 0.0, 0.5), dist=(6.0, 8.5), el=(10.0, 32.0), az=35.0,
                 lens=(40.0, 55.0)):
    loc = orbit_point(target, rng.uniform(*dist), rng.uniform(-az, az), rng.uniform(*el))
    return add_camera(loc, target, lens=rng.uniform(*lens))


def key_lights(rng, n=None, energy=300.0):
    n = n or rng.randint(1, 2)
    for i in range(n):
        loc = orbit_point((0, 0, 0), rng.uniform(4.0, 7.0), rng.uniform(-120, 120),
                          rng.uniform(25, 70))
        add_light("AREA", "Key%d" % i, loc, energy=energy * (1.0 if i == 0 else 0.4),
                  size=rng.uniform(0.8, 3.0), target=(0, 0, 0.3),
                  color=hsv(rng.random(), rng.uniform(0.0, 0.3), 1.0))


def build_glossy(rng, ctx):
    stage(rng, glossy_floor=True)
    items = scatter(rng, rng.randint(3, 6), (-2.6, 2.6), (-1.8, 1.8), (0.3, 0.8),
                    ["sphere", "torus", "monkey", "cube", "cylinder", "cone", "sphere"])
    for i, (x, y, s, k) in enumerate(items):
        r = rng.random()
        if r < 0.45:
            m = mat_principled("Obj%d" % i, metal_color(rng), rough=rng.uniform(0.0, 0.35),
                               metal=1.0)
        elif r < 0.8:
            m = mat_principled("Obj%d" % i, rand_color(rng), rough=rng.uniform(0.0, 0.3),
                               spec=rng.uniform(0.5, 1.0), clearcoat=rng.choice([0.0, 1.0]))
        else:
            m = mat_principled("Obj%d" % i, rand_color(rng), rough=0.2, rng=rng,
                               metal=rng.choice([0.0, 1.0]),
                               tex=(rand_color(rng), rng.uniform(2, 8)),
                               rough_tex=(rng.uniform(0.0, 0.1), rng.uniform(0.3, 0.6)))
        add_obj(k, (x, y, 0.0), s, rot_z=rng.uniform(0, 2 * math.pi), mat=m, name="Obj%d" % i)
    key_lights(rng)
    set_world_color(hsv(rng.uniform(0.5, 0.65), rng.uniform(0.0, 0.4), 1.0), rng.uniform(0.1, 0.4))
    stage_camera(rng)
    return {}


def build_glass(rng, ctx):
    stage(rng, glossy_floor=False)
    items = scatter(rng, rng.randint(2, 4), (-2.2, 2.2), (-1.5, 1.5), (0.35, 0.8),
                    ["sphere", "cylinder", "monkey", "torus", "cube", "ico"])
    for i, (x, y, s, k) in enumerate(items):
        tint = hsv(rng.random(), rng.uniform(0.0, 0.5) if rng.random() < 0.6 else 0.0, 1.0)
        m = mat_principled("Glass%d" % i, tint,
                           rough=0.0 if rng.random() < 0.7 else rng.uniform(0.02, 0.15),
                           transmission=1.0, ior=rng.uniform(1.33, 1.8), spec=0.5)
        add_obj(k, (x, y, 0.0), s, rot_z=rng.uniform(0, 2 * math.pi), mat=m, name="Glass%d" % i)
    # an opaque object or two for refraction to show
    for j, (x, y, s, k) in enumerate(scatter(rng, rng.randint(0, 2), (-3.0, 3.0), (0.0, 2.5),
                                             (0.2, 0.5), ["cube", "sphere", "cylinder"],
                                             placed=[(a, b, c) for a, b, c, _ in items])):
        m, _ = random_surface(rng, "Opaque%d" % j, allow_metal=False)
        add_obj(k, (x, y, 0.0), s, rot_z=rng.uniform(0, 2 * math.pi), mat=m, name="Opaque%d" % j)
    # a small hard light for sharp caustics
    loc = orbit_point((0, 0, 0), rng.uniform(4.0, 6.0), rng.uniform(-100, 100),
                      rng.uniform(35, 70))
    if rng.random() < 0.6:
        add_light("SPOT", "Spot", loc, energy=1500.0, size=rng.uniform(0.02, 0.15),
                  target=(0, 0, 0), spot_size=math.radians(rng.uniform(40, 70)), spot_blend=0.3)
    else:
        add_light("AREA", "SmallArea", loc, energy=500.0, size=rng.uniform(0.1, 0.4),
                  target=(0, 0, 0))
    set_world_color(hsv(rng.uniform(0.5, 0.65), rng.uniform(0.0, 0.3), 1.0), rng.uniform(0.05, 0.2))
    stage_camera(rng)
    return {}


def build_dof(rng, ctx):
    add_plane("Floor", (0, 20, 0), (0, 0, 0), 80.0, 80.0,
              floor_material(rng, glossy=rng.random() < 0.3))
    cam_loc = (rng.uniform(-0.5, 0.5), -2.0, rng.uniform(0.6, 1.6))
    target = (0.0, 8.0, 0.4)
    lens = rng.uniform(50.0, 85.0)
    placed = []
    objs = []
    for i in range(rng.randint(8, 14)):
        for _ in range(200):
            y = rng.uniform(0.5, 16.0)
            spread = 0.3 + 0.22 * (y + 2.0) * (36.0 / lens)
            x = rng.uniform(-spread, spread)
            s = rng.uniform(0.15, 0.5)
            if all(math.hypot(x - px, y - py) > s + ps + 0.1 for px, py, ps in placed):
                placed.append((x, y, s))
                break
        else:
            continue
        m, _ = random_surface(rng, "Obj%d" % i)
        k = rng.choice(["sphere", "cube", "cylinder", "torus", "monkey", "cone"])
        objs.append(add_obj(k, (x, y, 0.0), s, rot_z=rng.uniform(0, 2 * math.pi),
                            mat=m, name="Obj%d" % i))
    sun_dir = orbit_point((0, 0, 0), 1.0, rng.uniform(-150, 150), rng.uniform(20, 60))
    add_light("SUN", "Sun", sun_dir, energy=3.0, size=math.radians(rng.uniform(0.5, 5.0)),
              target=(0, 0, 0), color=hsv(rng.uniform(0.06, 0.12), rng.uniform(0.0, 0.3), 1.0))
    set_world_color(hsv(rng.uniform(0.55, 0.62), rng.uniform(0.2, 0.6), 1.0), rng.uniform(0.3, 1.0))
    cam = add_camera(cam_loc, target, lens=lens)
    cd = cam.data
    cd.dof.use_dof = True
    cd.dof.aperture_fstop = rng.uniform(1.2, 2.8)
    cd.dof.aperture_blades = rng.choice([0, 0, 5, 6, 8])
    cd.dof.aperture_rotation = rng.uniform(0, math.pi)
    bpy.context.view_layer.update()
    fwd = cam.matrix_world.to_3x3() @ Vector((0.0, 0.0, -1.0))
    focus_ob = rng.choice(objs) if objs else None
    if focus_ob is not None:
        fd = (focus_ob.location - cam.matrix_world.translation).dot(fwd)
    else:
        fd = 5.0
    cd.dof.focus_distance = max(0.5, fd)
    return {"dof_fstop": cd.dof.aperture_fstop, "dof_focus_distance": cd.dof.focus_distance}


def build_motionblur(rng, ctx):
    f0 = ctx["frame_start"]
    stage(rng)
    items = scatter(rng, rng.randint(3, 5), (-2.6, 2.6), (-1.8, 1.8), (0.3, 0.7),
                    ["sphere", "cube", "torus", "monkey", "cylinder"])
    moving = []
    for i, (x, y, s, k) in enumerate(items):
        m, _ = random_surface(rng, "Obj%d" % i)
        ob = add_obj(k, (x, y, 0.0), s, rot_z=rng.uniform(0, 2 * math.pi), mat=m, name="Obj%d" % i)
        if i == 0 or rng.random() < 0.6:
            speed = rng.uniform(0.3, 1.2)          # metres per frame
            ang = rng.uniform(0, 2 * math.pi)
            dz = rng.uniform(-0.1, 0.3) * speed
            loc0 = ob.location.copy()
            loc1 = loc0 + Vector((speed * math.cos(ang), speed * math.sin(ang), dz))
            r0 = ob.rotation_euler.copy()
            spin = math.radians(rng.uniform(-60, 60))
            r1 = (r0.x + math.radians(rng.uniform(-30, 30)), r0.y, r0.z + spin)
            animate_linear(ob, f0, f0 + 1, loc0, loc1, tuple(r0), r1)
            moving.append(ob.name)
    key_lights(rng)
    set_world_color(hsv(rng.uniform(0.5, 0.65), rng.uniform(0.0, 0.4), 1.0), rng.uniform(0.1, 0.4))
    cam = stage_camera(rng)
    cam_moves = rng.random() < 0.3
    if cam_moves:
        r0 = cam.rotation_euler.copy()
        r1 = (r0.x + math.radians(rng.uniform(-1, 1)), r0.y,
              r0.z + math.radians(rng.choice([-1, 1]) * rng.uniform(1.0, 3.0)))
        loc = cam.location.copy()
        animate_linear(cam, f0, f0 + 1, loc, loc, tuple(r0), r1)
    sc = bpy.context.scene
    sc.render.use_motion_blur = True
    sc.render.motion_blur_shutter = rng.uniform(0.3, 1.0)
    return {"moving_objects": moving, "camera_moves": cam_moves}


def build_anim(rng, ctx):
    f0, nf = ctx["frame_start"], ctx["frames"]
    f1 = f0 + max(nf - 1, 1)
    span = f1 - f0
    stage(rng)
    items = scatter(rng, rng.randint(3, 6), (-2.6, 2.6), (-1.8, 1.8), (0.3, 0.7),
                    ["sphere", "cube", "torus", "monkey", "cylinder", "cone"])
    moving = []
    for i, (x, y, s, k) in enumerate(items):
        m, _ = random_surface(rng, "Obj%d" % i)
        ob = add_obj(k, (x, y, 0.0), s, rot_z=rng.uniform(0, 2 * math.pi), mat=m, name="Obj%d" % i)
        if i == 0 or rng.random() < 0.5:
            speed = rng.uniform(0.05, 0.25)        # metres per frame
            ang = rng.uniform(0, 2 * math.pi)
            loc0 = ob.location.copy()
            loc1 = loc0 + span * Vector((speed * math.cos(ang), speed * math.sin(ang), 0.0))
            r0 = ob.rotation_euler.copy()
            r1 = (r0.x, r0.y, r0.z + span * math.radians(rng.uniform(-15, 15)))
            animate_linear(ob, f0, f1, loc0, loc1, tuple(r0), r1)
            moving.append(ob.name)
    key_lights(rng)
    set_world_color(hsv(rng.uniform(0.5, 0.65), rng.uniform(0.0, 0.4), 1.0), rng.uniform(0.1, 0.4))
    # camera: orbit + dolly
    target = (rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), 0.5)
    dist0 = rng.uniform(6.0, 8.0)
    ddist = rng.uniform(-0.15, 0.15)               # metres per frame
    az0 = rng.uniform(-30, 30)
    daz = rng.choice([-1, 1]) * rng.uniform(2.0, 6.0)  # degrees per frame
    el = rng.uniform(12, 30)
    lens = rng.uniform(40, 55)
    cam = add_camera(orbit_point(target, dist0, az0, el), target, lens=lens)
    r0 = cam.rotation_euler.copy()
    cam.location = orbit_point(target, dist0 + span * ddist, az0 + span * daz, el)
    look_at(cam, target)
    r1 = cam.rotation_euler.copy()
    animate_linear(cam, f0, f1, orbit_point(target, dist0, az0, el), tuple(cam.location),
                   tuple(r0), tuple(r1))
    return {"moving_objects": moving, "camera_orbit_deg_per_frame": daz}


def build_hdri(rng, ctx):
    stage(rng, back_wall_p=0.0)
    items = scatter(rng, rng.randint(3, 6), (-2.6, 2.6), (-1.8, 1.8), (0.3, 0.8),
                    ["sphere", "torus", "monkey", "cube", "cylinder", "cone"])
    for i, (x, y, s, k) in enumerate(items):
        m, _ = random_surface(rng, "Obj%d" % i, allow_glass=True)
        add_obj(k, (x, y, 0.0), s, rot_z=rng.uniform(0, 2 * math.pi), mat=m, name="Obj%d" % i)
    files = hdri_files()
    extra = {}
    if files and rng.random() < 0.75:
        path = rng.choice(files)
        set_world_hdri(path, rng.uniform(0, 2 * math.pi), 1.0)
        world = "hdri:" + os.path.basename(path)
    else:
        extra.update(set_world_sky(rng, 1.0))
        world = "nishita_sky"
    stage_camera(rng, el=(5.0, 30.0))
    extra["world"] = world
    return extra


# --------------------------------------------------------------------------
# stability families: scenes where denoisers fail.  Added after the
# dataset families, which they leave as they were, so the render cache's scenes
# re-render the same.  (None of these builders makes the shared cycles-train set's
# scenes: that set came from another generator; scenes_simple.py has its look.)


def mat_volume(name, color, density, anisotropy=0.0, absorption=(0.0, 0.0, 0.0),
               rng=None, noise_scale=None):
    """Principled Volume only (no surface: the mesh boundary is invisible).  With
    noise_scale the density is a clipped noise texture (a heterogeneous 'smoke')."""
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nt = m.node_tree
    N, L = nt.nodes, nt.links
    N.remove(N["Principled BSDF"])
    v = N.new("ShaderNodeVolumePrincipled")
    v.inputs["Color"].default_value = (*color, 1.0)
    v.inputs["Density"].default_value = density
    v.inputs["Anisotropy"].default_value = anisotropy
    v.inputs["Absorption Color"].default_value = (*absorption, 1.0)
    if noise_scale is not None:
        tc = N.new("ShaderNodeTexCoord")
        nz = N.new("ShaderNodeTexNoise")
        nz.inputs["Scale"].default_value = noise_scale
        nz.inputs["Detail"].default_value = rng.uniform(2.0, 6.0)
        nz.inputs["Roughness"].default_value = rng.uniform(0.45, 0.65)
        nz.inputs["W"].default_value = rng.uniform(0.0, 10.0)
        nz.noise_dimensions = "4D"
        L.new(tc.outputs["Object"], nz.inputs["Vector"])
        mr = N.new("ShaderNodeMapRange")
        mr.inputs["From Min"].default_value = rng.uniform(0.4, 0.5)
        mr.inputs["From Max"].default_value = rng.uniform(0.6, 0.75)
        mr.inputs["To Min"].default_value = 0.0
        mr.inputs["To Max"].default_value = density
        mr.clamp = True
        L.new(nz.outputs["Fac"], mr.inputs["Value"])
        L.new(mr.outputs["Result"], v.inputs["Density"])
    L.new(v.outputs["Volume"], N["Material Output"].inputs["Volume"])
    return m


def add_box(name, center, size, mat):
    """Axis-aligned box; the size is baked into the mesh."""
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=center)
    ob = bpy.context.active_object
    ob.name = name
    for v in ob.data.vertices:
        v.co.x *= size[0]
        v.co.y *= size[1]
        v.co.z *= size[2]
    assign(ob, mat)
    return ob


def build_volume(rng, ctx):
    W, D, H = build_room(rng, colorful_walls=rng.random() < 0.5)
    # the whole room filled with thin fog (homogeneous: no ray marching) ...
    e = 0.01
    fog_d = rng.uniform(0.08, 0.3)
    aniso = rng.uniform(0.0, 0.6)
    fog_col = hsv(rng.uniform(0.0, 1.0), rng.uniform(0.0, 0.15), 1.0)
    add_box("Fog", (0.0, D / 2, H / 2), (W - 2 * e, D - 2 * e, H - 2 * e),
            mat_volume("Fog", fog_col, fog_d, anisotropy=aniso))
    # ... occluders on the floor, so the spot makes shafts and shadowed fog ...
    items = scatter(rng, rng.randint(2, 3), (-W / 2 + 0.05, W / 2 - 0.05), (0.3, D - 0.05),
                    (0.15, 0.35), ["cube", "tallbox", "sphere", "cylinder"])
    for i, (x, y, s, k) in enumerate(items[1:]):
        if k == "tallbox":
            s = min(s, H / 4.5)
        add_obj(k, (x, y, 0.0), s, rot_z=rng.uniform(0, math.pi / 2),
                mat=mat_diffuse("Obj%d" % i, rand_color(rng, s=(0.0, 0.6), v=(0.4, 0.85))),
                name="Obj%d" % i)
    # ... and a dense heterogeneous smoke blob (coloured absorption) in the first slot
    x, y, s, _ = items[0] if items else (0.0, D / 2, 0.3, "")
    smoke_d = rng.uniform(3.0, 10.0)
    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=3, radius=s * 1.3,
                                          location=(x, y, s * 1.3 + 0.01))
    ob = bpy.context.active_object
    ob.name = "Smoke"
    assign(ob, mat_volume("Smoke", rand_color(rng, s=(0.0, 0.5), v=(0.7, 1.0)), smoke_d,
                          anisotropy=rng.uniform(-0.2, 0.4),
                          absorption=rand_color(rng, s=(0.2, 0.8), v=(0.3, 0.9)),
                          rng=rng, noise_scale=rng.uniform(2.0, 5.0)))
    # a spot under the ceiling aimed at the floor (god rays); the rest is lit by the
    # fog and the walls (no fill lamp: one inside the fog makes nearby fog a firefly source)
    sx, sy = rng.uniform(-0.3, 0.3) * W, rng.uniform(0.3, 0.8) * D
    tgt = (x + rng.uniform(-0.2, 0.2), y + rng.uniform(-0.2, 0.2), 0.0)  # through the smoke
    spot_deg = rng.uniform(25.0, 50.0)
    add_light("SPOT", "Spot", (sx, sy, H - 0.1), energy=400.0, size=rng.uniform(0.01, 0.08),
              target=tgt, spot_size=math.radians(spot_deg), spot_blend=rng.uniform(0.05, 0.3),
              color=hsv(rng.uniform(0.05, 0.15), rng.uniform(0.0, 0.3), 1.0))
    sc = bpy.context.scene
    sc.cycles.volume_bounces = 2
    set_world_color((1.0, 1.0, 1.0), 0.03)
    room_camera(rng, W, D, H, ctx)
    return {"volume_fog_density": fog_d, "volume_fog_anisotropy": aniso,
            "volume_smoke_density": smoke_d, "volume_spot_deg": spot_deg,
            "volume_bounces": sc.cycles.volume_bounces}


def mat_fine(name, rng, kind, scale, bump):
    """High-contrast procedural texture at a fine scale, optionally also as a bump map
    (high-frequency normals as well as albedo)."""
    c1 = rand_color(rng, s=(0.0, 0.7), v=(0.65, 0.95))
    c2 = rand_color(rng, s=(0.0, 0.7), v=(0.02, 0.2))
    m = mat_principled(name, c1, rough=rng.uniform(0.3, 0.7), spec=0.5, rng=rng,
                       tex=(c2, scale, kind))
    if bump > 0.0:
        nt = m.node_tree
        p = nt.nodes["Principled BSDF"]
        tex = next(n for n in nt.nodes if n.bl_idname.startswith("ShaderNodeTex")
                   and n.bl_idname != "ShaderNodeTexCoord")
        # the height is the texture's scalar output: Voronoi names it Distance
        fac = tex.outputs["Fac" if "Fac" in tex.outputs else "Distance"]
        b = nt.nodes.new("ShaderNodeBump")
        b.inputs["Strength"].default_value = bump
        b.inputs["Distance"].default_value = 0.02
        nt.links.new(fac, b.inputs["Height"])
        nt.links.new(b.outputs["Normal"], p.inputs["Normal"])
    return m


def build_texture(rng, ctx):
    # a floor checker fine enough to alias towards the horizon, stripes or bricks on
    # a back wall, objects with textures of a few millimetres, some also as bump
    add_plane("Floor", (0, 0, 0), (0, 0, 0), 60.0, 60.0,
              mat_fine("Floor", rng, "checker", rng.uniform(4.0, 12.0), 0.0))
    y = rng.uniform(3.0, 5.0)
    add_plane("BackWall", (0, y, 15.0), (math.pi / 2, 0, 0), 60.0, 30.0,
              mat_fine("BackWall", rng, rng.choice(["wave", "brick", "checker"]),
                       rng.uniform(10.0, 30.0), 0.0))
    items = scatter(rng, rng.randint(3, 5), (-2.4, 2.4), (-1.6, 1.6), (0.35, 0.8),
                    ["sphere", "cube", "cylinder", "torus", "monkey"])
    kinds = []
    for i, (x, y0, s, k) in enumerate(items):
        tk = rng.choice(TEX_KINDS)
        kinds.append(tk)
        m = mat_fine("Obj%d" % i, rng, tk, rng.uniform(20.0, 80.0),
                     rng.uniform(0.2, 0.8) if rng.random() < 0.5 else 0.0)
        add_obj(k, (x, y0, 0.0), s, rot_z=rng.uniform(0, 2 * math.pi), mat=m, name="Obj%d" % i)
    key_lights(rng)
    set_world_color(hsv(rng.uniform(0.5, 0.65), rng.uniform(0.0, 0.4), 1.0), rng.uniform(0.1, 0.4))
    stage_camera(rng, el=(8.0, 25.0))
    return {"texture_kinds": kinds}


def mesh_object(name, verts, faces, mat):
    """A linked object of a mesh built from vertices and faces, with material mat."""
    me = bpy.data.meshes.new(name)
    me.from_pydata(verts, [], faces)
    me.update()
    ob = link(bpy.data.objects.new(name, me))
    assign(ob, mat)
    return ob


def add_segments(name, segs, mat):
    """One mesh of thin square-section beams; segs = [(p0, p1, radius), ...]."""
    verts, faces = [], []
    for p0, p1, r in segs:
        a, b = Vector(p0), Vector(p1)
        d = (b - a).normalized()
        u = d.cross(Vector((0.0, 0.0, 1.0)) if abs(d.z) < 0.9 else Vector((1.0, 0.0, 0.0)))
        u.normalize()
        v = d.cross(u)
        base = len(verts)
        for end in (a, b):
            for su, sv in ((1, 1), (-1, 1), (-1, -1), (1, -1)):
                verts.append(tuple(end + r * (su * u + sv * v)))
        faces += [(base + i, base + (i + 1) % 4, base + 4 + (i + 1) % 4, base + 4 + i)
                  for i in range(4)]
        faces += [(base + 3, base + 2, base + 1, base), (base + 4, base + 5, base + 6, base + 7)]
    return mesh_object(name, verts, faces, mat)


def add_blades(name, blades, mat):
    """Grass: one triangle per blade; blades = [(base xyz, tip xyz, half width), ...]."""
    verts, faces = [], []
    for base, tip, hw in blades:
        bx, by, bz = base
        ang = math.atan2(tip[1] - by, tip[0] - bx) + math.pi / 2
        dx, dy = hw * math.cos(ang), hw * math.sin(ang)
        k = len(verts)
        verts += [(bx - dx, by - dy, bz), (bx + dx, by + dy, bz), tuple(tip)]
        faces.append((k, k + 1, k + 2))
    return mesh_object(name, verts, faces, mat)


def build_thin(rng, ctx):
    # dark soil, a plain light back wall: thin things against a smooth background are
    # what a denoiser erases
    add_plane("Floor", (0, 0, 0), (0, 0, 0), 60.0, 60.0,
              mat_diffuse("Floor", rand_color(rng, s=(0.2, 0.6), v=(0.08, 0.2)), rng=rng,
                          tex=(rand_color(rng, s=(0.2, 0.6), v=(0.05, 0.15)), rng.uniform(1, 4),
                               "noise")))
    wall_y = rng.uniform(2.5, 4.0)
    add_plane("BackWall", (0, wall_y, 15.0), (math.pi / 2, 0, 0), 60.0, 30.0,
              mat_diffuse("BackWall", rand_color(rng, s=(0.0, 0.4), v=(0.6, 0.85))))
    # a few ordinary objects behind the fence
    for i, (x, y, s, k) in enumerate(scatter(rng, rng.randint(1, 3), (-2.0, 2.0), (0.2, 2.0),
                                             (0.3, 0.6), ["sphere", "cube", "cylinder", "monkey"])):
        m, _ = random_surface(rng, "Obj%d" % i, allow_metal=False)
        add_obj(k, (x, y, 0.0), s, rot_z=rng.uniform(0, 2 * math.pi), mat=m, name="Obj%d" % i)
    # a wire fence (a grid of beams) between the camera and the scene, slightly turned
    fy = rng.uniform(-1.8, -0.8)
    spacing = rng.uniform(0.12, 0.3)
    wire_r = rng.uniform(0.004, 0.012)
    turn = math.radians(rng.uniform(-25.0, 25.0))
    ct, st = math.cos(turn), math.sin(turn)

    def fence_pt(u, z):
        return (u * ct, fy + u * st, z)
    half, top = 6.0, 3.2
    segs = []
    n_u = int(2 * half / spacing)
    for j in range(n_u + 1):
        u = -half + j * spacing
        segs.append((fence_pt(u, 0.0), fence_pt(u, top), wire_r))
    for j in range(int(top / spacing) + 1):
        z = 0.02 + j * spacing
        segs.append((fence_pt(-half, z), fence_pt(half, z), wire_r))
    fence_metal = rng.random() < 0.5
    fence_mat = (mat_principled("Fence", metal_color(rng), rough=rng.uniform(0.2, 0.5), metal=1.0)
                 if fence_metal else mat_diffuse("Fence", rand_color(rng, v=(0.02, 0.15))))
    add_segments("Fence", segs, fence_mat)
    # loose wires across the view, between the fence and the wall
    wires = []
    for _ in range(rng.randint(3, 6)):
        y0, z0 = rng.uniform(fy + 0.3, wall_y - 0.3), rng.uniform(0.3, 2.5)
        wires.append(((-8.0, y0 + rng.uniform(-0.5, 0.5), z0),
                      (8.0, y0 + rng.uniform(-0.5, 0.5), z0 + rng.uniform(-1.2, 1.2)),
                      rng.uniform(0.002, 0.006)))
    add_segments("Wires", wires, mat_diffuse("Wires", rand_color(rng, v=(0.02, 0.3))))
    # grass: a patch of thin blades on both sides of the fence
    blades = []
    for _ in range(rng.randint(300, 600)):
        bx, by = rng.uniform(-3.5, 3.5), rng.uniform(fy - 1.0, fy + 2.0)
        hgt = rng.uniform(0.1, 0.45)
        lean = rng.uniform(0.0, 0.5) * hgt
        a = rng.uniform(0, 2 * math.pi)
        blades.append(((bx, by, 0.0), (bx + lean * math.cos(a), by + lean * math.sin(a), hgt),
                       rng.uniform(0.002, 0.006)))
    g = hsv(rng.uniform(0.2, 0.35), rng.uniform(0.5, 0.9), rng.uniform(0.5, 0.85))
    add_blades("Grass", blades, mat_diffuse("Grass", g))
    sun_dir = orbit_point((0, 0, 0), 1.0, rng.uniform(-150, 150), rng.uniform(20, 60))
    add_light("SUN", "Sun", sun_dir, energy=3.0, size=math.radians(rng.uniform(0.5, 3.0)),
              target=(0, 0, 0), color=hsv(rng.uniform(0.06, 0.12), rng.uniform(0.0, 0.3), 1.0))
    set_world_color(hsv(rng.uniform(0.55, 0.62), rng.uniform(0.2, 0.6), 1.0), rng.uniform(0.3, 1.0))
    stage_camera(rng, target=(0.0, 0.5, 0.6), dist=(6.0, 8.0), el=(5.0, 18.0), az=25.0)
    return {"thin_fence_spacing": spacing, "thin_wire_radius": wire_r,
            "thin_fence_metal": fence_metal, "thin_blades": len(blades)}


BUILDERS = {
    "cornell": build_cornell, "glossy": build_glossy, "glass": build_glass,
    "firefly": build_firefly, "dof": build_dof, "motionblur": build_motionblur,
    "anim": build_anim, "hdri": build_hdri,
    "volume": build_volume, "texture": build_texture, "thin": build_thin,
}


# --------------------------------------------------------------------------
# render settings, auto-exposure, rendering


def configure_render(sc, family, args, frames):
    sc.render.engine = "CYCLES"
    r = sc.render
    r.resolution_x = args.width
    r.resolution_y = args.height
    r.resolution_percentage = 100
    r.pixel_aspect_x = r.pixel_aspect_y = 1.0
    r.film_transparent = False
    r.use_border = False
    r.use_persistent_data = False
    r.threads_mode = "FIXED" if args.threads else "AUTO"
    if args.threads:
        r.threads = args.threads
    sc.frame_start = args.frame_start
    sc.frame_end = args.frame_start + frames - 1
    if family != "motionblur":
        r.use_motion_blur = False
    c = sc.cycles
    c.device = "CPU"
    c.feature_set = "SUPPORTED"
    c.use_denoising = False
    c.use_preview_denoising = False
    c.use_adaptive_sampling = False
    c.sampling_pattern = "PROGRESSIVE_MULTI_JITTER"
    c.use_animated_seed = False
    c.time_limit = 0.0
    c.max_bounces = 12
    c.diffuse_bounces = 4
    c.glossy_bounces = 4
    c.transmission_bounces = 12
    c.volume_bounces = 0
    c.transparent_max_bounces = 8
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0 if family == "firefly" else 10.0
    # firefly: no Filter Glossy either, so caustic paths keep their raw variance
    c.blur_glossy = 0.0 if family == "firefly" else 1.0
    c.caustics_reflective = True
    c.caustics_refractive = True
    c.motion_blur_position = "CENTER"
    c.pixel_filter_type = "BLACKMAN_HARRIS"
    c.filter_width = 1.5
    c.film_exposure = 1.0
    vs = sc.view_settings
    vs.view_transform = "Standard"
    vs.look = "None"
    vs.exposure = 0.0
    vs.gamma = 1.0
    for vl in sc.view_layers:
        vl.cycles.use_denoising = False
    vl = sc.view_layers["ViewLayer"] if "ViewLayer" in sc.view_layers else sc.view_layers[0]
    vl.name = "ViewLayer"
    for other in list(sc.view_layers):
        other.use = other == vl
    return vl


def set_passes(vl, noisy, vector):
    vl.use_pass_combined = True
    vl.use_pass_z = noisy
    vl.use_pass_normal = noisy
    vl.use_pass_vector = noisy and vector
    vl.use_pass_mist = False
    vl.use_pass_diffuse_color = False
    vl.use_pass_glossy_color = False
    vl.cycles.denoising_store_passes = noisy


def set_output_format(sc, multilayer_half):
    im = sc.render.image_settings
    if multilayer_half:
        im.file_format = "OPEN_EXR_MULTILAYER"
        im.color_depth = "16"
    else:
        im.file_format = "OPEN_EXR"
        im.color_depth = "32"
    im.exr_codec = "ZIP"
    im.use_preview = False


class QuietStdout:
    """Silence Blender's per-sample render log (C-level stdout) unless verbose."""

    def __init__(self, enabled):
        self.enabled = enabled
        self.saved = None

    def __enter__(self):
        if self.enabled:
            sys.stdout.flush()
            self.saved = os.dup(1)
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, 1)
            os.close(devnull)
        return self

    def __exit__(self, *exc):
        if self.saved is not None:
            sys.stdout.flush()
            os.dup2(self.saved, 1)
            os.close(self.saved)
            self.saved = None
        return False


def do_render(quiet):
    with QuietStdout(quiet):
        res = bpy.ops.render.render(write_still=False)
    if "FINISHED" not in res:
        raise RuntimeError("render did not finish: %r" % (res,))


def scale_lights(s):
    for ld in bpy.data.lights:
        ld.energy *= s
    for w in bpy.data.worlds:
        if w.use_nodes:
            for n in w.node_tree.nodes:
                if n.type == "BACKGROUND":
                    n.inputs["Strength"].default_value *= s
    for m in bpy.data.materials:
        if m.use_nodes:
            for n in m.node_tree.nodes:
                if n.type == "EMISSION":
                    n.inputs["Strength"].default_value *= s


PREVIEW_CLIP_REL = 100.0


def preview_mean(sc, vl, args, tmpdir, quiet, seed):
    """Render a small Combined-only preview; return (robust mean luminance, max, size)."""
    import numpy as np
    r = sc.render
    saved = (r.resolution_x, r.resolution_y, sc.cycles.samples, sc.cycles.seed)
    pw = max(16, args.width // 4)
    ph = max(16, args.height // 4)
    r.resolution_x, r.resolution_y = pw, ph
    sc.cycles.samples = args.preview_spp
    sc.cycles.seed = seed
    set_passes(vl, noisy=False, vector=False)
    set_output_format(sc, multilayer_half=False)
    path = os.path.join(tmpdir, "preview.exr")
    try:
        do_render(quiet)
        bpy.data.images["Render Result"].save_render(filepath=path, scene=sc)
        img = bpy.data.images.load(path)
        try:
            a = np.empty(img.size[0] * img.size[1] * img.channels, dtype=np.float32)
            img.pixels.foreach_get(a)
            rgb = a.reshape(-1, img.channels)[:, :3].astype(np.float64)
        finally:
            bpy.data.images.remove(img)
    finally:
        r.resolution_x, r.resolution_y, sc.cycles.samples, sc.cycles.seed = saved
        if os.path.exists(path):
            os.remove(path)
    rgb = np.nan_to_num(rgb, nan=0.0, posinf=1e9, neginf=0.0).clip(0.0, 1e9)
    lum = rgb @ np.array([0.2126, 0.7152, 0.0722])
    # Robust mean: a pixel counts as at most PREVIEW_CLIP_REL * target, so a visible sun
    # disc, a specular highlight of it or a few fireflies in a small preview do not set
    # the exposure of the whole scene.  (Exact once the scale has converged.)  The simple
    # style takes the plain mean, as the shared set's generator did (scenes_simple.py).
    cap = PREVIEW_CLIP_REL * args.target_mean if args.style == "busy" else float("inf")
    return float(np.minimum(lum, cap).mean()), float(lum.max()), (pw, ph)


def autoexpose(sc, vl, args, tmpdir, quiet, seed_rng):
    """Scale every emitter (lamps, emission shaders, world) so the preview's robust mean
    luminance hits the target.  Repeats the preview (at most 3 in all) while the
    correction is beyond +-25 %: sample clamping and the clipped mean are not linear in
    the light strength.  The simple style renders one preview, as the shared set's
    generator did."""
    total = 1.0
    steps = []
    size = None
    for it in range(3 if args.style == "busy" else 1):
        m, mx, size = preview_mean(sc, vl, args, tmpdir, quiet, seed_rng.randrange(2**31 - 1))
        if not (m > 1e-8 and math.isfinite(m)):
            raise RuntimeError("auto-exposure preview rendered black (mean %r)" % m)
        s = args.target_mean / m
        steps.append({"light_scale_before": total, "mean_lum": m, "max_lum": mx})
        scale_lights(s)
        total *= s
        log("autoexpose: preview %dx%d %d spp mean luminance %.4g (max %.4g) -> light scale x%.4g"
            % (size[0], size[1], args.preview_spp, m, mx, s))
        if abs(math.log(s)) < math.log(1.25):
            break
    return {"preview_mean_lum": steps[0]["mean_lum"], "light_scale": total,
            "target_mean_lum": args.target_mean, "preview_size": list(size),
            "preview_spp": args.preview_spp, "preview_clip_lum": PREVIEW_CLIP_REL * args.target_mean if args.style == "busy" else None,
            "previews": steps}


def render_seed(family, seed, frame, kind, spp):
    return random.Random("cycles:%s:%d:%d:%s:%d" % (family, seed, frame, kind, spp)) \
        .randrange(1, 2**31 - 1)


def render_one(sc, vl, out_dir, fname, spp, cseed, noisy, vector, quiet):
    sc.cycles.samples = spp
    sc.cycles.seed = cseed
    set_passes(vl, noisy=noisy, vector=vector)
    set_output_format(sc, multilayer_half=True)
    final = os.path.join(out_dir, fname)
    tmp = os.path.join(out_dir, ".%s.tmp-%d.exr" % (fname[:-4], os.getpid()))
    load0 = os.getloadavg()[0]
    t0, c0 = time.time(), time.process_time()
    do_render(quiet)
    t1, c1 = time.time(), time.process_time()
    try:
        bpy.data.images["Render Result"].save_render(filepath=tmp, scene=sc)
        if not os.path.isfile(tmp) or os.path.getsize(tmp) == 0:
            raise RuntimeError("Blender did not write %s" % tmp)
        os.replace(tmp, final)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
    t2 = time.time()
    return {"render_s": round(t1 - t0, 3), "save_s": round(t2 - t1, 3),
            "render_cpu_s": round(c1 - c0, 3), "loadavg_1m": load0,
            "bytes": os.path.getsize(final)}


def write_json_atomic(path, obj):
    tmp = "%s.tmp-%d" % (path, os.getpid())
    try:
        with open(tmp, "w") as f:
            json.dump(obj, f, indent=1)
            f.write("\n")
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


def run(args):
    family = args.family
    letter = FAMILIES[family][0]
    frames = args.frames if args.frames is not None else (4 if family == "anim" else 1)
    out_dir = os.path.abspath(args.out)
    check_out_dir(out_dir)
    quiet = not args.verbose
    t_start = time.time()
    log("family=%s seed=%d %dx%d frames=%d spp=%s ref=%s -> %s"
        % (family, args.seed, args.width, args.height, frames,
           ",".join(map(str, args.spp)), args.ref_spp or "none", out_dir))

    sc = bpy.context.scene
    clear_scene()
    vl = configure_render(sc, family, args, frames)
    rng = random.Random(args.seed)
    ctx = {"width": args.width, "height": args.height,
           "frame_start": args.frame_start, "frames": frames}
    sc.frame_set(args.frame_start)
    if args.style == "simple":
        sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # not there under Blender
        import scenes_simple
        builders = scenes_simple.BUILDERS
        if family not in builders:
            raise UsageError("--style simple has the families %s" % ", ".join(builders))
    else:
        builders = BUILDERS
    extra = builders[family](rng, ctx) or {}
    world = extra.pop("world", None)
    vector = family != "motionblur"
    n_obj = len([o for o in sc.objects if o.type == "MESH"])
    log("built scene: %d meshes, %d lights, world=%s (%.1f s)"
        % (n_obj, len([o for o in sc.objects if o.type == "LIGHT"]), world,
           time.time() - t_start))

    tmpdir = tempfile.mkdtemp(prefix=".autoexpose-", dir=out_dir)
    try:
        sc.frame_set(args.frame_start)
        if args.no_autoexpose:
            ae = None
        else:
            ae = autoexpose(sc, vl, args, tmpdir, quiet,
                            random.Random("preview:%s:%d" % (family, args.seed)))
    finally:
        shutil.rmtree(tmpdir, ignore_errors=True)

    if args.save_blend:
        bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(args.save_blend), copy=True)
        log("saved %s" % args.save_blend)

    c = sc.cycles
    meta = {
        "family": letter,
        "family_name": family,
        "style": args.style,
        "variant_seed": args.seed,
        "width": args.width,
        "height": args.height,
        "frame_start": args.frame_start,
        "frames": frames,
        "blender": bpy.app.version_string,
        "world": world,
        "cycles": {
            "sampling_pattern": c.sampling_pattern,
            "max_bounces": c.max_bounces,
            "diffuse_bounces": c.diffuse_bounces,
            "glossy_bounces": c.glossy_bounces,
            "transmission_bounces": c.transmission_bounces,
            "transparent_max_bounces": c.transparent_max_bounces,
            "sample_clamp_direct": c.sample_clamp_direct,
            "sample_clamp_indirect": c.sample_clamp_indirect,
            "blur_glossy": c.blur_glossy,
            "caustics_reflective": c.caustics_reflective,
            "caustics_refractive": c.caustics_refractive,
            "use_adaptive_sampling": c.use_adaptive_sampling,
            "use_denoising": c.use_denoising,
            "motion_blur_position": c.motion_blur_position,
        },
        "pixel_filter": "%s %.2fpx" % (c.pixel_filter_type, c.filter_width),
        "motion_blur": bool(sc.render.use_motion_blur),
        "motion_blur_shutter": sc.render.motion_blur_shutter if sc.render.use_motion_blur else None,
        "dof": bool(sc.camera.data.dof.use_dof),
        "input_depth": "16",
        "ref_depth": "16",
        "codec": "ZIP",
        "renders": [],
    }
    meta.update(extra)
    meta["autoexpose"] = ae
    meta["generator"] = {
        "script": "tools/blender/render_scene.py",
        "argv": script_argv(),
        "vector_pass": vector,
    }

    dir_name = os.path.basename(out_dir.rstrip(os.sep))
    jobs = []
    for f in range(args.frame_start, args.frame_start + frames):
        for spp in args.spp:
            jobs.append((f, "noisy", spp, "f%04d_spp%04d.exr" % (f, spp)))
        if args.ref_spp:
            jobs.append((f, "ref", args.ref_spp, "f%04d_ref%04d.exr" % (f, args.ref_spp)))
    for i, (f, kind, spp, fname) in enumerate(jobs):
        sc.frame_set(f)
        cseed = render_seed(family, args.seed, f, kind, spp)
        log("[%d/%d] frame %d %s %d spp (cycles seed %d) ..." % (i + 1, len(jobs), f, kind,
                                                                   spp, cseed))
        st = render_one(sc, vl, out_dir, fname, spp, cseed, kind == "noisy", vector, quiet)
        log("[%d/%d] wrote %s: render %.2f s (cpu %.2f s), save %.2f s, %d bytes"
            % (i + 1, len(jobs), fname, st["render_s"], st["render_cpu_s"], st["save_s"],
               st["bytes"]))
        rec = {"file": "%s/%s" % (dir_name, fname), "frame": f, "spp": spp, "kind": kind,
               "cycles_seed": cseed, "bit_depth": "16"}
        rec.update(st)
        meta["renders"].append(rec)

    write_json_atomic(os.path.join(out_dir, "meta.json"), meta)
    log("done: %d renders + meta.json in %.1f s" % (len(jobs), time.time() - t_start))


def main():
    parser = build_parser()
    try:
        args = parser.parse_args(script_argv())
    except SystemExit as e:  # argparse: --help (0) or usage error (2)
        sys.stdout.flush()
        sys.stderr.flush()
        sys.exit(e.code)
    if bpy is None:
        sys.stderr.write("%s: must run inside Blender: %s\n" % (PROG, USAGE))
        sys.exit(2)
    try:
        run(args)
    except UsageError as e:
        sys.stderr.write("%s: error: %s\n" % (PROG, e))
        sys.stderr.flush()
        sys.exit(2)
    except Exception:
        traceback.print_exc()
        sys.stderr.write("%s: error: rendering failed (see traceback above)\n" % PROG)
        sys.stderr.flush()
        sys.exit(1)
    sys.stdout.flush()
    sys.stderr.flush()
    sys.exit(0)


if __name__ == "__main__":
    main()
