#!/usr/bin/env python3
"""Writes a lightsplit scene as a Mitsuba 3 scene: OUT_DIR/scene.xml and one OBJ a mesh part.

    python3 mitsuba_scene.py SCENE.toml OUT_DIR [--width W] [--height H] [--spp N]
        [--max-depth D] [--mitsuba-max-depth M] [--file-format pfm|openexr]

Only what scenes/embree-cornell.toml uses is translated, and anything else is refused (exit 2)
rather than approximated: a pinhole camera, OBJ meshes whose parts take their .mtl Kd as a
diffuse colour (Ke must be zero), named diffuse materials, and point lights.

How lightsplit's semantics map onto Mitsuba's:
- camera: `perspective` sensor, the same look-at frame, `fov` about the y axis (lightsplit's fov
  is vertical). Both put image-right along forward x up.
- pixels: lightsplit averages uniformly jittered samples within each pixel; that is Mitsuba's
  `box` reconstruction filter with the `independent` sampler.
- materials: lightsplit's surfaces are two-sided Lambertian; Mitsuba's `diffuse` is one-sided,
  so each is wrapped in `twosided`. Mitsuba's OBJ loader ignores .mtl files, so each OBJ part
  (object and material) is written to an OBJ of its own, triangulated as a fan like lightsplit's
  loader does, and given its BSDF in the XML.
- lights: lightsplit's point `intensity` is radiant intensity (W/sr), as is Mitsuba's.
- depth: lightsplit's max_depth D allows D scattering vertices (depth 0 is the camera ray's
  hit), each doing next-event estimation, so its longest path has D + 1 segments: the camera
  segment, D - 1 bounces and the shadow segment. Mitsuba's `path` max_depth counts segments
  including the camera's (2 is direct light only), so the match is D + 1.
- output: the film writes PFM (32-bit float, linear) by default. The `mitsuba` command of
  Mitsuba 3.9.1 from PyPI never returns from writing an OpenEXR file when given `-t 1` or `-t 2`
  (it waits on OpenEXR's thread pool; `-t 3` and more are fine); PFM does not use OpenEXR.
"""

import argparse
import os
import sys

try:
    import tomllib
except ImportError:  # Python before 3.11
    import tomli as tomllib
from xml.sax.saxutils import quoteattr


class Unsupported(Exception):
    pass


def vec3(value, what):
    if not (isinstance(value, list) and len(value) == 3 and all(isinstance(x, (int, float)) for x in value)):
        raise Unsupported(f"{what}: expected three numbers, got {value!r}")
    return [float(x) for x in value]


def only_keys(table, allowed, what):
    extra = sorted(set(table) - set(allowed))
    if extra:
        raise Unsupported(f"{what}: keys not translated to Mitsuba: {', '.join(extra)}")


def read_mtl(path):
    """Material name -> Kd, refusing emission."""
    materials, current = {}, None
    with open(path, encoding="utf-8") as f:
        for line in f:
            words = line.split()
            if not words or words[0].startswith("#"):
                continue
            if words[0] == "newmtl":
                current = " ".join(words[1:])
                materials[current] = [0.0, 0.0, 0.0]
            elif words[0] == "Kd" and current is not None:
                materials[current] = [float(x) for x in words[1:4]]
            elif words[0] == "Ke" and current is not None:
                if any(float(x) != 0.0 for x in words[1:4]):
                    raise Unsupported(f"{path}: material {current}: emission (Ke) is not translated")
    return materials


