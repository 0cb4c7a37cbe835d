# Renders a glTF file (nbtf export-gltf's material.gltf, or any) headless with Blender's Cycles,
# in the scene conventions of `nbtf render` (world +y up, the light and camera given as nbtf
# render takes them), so the two renderers can be compared pixel by pixel:
#
#   blender -b -noaudio --python scripts/blender_render_gltf.py -- material.gltf out.exr \
#       [--node plane] [--size 64x64] [--camera EX,EY,EZ,TX,TY,TZ,FOV] [--light THETA,PHI]
#       [--sun S] [--samples N] [--info info.json]
#
# --sun defaults to the material's extras.nbtf.exposure (the sun strength that reproduces the
# BTF's values). The world is black (nbtf render --env 0); only --node is shown. The EXR holds
# linear radiance (view transform Standard). --info writes what the importer built (the
# Principled BSDF's distribution and inputs), so a comparison can say what it compared.
import json
import math
import sys

import numpy
import bpy
import mathutils

if not hasattr(numpy, "bool"):  # Blender 3.4's glTF importer still uses numpy.bool (gone in numpy 1.24)
    numpy.bool = bool


def parse(argv):
    args = {"node": "plane", "size": "64x64", "camera": "0,2.3,2.4,0,0,0.1,45", "light": "45,300", "sun": None,
            "samples": "64", "info": None}
    pos = []
    i = 0
    while i < len(argv):
        a = argv[i]
        if a.startswith("--"):
            args[a[2:]] = argv[i + 1]
            i += 2
        else:
            pos.append(a)
            i += 1
    if len(pos) != 2:
        raise SystemExit("usage: blender -b -noaudio --python blender_render_gltf.py -- IN.gltf OUT.exr [options]")
    return pos[0], pos[1], args


def to_blender(x, y, z):  # glTF / nbtf render (+y up) -> Blender (+z up), as the importer maps them
    return mathutils.Vector((x, -z, y))


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    gltf, out, a = parse(argv)
    with open(gltf) as f:
        doc = json.load(f)
    exposure = doc["materials"][0].get("extras", {}).get("nbtf", {}).get("exposure", 1.0)
    sun = float(a["sun"]) if a["sun"] is not None else exposure

    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=gltf)
    sc = bpy.context.scene
    for obj in list(sc.objects):
        if obj.type == "MESH" and obj.name != a["node"]:
            bpy.data.objects.remove(obj, do_unlink=True)

    w, h = (int(v) for v in a["size"].split("x"))
    ex, ey, ez, tx, ty, tz, fov = (float(v) for v in a["camera"].split(","))
    cam = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    sc.collection.objects.link(cam)
    cam.data.sensor_fit = "VERTICAL"
    cam.data.angle_y = math.radians(fov)
    eye, target = to_blender(ex, ey, ez), to_blender(tx, ty, tz)
    cam.location = eye
    cam.rotation_euler = (target - eye).to_track_quat("-Z", "Y").to_euler()
    sc.camera = cam

    theta, phi = (math.radians(float(v)) for v in a["light"].split(","))
    to_light = to_blender(math.sin(theta) * math.cos(phi), math.cos(theta), math.sin(theta) * math.sin(phi))
    light = bpy.data.objects.new("sun", bpy.data.lights.new("sun", "SUN"))
    light.data.energy = sun
    light.data.angle = 0.0
    light.rotation_euler = to_light.to_track_quat("Z", "Y").to_euler()
    sc.collection.objects.link(light)

    world = bpy.data.worlds.new("black")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    sc.world = world

    sc.render.engine = "CYCLES"
    sc.cycles.device = "CPU"
    sc.cycles.use_denoising = False  # Debian's Cycles has no OpenImageDenoise
    sc.cycles.samples = int(a["samples"])
    sc.cycles.filter_width = 0.01  # a box pixel, as nbtf render's uniform sampling
    sc.cycles.max_bounces = 0      # direct light only: one plane, a black world
    sc.render.resolution_x, sc.render.resolution_y = w, h
    sc.render.resolution_percentage = 100
    sc.view_settings.view_transform = "Standard"
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.image_settings.color_depth = "32"
    sc.render.filepath = out
    bpy.ops.render.render(write_still=True)

    if a["info"]:
        info = {"blender": bpy.app.version_string, "sun_strength": sun}
        for mat in bpy.data.materials:
            if not mat.node_tree:
                continue
            for node in mat.node_tree.nodes:
                if node.type == "BSDF_PRINCIPLED":
                    info["principled"] = {"distribution": node.distribution,
                                          "subsurface_method": node.subsurface_method,
                                          "specular": node.inputs["Specular"].default_value}
            info["nodes"] = sorted(n.type for n in mat.node_tree.nodes)
        with open(a["info"], "w") as f:
            json.dump(info, f, indent=2)


main()
