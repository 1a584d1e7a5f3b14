# tools/blender/render_tile.py - render a tile exported by
# `loom export --format vdb` in Blender's Cycles, headless:
#
#   blender -b --factory-startup --python-exit-code 1 \
#       -P tools/blender/render_tile.py -- TILE.vdb [more tiles] -o OUT.png \
#       [--samples N] [--size W,H] [--threads N] [--density K]
#       [--camera top | --camera persp --eye X,Y,Z --target X,Y,Z --fov DEG]
#       [--ortho X0,Y0,X1,Y1] [--sun AZ,EL[,INTENSITY[,ANGLE]]]
#       [--background G] [--bounces N] [--json FILE]
#
# Scene, in loom's conventions (docs/rendering.md, docs/interop.md):
# millimetres (the grids' transforms), z up, the cloth in the x-y plane.
#   - the tiles' `density` grid times --density K (extinction per mm, as
#     `loom render --density-scale`, default 80) through a Principled Volume
#     whose colour is the `color` grid (loom's albedo; white when absent),
#     no extra absorption, isotropic phase;
#   - a sun at azimuth AZ, elevation EL (degrees, measured as loom's camera
#     angles: towards the light is (-sin AZ cos EL, -cos AZ cos EL, sin EL)),
#     irradiance INTENSITY (default 2.6) and disc ANGLE (default 0.53 deg);
#   - a constant grey world --background G (default 0.18), as loom's;
#   - camera `top` (default): orthographic from straight above, framing
#     --ortho X0,Y0,X1,Y1 mm (default: the tiles' bounding box), image up
#     = +y; or `persp`: a pinhole at --eye looking at --target (mm), up +z,
#     vertical field of view --fov (loom render's --fov);
#   - Cycles on the CPU, --samples per pixel (no adaptive sampling, no
#     denoising), --threads (default 2), up to --bounces (default 32, loom's
#     path depth), Standard view transform (linear -> sRGB, as loom's PNGs).
# --json FILE writes the seconds the render took (without loading the
# scene) and the scene's figures.
import json
import math
import sys
import time

import bpy
from mathutils import Vector


def fail(msg):
    print("render_tile.py: " + msg, file=sys.stderr)
    sys.exit(2)


def floats(text, n_min, n_max, what):
    try:
        v = [float(s) for s in text.split(",")]
    except ValueError:
        fail("%s: expected numbers separated by commas, got '%s'" % (what, text))
    if not n_min <= len(v) <= n_max:
        fail("%s: expected %d to %d numbers, got '%s'" % (what, n_min, n_max, text))
    return v