def read_obj(path):
    """Parts of an OBJ, one per (object, material), as (name, material, positions, triangles)."""
    base = os.path.dirname(path)
    positions, materials = [], {}
    parts, order = {}, []
    obj, mtl = "default", None
    with open(path, encoding="utf-8") as f:
        for number, line in enumerate(f, 1):
            words = line.split()
            if not words or words[0].startswith("#"):
                continue
            key = words[0]
            if key == "mtllib":
                materials.update(read_mtl(os.path.join(base, " ".join(words[1:]))))
            elif key == "o":
                obj = " ".join(words[1:]) or "default"
            elif key == "usemtl":
                mtl = " ".join(words[1:])
            elif key == "v":
                positions.append([float(x) for x in words[1:4]])
            elif key == "f":
                idx = []
                for w in words[1:]:
                    i = int(w.split("/")[0])
                    idx.append(i - 1 if i > 0 else len(positions) + i)
                if any(not 0 <= i < len(positions) for i in idx):
                    raise Unsupported(f"{path}:{number}: face index out of range")
                if (obj, mtl) not in parts:
                    parts[(obj, mtl)] = []
                    order.append((obj, mtl))
                # A fan, as lightsplit's loader triangulates a polygon.
                for k in range(1, len(idx) - 1):
                    parts[(obj, mtl)].append((idx[0], idx[k], idx[k + 1]))
            elif key in ("vn", "vt", "s", "g"):
                pass  # flat Lambertian surfaces: normals, uvs and groups change nothing here
            else:
                raise Unsupported(f"{path}:{number}: OBJ statement {key!r} is not translated")
    out = []
    for obj, mtl in order:
        if mtl is not None and mtl not in materials:
            raise Unsupported(f"{path}: material {mtl!r} is not in the material library")
        kd = materials[mtl] if mtl is not None else [0.8, 0.8, 0.8]
        out.append((obj, mtl, kd, positions, parts[(obj, mtl)]))
    return out


def write_part_obj(path, positions, triangles):
    """One part re-indexed on its own vertices."""
    used = sorted({i for t in triangles for i in t})
    remap = {old: new + 1 for new, old in enumerate(used)}
    with open(path, "w", encoding="utf-8") as f:
        for i in used:
            f.write("v {:.9g} {:.9g} {:.9g}\n".format(*positions[i]))
        for t in triangles:
            f.write("f {} {} {}\n".format(*(remap[i] for i in t)))


def fmt(v):
    return ", ".join(f"{x:.9g}" for x in v)


