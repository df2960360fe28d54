"""Blender (the `bpy` module from PyPI, Python 3.11) as a third-party glTF exporter and as the
reference renderer for lightsplit's glTF import. Two modes:

    python scripts/blender-gltf.py export OUT.glb
        Builds a small scene in Blender (a checker-textured sphere, a gold Suzanne, a red plastic
        cube on a grey floor, and a camera) and exports it with Blender's own glTF exporter:
        base-colour textures and metallic-roughness materials, as real exporters write them.

    python scripts/blender-gltf.py render IN.glb ENV.hdr OUT.exr WIDTH HEIGHT SPP
        Imports IN.glb with Blender's glTF importer, lights it by ENV.hdr as the world
        (equirectangular, Blender's orientation), renders it with Cycles on the CPU through the
        glTF's camera, and writes the linear image and an object-index pass (each object's index
        is its position, from 1, in the glTF's node order) to OUT.exr.

    python scripts/blender-gltf.py model IN.glb|IN.gltf OUT_DIR WIDTH HEIGHT SPP
        A third-party model as its author would see it in Blender: imports it with Blender's glTF
        importer, frames its bounds as `lightsplit render MODEL.glb` does when the file has no
        camera (from the front and a little above, a vertical field of view of 40 degrees),
        lights it by a uniform white sky of radiance 1 (lightsplit's default environment),
        renders it with Cycles on the CPU (8 bounces of every kind, no glossy blur, no clamping,
        no denoising) to OUT_DIR/blender.exr, and writes OUT_DIR/lightsplit.toml: the same
        model, camera, film and sky for lightsplit (at twice the samples).

scripts/compare-blender.sh runs both and compares lightsplit's render of the same file with
Blender's; scripts/compare-blender-models.sh does so for the Khronos sample models.
Comparison only: Blender is never a dependency of lightsplit.
"""

import math
import sys

import bpy


def clear():
    bpy.ops.wm.read_factory_settings(use_empty=True)


def material(name, color, metallic, roughness, image=None):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    bsdf = m.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*color, 1.0)
    bsdf.inputs["Metallic"].default_value = metallic
    bsdf.inputs["Roughness"].default_value = roughness
    if image is not None:
        tex = m.node_tree.nodes.new("ShaderNodeTexImage")
        tex.image = image
        m.node_tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    return m


def checker(size=64, cells=8):
    img = bpy.data.images.new("checker", size, size)
    px = []
    for y in range(size):
        for x in range(size):
            on = ((x * cells // size) + (y * cells // size)) % 2 == 0
            c = (0.9, 0.85, 0.2) if on else (0.1, 0.25, 0.7)
            px.extend((*c, 1.0))
    img.pixels = px
    img.file_format = "PNG"
    img.pack()
    return img


def export(out):
    clear()
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_plane_add(size=8, location=(0, 0, 0))
    floor = bpy.context.object
    floor.name = "floor"
    floor.data.materials.append(material("grey", (0.5, 0.5, 0.5), 0.0, 0.9))
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.7, location=(-1.6, 0, 0.7), segments=48, ring_count=24)
    sphere = bpy.context.object
    sphere.name = "sphere"
    bpy.ops.object.shade_smooth()
    sphere.data.materials.append(material("checker", (1, 1, 1), 0.0, 0.5, checker()))
    bpy.ops.mesh.primitive_monkey_add(size=1.2, location=(0, 0, 0.75), rotation=(math.radians(-20), 0, math.radians(-30)))
    monkey = bpy.context.object
    monkey.name = "suzanne"
    mod = monkey.modifiers.new("subsurf", "SUBSURF")
    mod.levels = 1
    bpy.ops.object.shade_smooth()
    monkey.data.materials.append(material("gold", (1.0, 0.78, 0.34), 1.0, 0.35))
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(1.6, 0.2, 0.5), rotation=(0, 0, math.radians(25)))
    cube = bpy.context.object
    cube.name = "cube"
    cube.data.materials.append(material("red plastic", (0.7, 0.05, 0.04), 0.0, 0.2))
    bpy.ops.object.camera_add(location=(0.0, -6.5, 2.2))
    cam = bpy.context.object
    cam.name = "camera"
    direction = (0.0, 6.5, -1.6)
    cam.rotation_euler = (math.atan2(math.hypot(direction[0], direction[1]), -direction[2]), 0, 0)
    cam.data.sensor_fit = "VERTICAL"
    cam.data.angle_y = math.radians(32)
    scene.camera = cam
    scene.render.resolution_x, scene.render.resolution_y = 400, 250
    bpy.ops.export_scene.gltf(filepath=out, export_format="GLB", export_cameras=True, export_lights=False,
                              export_apply=True)
    print(f"exported {out}")