def parse(argv):
    a = {"tiles": [], "out": None, "samples": 16, "size": (320, 240), "threads": 2,
         "density": 80.0, "camera": "top", "eye": None, "target": None, "fov": 30.0,
         "ortho": None, "sun": [150.0, 35.0, 2.6, 0.53], "background": 0.18,
         "bounces": 32, "json": None}
    i = 0
    while i < len(argv):
        o = argv[i]
        if not o.startswith("-"):
            a["tiles"].append(o)
            i += 1
            continue
        if i + 1 >= len(argv):
            fail("%s needs a value" % o)
        v = argv[i + 1]
        i += 2
        if o in ("-o", "--output"):
            a["out"] = v
        elif o == "--samples":
            a["samples"] = int(v)
        elif o == "--size":
            w, h = floats(v, 2, 2, o)
            a["size"] = (int(w), int(h))
        elif o == "--threads":
            a["threads"] = int(v)
        elif o == "--density":
            a["density"] = float(v)
        elif o == "--camera":
            if v not in ("top", "persp"):
                fail("--camera: top or persp, got '%s'" % v)
            a["camera"] = v
        elif o == "--eye":
            a["eye"] = floats(v, 3, 3, o)
        elif o == "--target":
            a["target"] = floats(v, 3, 3, o)
        elif o == "--fov":
            a["fov"] = float(v)
        elif o == "--ortho":
            a["ortho"] = floats(v, 4, 4, o)
        elif o == "--sun":
            s = floats(v, 2, 4, o)
            a["sun"] = s + [2.6, 0.53][len(s) - 2:]
        elif o == "--background":
            a["background"] = float(v)
        elif o == "--bounces":
            a["bounces"] = int(v)
        elif o == "--json":
            a["json"] = v
        else:
            fail("unknown option %s" % o)
    if not a["tiles"]:
        fail("no tile given (TILE.vdb after --)")
    if not a["out"]:
        fail("missing -o OUT.png")
    if a["camera"] == "persp" and (a["eye"] is None or a["target"] is None):
        fail("--camera persp needs --eye and --target")
    if a["samples"] < 1 or a["threads"] < 1 or min(a["size"]) < 1:
        fail("--samples, --threads and --size must be positive")
    return a


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    a = parse(argv)
    t_start = time.time()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene

    # the tiles, one volume object each, sharing one material
    mat = bpy.data.materials.new("loom_cloth")
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    pv = nt.nodes.new("ShaderNodeVolumePrincipled")
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(pv.outputs["Volume"], out.inputs["Volume"])
    pv.inputs["Color"].default_value = (1, 1, 1, 1)
    pv.inputs["Density"].default_value = a["density"]
    pv.inputs["Density Attribute"].default_value = "density"
    pv.inputs["Anisotropy"].default_value = 0.0
    pv.inputs["Absorption Color"].default_value = (0, 0, 0, 1)
    lo = [math.inf] * 3
    hi = [-math.inf] * 3
    has_color = True
    for k, path in enumerate(a["tiles"]):
        vol = bpy.data.volumes.new("tile%d" % k)
        vol.filepath = path
        if not vol.grids.load():
            fail("%s: Blender cannot read it: %s" % (path, vol.grids.error_message))
        names = [g.name for g in vol.grids]
        if "density" not in names:
            fail("%s: no 'density' grid (export with --channels density,albedo)" % path)
        has_color = has_color and "color" in names
        ob = bpy.data.objects.new("tile%d" % k, vol)
        scene.collection.objects.link(ob)
        ob.data.materials.append(mat)
        for c in ob.bound_box:
            for q in range(3):
                lo[q] = min(lo[q], c[q])
                hi[q] = max(hi[q], c[q])
    if has_color:
        pv.inputs["Color Attribute"].default_value = "color"

    # world: constant grey, loom's environment
    world = bpy.data.worlds.new("loom_env")
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    g = a["background"]
    bg.inputs["Color"].default_value = (g, g, g, 1)
    bg.inputs["Strength"].default_value = 1.0
    scene.world = world

    # the sun: its light travels along -dir, Blender's sun shines along its -Z
    az, el, inten, ang = [math.radians(a["sun"][0]), math.radians(a["sun"][1]),
                          a["sun"][2], math.radians(a["sun"][3])]
    to_light = Vector((-math.sin(az) * math.cos(el), -math.cos(az) * math.cos(el),
                       math.sin(el)))
    sun = bpy.data.lights.new("sun", "SUN")
    sun.energy = inten
    sun.angle = ang
    sob = bpy.data.objects.new("sun", sun)
    sob.rotation_mode = "QUATERNION"
    sob.rotation_quaternion = to_light.to_track_quat("Z", "Y")
    scene.collection.objects.link(sob)

    # camera
    cam = bpy.data.cameras.new("camera")
    cob = bpy.data.objects.new("camera", cam)
    scene.collection.objects.link(cob)
    scene.camera = cob
    w, h = a["size"]
    cam.clip_start = 1e-3
    cam.clip_end = 1e5
    cob.rotation_mode = "QUATERNION"
    if a["camera"] == "top":
        x0, y0, x1, y1 = a["ortho"] or [lo[0], lo[1], hi[0], hi[1]]
        cam.type = "ORTHO"
        cam.sensor_fit = "HORIZONTAL" if (x1 - x0) * h >= (y1 - y0) * w else "VERTICAL"
        cam.ortho_scale = max(x1 - x0, (y1 - y0) * w / h) if cam.sensor_fit == "HORIZONTAL" \
            else (y1 - y0)
        cob.location = (0.5 * (x0 + x1), 0.5 * (y0 + y1), hi[2] + 1.0)
        cob.rotation_quaternion = (1, 0, 0, 0)
    else:
        eye, target = Vector(a["eye"]), Vector(a["target"])
        cam.type = "PERSP"
        cam.sensor_fit = "VERTICAL"
        cam.angle_y = math.radians(a["fov"])
        cob.location = eye
        cob.rotation_quaternion = (target - eye).to_track_quat("-Z", "Y")

    # Cycles on the CPU, fixed samples and threads, linear -> sRGB
    r = scene.render
    r.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = a["samples"]
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = False
    scene.cycles.max_bounces = a["bounces"]
    scene.cycles.volume_bounces = a["bounces"]
    scene.cycles.transparent_max_bounces = a["bounces"]
    scene.cycles.seed = 1
    r.threads_mode = "FIXED"
    r.threads = a["threads"]
    r.resolution_x, r.resolution_y = w, h
    r.resolution_percentage = 100
    r.film_transparent = False
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    r.image_settings.file_format = "PNG"
    r.image_settings.color_mode = "RGB"
    r.image_settings.color_depth = "8"
    r.filepath = a["out"]
    t_load = time.time() - t_start
    t0 = time.time()
    bpy.ops.render.render(write_still=True)
    secs = time.time() - t0
    print("render_tile.py: %s: %dx%d, %d samples, %d threads, %.3f s" %
          (a["out"], w, h, a["samples"], a["threads"], secs))
    if a["json"]:
        with open(a["json"], "w") as f:
            json.dump({"output": a["out"], "width": w, "height": h, "samples": a["samples"],
                       "threads": a["threads"], "seconds": secs, "load_seconds": t_load,
                       "bbox_mm": [lo, hi], "color_grid": has_color,
                       "blender": bpy.app.version_string}, f, indent=1)


main()
