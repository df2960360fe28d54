#!/usr/bin/env python3
"""Makes the two scenes of issue 39 on which a light tree and path guiding are measured, each a
binary glTF (the geometry, materials, lights and camera) and a TOML scene that places that
glTF and adds what glTF cannot hold:

- scenes/gltf/many-lights.glb and scenes/many-lights.toml: a city block grid at night, 40 x 40
  units, lit only by its own lamps: lit windows (small emissive quads on the facades, each a
  mesh and a material of its own) and point lights (street lamps, bollards, rooftop beacons),
  their powers spread log-normally over more than two orders of magnitude. The buildings hide
  most lamps from most points: what a light tree exploits.
- scenes/gltf/window-room.glb and scenes/window-room.toml: a closed room with one window, lit
  from outside by a sun (in the glTF, a directional light) and a uniform sky (in the TOML: glTF
  has no sky). The sun makes a patch on the floor; the camera looks at walls lit only
  indirectly: what path guiding exploits.

The TOML files reference the glTF files rather than repeating their shapes, so that lightsplit's
scene and the file Blender imports (scripts/compare-cycles.sh) are the same bytes; each TOML
holds the glTF's own camera (the same numbers the glTF's camera node is made from), the film,
the depth and, for the room, the sky.

Every material is diffuse: metallic 0, roughness 1 and KHR_materials_specular's factor 0,
which removes the 4% specular layer of glTF's model, in lightsplit and in Blender's import
alike, leaving a Lambertian base. Emitters emit from their front side only (lightsplit's
rule); the windows' backs face their wall 5 mm away, and their base colour is black.

Light units are glTF's: point lights in candela, the sun in lux, each 683 times the W/sr or
W/m^2 lightsplit (and Blender's importer in its default 'SPEC' mode) turns them back into.

    python3 scripts/make-hard-light-scenes.py      # rewrites the four files; deterministic
"""

import json
import math
import os
import random
import struct

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
LUMENS_PER_WATT = 683.0  # glTF's candela and lux per W/sr and W/m^2 (KHR_lights_punctual)


def normalize(v):
    n = math.sqrt(sum(c * c for c in v))
    return [c / n for c in v]


def cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def quaternion_from_basis(x, y, z):
    """The rotation (x, y, z, w) whose matrix has columns x, y, z (orthonormal, right-handed)."""
    m = [[x[0], y[0], z[0]], [x[1], y[1], z[1]], [x[2], y[2], z[2]]]
    trace = m[0][0] + m[1][1] + m[2][2]
    if trace > 0:
        s = 2.0 * math.sqrt(1.0 + trace)
        q = [(m[2][1] - m[1][2]) / s, (m[0][2] - m[2][0]) / s, (m[1][0] - m[0][1]) / s, 0.25 * s]
    elif m[0][0] > m[1][1] and m[0][0] > m[2][2]:
        s = 2.0 * math.sqrt(1.0 + m[0][0] - m[1][1] - m[2][2])
        q = [0.25 * s, (m[0][1] + m[1][0]) / s, (m[0][2] + m[2][0]) / s, (m[2][1] - m[1][2]) / s]
    elif m[1][1] > m[2][2]:
        s = 2.0 * math.sqrt(1.0 + m[1][1] - m[0][0] - m[2][2])
        q = [(m[0][1] + m[1][0]) / s, 0.25 * s, (m[1][2] + m[2][1]) / s, (m[0][2] - m[2][0]) / s]
    else:
        s = 2.0 * math.sqrt(1.0 + m[2][2] - m[0][0] - m[1][1])
        q = [(m[0][2] + m[2][0]) / s, (m[1][2] + m[2][1]) / s, 0.25 * s, (m[1][0] - m[0][1]) / s]
    return normalize(q)