def render(glb, env, out, width, height, spp):
    clear()
    bpy.ops.import_scene.gltf(filepath=glb)
    scene = bpy.context.scene
    cams = [o for o in scene.objects if o.type == "CAMERA"]
    scene.camera = cams[0]
    meshes = sorted((o for o in scene.objects if o.type == "MESH"), key=lambda o: o.name)
    for i, o in enumerate(meshes, start=1):
        o.pass_index = i
        print(f"object index {i}: {o.name}")
    world = bpy.data.worlds.new("env")
    world.use_nodes = True
    nodes = world.node_tree.nodes
    tex = nodes.new("ShaderNodeTexEnvironment")
    tex.image = bpy.data.images.load(env)
    world.node_tree.links.new(tex.outputs["Color"], nodes["Background"].inputs["Color"])
    scene.world = world
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = spp
    scene.cycles.use_denoising = False
    scene.cycles.max_bounces = 8
    # lightsplit's pixel filter: a box one pixel wide (0.01 would be a point sample, aliased).
    scene.cycles.pixel_filter_type = "BOX"
    scene.cycles.filter_width = 1.0
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    scene.view_settings.view_transform = "Standard"
    scene.view_layers[0].use_pass_object_index = True
    settings = scene.render.image_settings
    if hasattr(settings, "media_type"):  # Blender 5: multilayer EXR is a media type
        settings.media_type = "MULTI_LAYER_IMAGE"
    else:
        settings.file_format = "OPEN_EXR_MULTILAYER"
    scene.render.image_settings.color_depth = "32"
    scene.render.filepath = out
    bpy.ops.render.render(write_still=True)
    print(f"rendered {out}")


def cycles(scene, width, height, spp):
    """Cycles on the CPU, unbiased as lightsplit is: 8 bounces of every kind, no glossy blur,
    no clamping, no denoising, lightsplit's pixel filter (a box one pixel wide; a width of 0.01
    would be a point sample, which aliases textures and edges)."""
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device = "CPU"
    c.samples = spp
    c.use_denoising = False
    c.use_adaptive_sampling = False
    c.max_bounces = c.diffuse_bounces = c.glossy_bounces = c.transmission_bounces = 8
    c.transparent_max_bounces = 8
    c.blur_glossy = 0.0
    c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    c.pixel_filter_type = "BOX"
    c.filter_width = 1.0
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    scene.view_settings.view_transform = "Standard"
    settings = scene.render.image_settings
    if hasattr(settings, "media_type"):  # Blender 5: multilayer EXR is a media type
        settings.media_type = "MULTI_LAYER_IMAGE"
    else:
        settings.file_format = "OPEN_EXR_MULTILAYER"
    settings.color_depth = "32"


def model(path, out_dir, width, height, spp):
    import os
    from mathutils import Vector

    clear()
    bpy.ops.import_scene.gltf(filepath=os.path.abspath(path))
    scene = bpy.context.scene
    depsgraph = bpy.context.evaluated_depsgraph_get()
    lo = [math.inf] * 3
    hi = [-math.inf] * 3
    for o in scene.objects:
        if o.type != "MESH":
            continue
        mesh = o.evaluated_get(depsgraph).to_mesh()
        for v in mesh.vertices:
            p = o.matrix_world @ v.co
            # Blender's z-up back to glTF's y-up: (x, y, z) -> (x, z, -y).
            g = (p.x, p.z, -p.y)
            lo = [min(a, b) for a, b in zip(lo, g)]
            hi = [max(a, b) for a, b in zip(hi, g)]
    centre = [(a + b) / 2 for a, b in zip(lo, hi)]
    radius = max(0.5 * math.dist(lo, hi), 1e-6)
    fov = 40.0
    distance = radius / math.sin(math.radians(fov / 2))
    back = Vector((0.0, 0.35, 1.0)).normalized()
    position = [c + b * distance for c, b in zip(centre, back)]
    # The camera in Blender's coordinates, its -z toward the centre and its y up (glTF's +y).
    to_blender = lambda g: Vector((g[0], -g[2], g[1]))  # noqa: E731
    data = bpy.data.cameras.new("frame")
    data.sensor_fit = "VERTICAL"
    data.angle_y = math.radians(fov)
    data.clip_start = distance * 1e-3
    data.clip_end = distance * 1e3
    cam = bpy.data.objects.new("frame", data)
    scene.collection.objects.link(cam)
    cam.location = to_blender(position)
    direction = to_blender(centre) - to_blender(position)
    cam.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()
    scene.camera = cam
    world = bpy.data.worlds.new("white")
    world.use_nodes = True
    background = world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    background.inputs["Strength"].default_value = 1.0
    scene.world = world
    cycles(scene, width, height, spp)
    scene.render.filepath = os.path.join(out_dir, "blender.exr")
    with open(os.path.join(out_dir, "lightsplit.toml"), "w") as f:
        vec = lambda v: "[" + ", ".join(f"{x:.9g}" for x in v) + "]"  # noqa: E731
        f.write(f"""# Written by scripts/blender-gltf.py model: the view Blender renders.
[camera]
position = {vec(position)}
look_at = {vec(centre)}
fov = {fov}
[film]
width = {width}
height = {height}
spp = {2 * spp}
[render]
max_depth = 8
[[shape]]
type = "gltf"
file = "{os.path.abspath(path)}"
[[light]]
type = "sky"
radiance = [1, 1, 1]
""")
    bpy.ops.render.render(write_still=True)
    print(f"rendered {scene.render.filepath}")


if __name__ == "__main__":
    args = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
    if args and args[0] == "export":
        export(args[1])
    elif args and args[0] == "model":
        model(args[1], args[2], int(args[3]), int(args[4]), int(args[5]))
    elif args and args[0] == "render":
        render(args[1], args[2], args[3], int(args[4]), int(args[5]), int(args[6]))
    else:
        print(__doc__)
        sys.exit(2)