def convert(scene_path, out_dir, width=None, height=None, spp=None, max_depth=None, mitsuba_max_depth=None,
            file_format="pfm"):
    with open(scene_path, "rb") as f:
        scene = tomllib.load(f)
    base = os.path.dirname(os.path.abspath(scene_path))
    only_keys(scene, ["camera", "film", "render", "shape", "light", "material"], scene_path)

    if "camera" not in scene:
        raise Unsupported(f"{scene_path}: no [camera]")
    cam = scene["camera"]
    only_keys(cam, ["position", "look_at", "up", "fov"], "[camera]")
    film = scene.get("film", {})
    only_keys(film, ["width", "height", "spp"], "[film]")
    render = scene.get("render", {})
    only_keys(render, ["max_depth", "seed"], "[render]")

    width = width or film.get("width", 256)
    height = height or film.get("height", 256)
    spp = spp or film.get("spp", 16)
    max_depth = max_depth or render.get("max_depth", 8)
    if mitsuba_max_depth is None:
        mitsuba_max_depth = max_depth + 1

    named = {}
    for m in scene.get("material", []):
        only_keys(m, ["name", "type", "color"], f"material {m.get('name')!r}")
        if m.get("type", "diffuse") != "diffuse":
            raise Unsupported(f"material {m.get('name')!r}: only diffuse materials are translated")
        named[m["name"]] = vec3(m.get("color", [0.8, 0.8, 0.8]), f"material {m['name']!r} color")

    os.makedirs(out_dir, exist_ok=True)
    bsdfs, shapes = {}, []
    for n, shape in enumerate(scene.get("shape", [])):
        what = f"shape {n} ({shape.get('name', shape.get('type'))})"
        if shape.get("type") != "mesh":
            raise Unsupported(f"{what}: only mesh shapes are translated")
        only_keys(shape, ["type", "file", "name", "material", "object"], what)
        for k, (obj, mtl, kd, positions, triangles) in enumerate(read_obj(os.path.join(base, shape["file"]))):
            if "material" in shape:
                if shape["material"] not in named:
                    raise Unsupported(f"{what}: material {shape['material']!r} is not defined")
                kd = named[shape["material"]]
            key = tuple(kd)
            if key not in bsdfs:
                bsdfs[key] = f"bsdf{len(bsdfs)}"
            file = f"shape{n}_part{k}.obj"
            write_part_obj(os.path.join(out_dir, file), positions, triangles)
            shapes.append((obj, file, bsdfs[key]))

    lights = []
    for n, light in enumerate(scene.get("light", [])):
        if light.get("type") != "point":
            raise Unsupported(f"light {n}: only point lights are translated")
        only_keys(light, ["type", "position", "intensity"], f"light {n}")
        lights.append((vec3(light["position"], f"light {n} position"), vec3(light["intensity"], f"light {n} intensity")))

    pos = vec3(cam["position"], "camera position")
    target = vec3(cam["look_at"], "camera look_at")
    up = vec3(cam.get("up", [0, 1, 0]), "camera up")
    fov = float(cam.get("fov", 40))

    x = ['<scene version="3.0.0">']
    x.append(f'  <integrator type="path"><integer name="max_depth" value="{mitsuba_max_depth}"/></integrator>')
    x.append('  <sensor type="perspective">')
    x.append(f'    <float name="fov" value="{fov:.9g}"/>')
    x.append('    <string name="fov_axis" value="y"/>')
    x.append('    <float name="far_clip" value="1e7"/>')
    x.append(f'    <transform name="to_world"><lookat origin="{fmt(pos)}" target="{fmt(target)}" up="{fmt(up)}"/></transform>')
    x.append(f'    <sampler type="independent"><integer name="sample_count" value="{spp}"/></sampler>')
    x.append('    <film type="hdrfilm">')
    x.append(f'      <integer name="width" value="{width}"/>')
    x.append(f'      <integer name="height" value="{height}"/>')
    x.append('      <string name="pixel_format" value="rgb"/>')
    x.append(f'      <string name="file_format" value="{file_format}"/>')
    x.append('      <rfilter type="box"/>')
    x.append('    </film>')
    x.append('  </sensor>')
    for kd, ident in bsdfs.items():
        x.append(f'  <bsdf type="twosided" id="{ident}"><bsdf type="diffuse">'
                 f'<rgb name="reflectance" value="{fmt(kd)}"/></bsdf></bsdf>')
    for name, file, ident in shapes:
        x.append(f'  <shape type="obj" id={quoteattr(name)}><string name="filename" value="{file}"/>'
                 f'<boolean name="face_normals" value="true"/><ref id="{ident}"/></shape>')
    for p, i in lights:
        x.append(f'  <emitter type="point"><point name="position" x="{p[0]:.9g}" y="{p[1]:.9g}" z="{p[2]:.9g}"/>'
                 f'<rgb name="intensity" value="{fmt(i)}"/></emitter>')
    x.append('</scene>')
    path = os.path.join(out_dir, "scene.xml")
    with open(path, "w", encoding="utf-8") as f:
        f.write("\n".join(x) + "\n")
    return path


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scene")
    ap.add_argument("out_dir")
    ap.add_argument("--width", type=int)
    ap.add_argument("--height", type=int)
    ap.add_argument("--spp", type=int)
    ap.add_argument("--max-depth", type=int, help="lightsplit's max_depth (default: the scene's)")
    ap.add_argument("--mitsuba-max-depth", type=int, help="override the matched Mitsuba max_depth (to test it)")
    ap.add_argument("--file-format", choices=["pfm", "openexr"], default="pfm",
                    help="the film's file format (default pfm: see the module's docstring)")
    a = ap.parse_args()
    try:
        path = convert(a.scene, a.out_dir, a.width, a.height, a.spp, a.max_depth, a.mitsuba_max_depth,
                       a.file_format)
    except (Unsupported, OSError, KeyError, ValueError, tomllib.TOMLDecodeError) as e:
        print(f"mitsuba_scene: {e}", file=sys.stderr)
        sys.exit(2)
    print(path)


if __name__ == "__main__":
    main()