def looking(back, up=(0.0, 1.0, 0.0)):
    """A node rotation whose -z points along -back and whose +y is as near `up` as it can be:
    a glTF camera's view, or the direction a directional light shines."""
    z = normalize(back)
    x = normalize(cross(up, z))
    y = cross(z, x)
    return quaternion_from_basis(x, y, z)


def quad(center, n, half_u, half_v):
    """The corners of a rectangle facing axis direction n (counter-clockwise seen from n's side,
    glTF's front), half_v along world up for vertical faces, else along z."""
    v = [0.0, 1.0, 0.0] if abs(n[1]) < 0.5 else [0.0, 0.0, 1.0]
    u = cross(v, n)  # u x v = n, so (-u-v, +u-v, +u+v, -u+v) runs counter-clockwise
    return [[center[k] + su * half_u * u[k] + sv * half_v * v[k] for k in range(3)]
            for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1))], n


def box_faces(lo, hi):
    """A box's six faces, each a quad facing outwards."""
    c = [(a + b) / 2 for a, b in zip(lo, hi)]
    h = [(b - a) / 2 for a, b in zip(lo, hi)]
    faces = []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            n = [0.0, 0.0, 0.0]
            n[axis] = sign
            center = list(c)
            center[axis] += sign * h[axis]
            # The half sizes along the quad's u and v (see quad()).
            if axis == 1:
                hu, hv = h[0], h[2]  # v = z; u = z x n is along x
            else:
                hu, hv = (h[2] if axis == 0 else h[0]), h[1]
            faces.append(quad(center, n, hu, hv))
    return faces


class Gltf:
    """A glTF document and its binary buffer, built up piece by piece."""

    def __init__(self):
        self.bin = bytearray()
        self.shared = {}
        self.doc = {
            "asset": {"version": "2.0", "generator": "lightsplit scripts/make-hard-light-scenes.py"},
            "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_emissive_strength",
                               "KHR_materials_specular"],
            "extensions": {"KHR_lights_punctual": {"lights": []}},
            "scene": 0, "scenes": [{"nodes": []}], "nodes": [], "meshes": [], "materials": [],
            "cameras": [], "accessors": [], "bufferViews": [],
        }

    def accessor(self, values, kind, float_):
        data = struct.pack("<%d%s" % (len(values), "f" if float_ else "I"), *values)
        # Equal data shares one accessor (every window's indices, the normals of a direction):
        # the JSON of a thousand small meshes is most of the file otherwise.
        key = (data, kind, float_)
        if key in self.shared:
            return self.shared[key]
        while len(self.bin) % 4:
            self.bin.append(0)
        self.doc["bufferViews"].append({"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data)})
        self.bin.extend(data)
        width = {"SCALAR": 1, "VEC3": 3}[kind]
        a = {"bufferView": len(self.doc["bufferViews"]) - 1, "componentType": 5126 if float_ else 5125,
             "count": len(values) // width, "type": kind}
        if kind == "VEC3":
            # Bounds of the f32 values as stored, as the specification requires.
            stored = struct.unpack("<%df" % len(values), data)
            a["min"] = [min(stored[k::3]) for k in range(3)]
            a["max"] = [max(stored[k::3]) for k in range(3)]
        self.doc["accessors"].append(a)
        self.shared[key] = len(self.doc["accessors"]) - 1
        return self.shared[key]

    def material(self, name, color, emission=None):
        m = {"name": name,
             "pbrMetallicRoughness": {"baseColorFactor": [*[round(c, 6) for c in color], 1.0],
                                      "metallicFactor": 0.0, "roughnessFactor": 1.0},
             # No specular layer: a Lambertian surface in both lightsplit and Blender.
             "extensions": {"KHR_materials_specular": {"specularFactor": 0.0}}}
        if emission is not None:
            # glTF's emissive factor is at most 1: the colour normalized, its peak the strength.
            peak = max(emission)
            m["emissiveFactor"] = [round(c / peak, 6) for c in emission]
            m["extensions"]["KHR_materials_emissive_strength"] = {"emissiveStrength": round(peak, 6)}
        self.doc["materials"].append(m)
        return len(self.doc["materials"]) - 1

    def mesh_node(self, name, faces, material, placement=None):
        """A node holding one mesh of one primitive: the quads `faces`, in world coordinates or
        placed by the node's `placement` (its translation and scale)."""
        pos, nor, idx = [], [], []
        for corners, n in faces:
            base = len(pos) // 3
            for c in corners:
                pos += c
                nor += n
            idx += [base, base + 1, base + 2, base, base + 2, base + 3]
        prim = {"attributes": {"POSITION": self.accessor(pos, "VEC3", True),
                               "NORMAL": self.accessor(nor, "VEC3", True)},
                "indices": self.accessor(idx, "SCALAR", False), "material": material}
        self.doc["meshes"].append({"name": name, "primitives": [prim]})
        self.node(dict(placement or {}, name=name, mesh=len(self.doc["meshes"]) - 1))
        return 2 * len(faces)

    def node(self, node):
        self.doc["nodes"].append(node)
        self.doc["scenes"][0]["nodes"].append(len(self.doc["nodes"]) - 1)

    def light(self, name, kind, rgb, node):
        """A KHR_lights_punctual light from lightsplit's units (W/sr for points, W/m^2 for the
        sun): glTF's colour is the normalized RGB, its intensity the peak times 683."""
        peak = max(rgb)
        lights = self.doc["extensions"]["KHR_lights_punctual"]["lights"]
        lights.append({"name": name, "type": kind, "color": [round(c / peak, 6) for c in rgb],
                       "intensity": round(peak * LUMENS_PER_WATT, 4)})
        node = dict(node, name=name, extensions={"KHR_lights_punctual": {"light": len(lights) - 1}})
        self.node(node)

    def camera(self, position, look_at, fov_degrees, aspect):
        back = [p - q for p, q in zip(position, look_at)]
        self.doc["cameras"].append({"name": "camera", "type": "perspective", "perspective": {
            "yfov": math.radians(fov_degrees), "aspectRatio": aspect, "znear": 0.01}})
        self.node({"name": "camera", "camera": 0, "translation": list(position), "rotation": looking(back)})

    def write(self, path):
        doc = dict(self.doc, buffers=[{"byteLength": len(self.bin)}])
        text = json.dumps(doc, separators=(",", ":")).encode()
        text += b" " * (-len(text) % 4)
        data = bytes(self.bin) + b"\0" * (-len(self.bin) % 4)
        total = 12 + 8 + len(text) + 8 + len(data)
        with open(path, "wb") as f:
            f.write(struct.pack("<4sII", b"glTF", 2, total))
            f.write(struct.pack("<I4s", len(text), b"JSON") + text)
            f.write(struct.pack("<I4s", len(data), b"BIN\0") + data)


def vec(v):
    return "[" + ", ".join("%.6g" % c for c in v) + "]"


def toml_head(comment, position, look_at, fov, glb):
    return comment + """
[camera]
position = %s
look_at = %s
fov = %s

[film]
width = 256
height = 256
spp = 64

[render]
max_depth = 8

[[shape]]
type = "gltf"
file = "%s"
""" % (vec(position), vec(look_at), "%.6g" % fov, glb)


def spread(rng, sigma, clip):
    """A log-normal factor: 10 to a normal of deviation `sigma` decades, cut at +-`clip`."""
    return 10.0 ** max(-clip, min(clip, rng.gauss(0.0, sigma)))


def many_lights(rng):
    g = Gltf()
    triangles = 0
    ground = g.material("asphalt", [0.18, 0.18, 0.19])
    triangles += g.mesh_node("ground", [quad([0.0, 0.0, 0.0], [0.0, 1.0, 0.0], 20.0, 20.0)], ground)
    facade_colors = [[0.55, 0.52, 0.48], [0.42, 0.45, 0.5], [0.6, 0.42, 0.33], [0.35, 0.36, 0.34]]
    facades = [g.material("facade-%d" % i, c) for i, c in enumerate(facade_colors)]
    kiosk = g.material("kiosk", [0.3, 0.45, 0.3])

    # 5 x 5 blocks of pitch 8 (streets 2.5 wide at x, z = +-4, +-12), each block 2 x 2 lots.
    buildings = []
    for bx in range(5):
        for bz in range(5):
            for lx in range(2):
                for lz in range(2):
                    if rng.random() < 0.12:
                        continue  # an empty lot: a yard
                    cx = 8.0 * (bx - 2) + (lx - 0.5) * 2.75
                    cz = 8.0 * (bz - 2) + (lz - 0.5) * 2.75
                    w = rng.uniform(1.9, 2.45) / 2
                    d = rng.uniform(1.9, 2.45) / 2
                    h = rng.choice([2, 2, 3, 3, 3, 4, 4, 5, 6, 8]) + rng.uniform(0.1, 0.5)
                    # Sunk 5 cm into the ground: no face of the scene lies on another's plane
                    # (coplanar faces are ties that Embree and the BVH may break differently).
                    buildings.append(([cx - w, -0.05, cz - d], [cx + w, h, cz + d], rng.randrange(4)))
    by_color = [[] for _ in facades]
    for lo, hi, c in buildings:
        by_color[c] += box_faces(lo, hi)
    for c, faces in enumerate(by_color):
        triangles += g.mesh_node("buildings-%d" % c, faces, facades[c])
    # Kiosks and low walls in the streets: small occluders near the lamps.
    boxes = []
    while len(boxes) < 40:
        along = rng.uniform(-19.0, 19.0)
        street = rng.choice([-12.0, -4.0, 4.0, 12.0]) + rng.uniform(-0.6, 0.6)
        x, z = (street, along) if rng.random() < 0.5 else (along, street)
        s = rng.uniform(0.25, 0.5)
        boxes.append(([x - s, -0.05, z - s], [x + s, rng.uniform(0.5, 1.3), z + s]))
    triangles += g.mesh_node("kiosks", [f for lo, hi in boxes for f in box_faces(lo, hi)], kiosk)

    def inside_box(p, margin):
        return any(all(lo[k] - margin <= p[k] <= hi[k] + margin for k in range(3))
                   for lo, hi in boxes + [(lo, hi) for lo, hi, _ in buildings])

    # Window slots: every floor (1 unit) and every 1-unit column of every facade.
    slots = []
    for lo, hi, _ in buildings:
        for axis in (0, 2):
            for sign in (-1.0, 1.0):
                other = 2 - axis
                span = hi[other] - lo[other]
                columns = max(1, int(span / 1.0))
                for row in range(int(hi[1] - 0.4)):
                    for col in range(columns):
                        c = [0.0, 0.6 + row, 0.0]
                        c[axis] = (hi[axis] if sign > 0 else lo[axis]) + sign * 0.005
                        c[other] = lo[other] + span * (col + 0.5) / columns
                        n = [0.0, 0.0, 0.0]
                        n[axis] = sign
                        slots.append((c, n))
    windows = rng.sample(slots, 640)
    window_power = []
    for i, (c, n) in enumerate(windows):
        tint = rng.choice([[1.0, 0.72, 0.42]] * 3 + [[1.0, 0.9, 0.75], [0.7, 0.82, 1.0]])
        radiance = 1.5 * spread(rng, 0.45, 1.2)
        hu, hv = rng.uniform(0.15, 0.35), rng.uniform(0.15, 0.3)
        emission = [radiance * t for t in tint]
        m = g.material("window-%d" % i, [0.0, 0.0, 0.0], emission)
        # A unit quad of its facing, scaled and moved by its node: the windows facing one way
        # share their vertices in the file (each is still a mesh of its own, for its material).
        scale = [hu, hv, hu]
        scale[0 if n[0] != 0 else 2] = 1.0
        placement = {"translation": [round(x, 5) for x in c], "scale": [round(x, 5) for x in scale]}
        triangles += g.mesh_node("window-%d" % i, [quad([0.0, 0.0, 0.0], n, 1.0, 1.0)], m, placement)
        window_power.append(math.pi * 4 * hu * hv * radiance)

    # Point lights: street lamps along the sidewalks, bollards low down, beacons on the roofs.
    point_power = []
    kinds = [("street", 280, (2.2, 3.6), 0.8), ("bollard", 60, (0.5, 0.9), 0.12), ("beacon", 44, None, 0.5)]
    for kind, count, heights, base in kinds:
        made = 0
        while made < count:
            if kind == "beacon":
                lo, hi, _ = rng.choice(buildings)
                p = [rng.uniform(lo[0], hi[0]), hi[1] + rng.uniform(0.4, 1.0), rng.uniform(lo[2], hi[2])]
            else:
                along = rng.uniform(-19.5, 19.5)
                street = rng.choice([-12.0, -4.0, 4.0, 12.0]) + rng.choice([-0.9, 0.9])
                y = rng.uniform(*heights)
                p = [street, y, along] if rng.random() < 0.5 else [along, y, street]
                if inside_box(p, 0.3):
                    continue
            tint = [1.0, 0.55, 0.2] if rng.random() < 0.6 else [1.0, 0.93, 0.82]
            intensity = base * spread(rng, 0.5, 1.25)
            g.light("%s-%d" % (kind, made), "point", [intensity * t for t in tint],
                    {"translation": [round(c, 5) for c in p]})
            point_power.append(4 * math.pi * intensity)
            made += 1

    position, look_at, fov = [0.0, 23.0, -33.0], [0.0, 0.0, -2.0], 44.0
    g.camera(position, look_at, fov, 1.0)
    g.write(os.path.join(ROOT, "scenes", "gltf", "many-lights.glb"))
    powers = window_power + point_power
    toml = toml_head("""# A city at night, 40 x 40 units, lit only by its own lamps: %d lit windows (emissive quads,
# each a mesh and material of its own: %d emissive triangles) and %d point lights (street
# lamps, bollards, rooftop beacons), their powers spread log-normally over %.1f decades. The
# buildings hide most lamps from most points: a scene for a light tree (issue 39). Everything
# is in gltf/many-lights.glb (made, with this file, by scripts/make-hard-light-scenes.py; its
# camera is the one below); there is no sky. scripts/compare-cycles.sh renders the same file
# in Blender's Cycles.
""" % (len(windows), 2 * len(windows), len(point_power),
       math.log10(max(powers) / min(powers))), position, look_at, fov, "gltf/many-lights.glb")
    with open(os.path.join(ROOT, "scenes", "many-lights.toml"), "w") as f:
        f.write(toml)
    print("many-lights: %d buildings, %d kiosks, %d windows (%d emissive triangles), %d point lights, "
          "%d triangles; window power %.3g..%.3g W, point power %.3g..%.3g W (%.1f decades overall)" % (
              len(buildings), len(boxes), len(windows), 2 * len(windows), len(point_power), triangles,
              min(window_power), max(window_power), min(point_power), max(point_power),
              math.log10(max(powers) / min(powers))))


def window_room():
    g = Gltf()
    triangles = 0
    wall = g.material("plaster", [0.75, 0.74, 0.7])
    floor = g.material("wood", [0.45, 0.3, 0.18])
    ground = g.material("grass", [0.16, 0.22, 0.1])
    sofa = g.material("blue", [0.12, 0.2, 0.45])
    table = g.material("red", [0.55, 0.12, 0.08])
    # The room's inside: x in [-3, 3], y in [0, 2.8], z in [-4, 4]; walls 0.2 thick. The boxes
    # overlap at the corners, so that no light leaks, but no two faces share a plane where they
    # overlap (coplanar faces are ties that Embree and the BVH may break differently): the +-x
    # walls end inside the +-z walls, which end 0.1 short of the +-x walls' outer faces; the
    # ceiling and the floor end inside the walls; the walls reach 5 cm below the ground, and the
    # furniture stands 5 cm into the floor. The window: in the +x wall, z in [-1, 1], y in
    # [0.9, 2.2].
    walls = [
        ([-3.2, -0.25, -4.1], [-3.0, 3.0, 4.1]),  # -x wall
        ([-3.1, -0.25, -4.2], [3.1, 3.0, -4.0]),  # -z wall
        ([-3.1, -0.25, 4.0], [3.1, 3.0, 4.2]),  # +z wall
        ([3.0, -0.25, -4.1], [3.2, 0.9, 4.1]),  # +x wall: under the window
        ([3.0, 2.2, -4.1], [3.2, 3.0, 4.1]),  # over it
        ([3.0, 0.9, -4.1], [3.2, 2.2, -1.0]),  # beside it
        ([3.0, 0.9, 1.0], [3.2, 2.2, 4.1]),
        ([-3.1, 2.8, -4.1], [3.1, 2.95, 4.1]),  # ceiling
    ]
    triangles += g.mesh_node("walls", [f for lo, hi in walls for f in box_faces(lo, hi)], wall)
    triangles += g.mesh_node("floor", box_faces([-3.1, -0.15, -4.1], [3.1, 0.0, 4.1]), floor)
    triangles += g.mesh_node("ground", [quad([0.0, -0.2, 0.0], [0.0, 1.0, 0.0], 60.0, 60.0)], ground)
    triangles += g.mesh_node("sofa", box_faces([-2.9, -0.05, -2.2], [-2.0, 0.8, 1.4]), sofa)
    triangles += g.mesh_node("table", box_faces([-1.0, -0.05, -0.9], [0.2, 0.55, 0.5]), table)
    # The sun: 32 degrees up, from outside the window and a little to +z.
    elevation, azimuth = math.radians(32.0), math.radians(25.0)
    to_sun = [math.cos(elevation) * math.cos(azimuth), math.sin(elevation), math.cos(elevation) * math.sin(azimuth)]
    sun = [32.0, 29.6, 26.4]  # W/m^2: bright enough that a plain PNG shows the indirect light
    g.light("sun", "directional", sun, {"rotation": looking(to_sun)})
    position, look_at, fov = [2.6, 1.5, 3.6], [-3.0, 1.0, -2.2], 62.0
    g.camera(position, look_at, fov, 1.0)
    g.write(os.path.join(ROOT, "scenes", "gltf", "window-room.glb"))
    sky = [2.8, 3.6, 4.8]
    toml = toml_head("""# A closed room with one window (2 x 1.3 units, in the +x wall), lit only from outside: a
# sun (a directional light in gltf/window-room.glb) makes a patch on the floor, and a uniform
# sky (below: glTF has no sky). The camera looks at walls lit only indirectly, through the
# window and off the sunlit patch: a scene for path guiding (issue 39). Made, with the glTF,
# by scripts/make-hard-light-scenes.py (the camera is the glTF's); scripts/compare-cycles.sh
# renders the same file in Blender's Cycles, its world the sky below.
""", position, look_at, fov, "gltf/window-room.glb") + """
[[light]]
type = "sky"
radiance = %s
""" % vec(sky)
    with open(os.path.join(ROOT, "scenes", "window-room.toml"), "w") as f:
        f.write(toml)
    print("window-room: %d triangles, sun %s W/m^2 from %s, sky %s" % (
        triangles, sun, vec([round(c, 3) for c in to_sun]), sky))


def main():
    os.makedirs(os.path.join(ROOT, "scenes", "gltf"), exist_ok=True)
    many_lights(random.Random(39))
    window_room()


if __name__ == "__main__":
    main()
