#!/usr/bin/env python3
"""Makes a glTF (.glb) whose one mesh is used by many nodes: a field of shapes on a ground
square, for instancing. The shape is a bumpy sphere of 2 * RINGS * (RINGS - 1) triangles with
normals and texture coordinates; the nodes place it on a COUNT x COUNT grid, each turned,
tilted and scaled by its own (seeded) amount, under one root node. Two materials alternate
between the rows, so instances of one mesh differ in material too.

With --copies, every node gets a mesh of its own (the same accessors under another mesh
index): the same scene with nothing shared, which a reader copies into each place. The two
render the same image; the instanced one keeps one copy of the triangles.

    python3 scripts/make-instances-gltf.py [--count N] [--rings R] [--copies] [OUT]
    # default: --count 7 --rings 12, scenes/gltf/instances.glb
"""

import argparse
import json
import math
import random
import struct


def sphere(rings):
    """A bumpy unit sphere: positions, normals, uvs (flat lists) and triangle indices."""
    pos, nor, uv, idx = [], [], [], []
    segments = 2 * rings
    for i in range(rings + 1):
        theta = math.pi * i / rings
        for j in range(segments + 1):
            phi = 2.0 * math.pi * j / segments
            d = (math.sin(theta) * math.cos(phi), math.cos(theta), math.sin(theta) * math.sin(phi))
            r = 1.0 + 0.12 * math.sin(3 * phi) * math.sin(theta) ** 2
            pos += [r * d[0], r * d[1], r * d[2]]
            nor += list(d)
            uv += [j / segments, i / rings]
    row = segments + 1
    for i in range(rings):
        for j in range(segments):
            a, b = i * row + j, i * row + j + 1
            c, d = a + row, b + row
            if i != 0:
                idx += [a, b, c]
            if i != rings - 1:
                idx += [b, d, c]
    return pos, nor, uv, idx


def quaternion(axis, angle):
    s = math.sin(angle / 2.0)
    return [axis[0] * s, axis[1] * s, axis[2] * s, math.cos(angle / 2.0)]


def multiply(q, r):
    x1, y1, z1, w1 = q
    x2, y2, z2, w2 = r
    return [w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2]


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--count", type=int, default=7, help="nodes along each side of the grid")
    parser.add_argument("--rings", type=int, default=12, help="the sphere's rings of triangles")
    parser.add_argument("--copies", action="store_true", help="a mesh of its own for every node")
    parser.add_argument("out", nargs="?", default="scenes/gltf/instances.glb")
    args = parser.parse_args()

    bin_ = bytearray()
    views, accessors = [], []

    def accessor(values, kind, component, bounds=False):
        while len(bin_) % 4:
            bin_.append(0)
        fmt = "<%d%s" % (len(values), "f" if component == 5126 else "I")
        data = struct.pack(fmt, *values)
        views.append({"buffer": 0, "byteOffset": len(bin_), "byteLength": len(data)})
        bin_.extend(data)
        width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3}[kind]
        a = {"bufferView": len(views) - 1, "componentType": component, "count": len(values) // width,
             "type": kind}
        if bounds:
            a["min"] = [min(values[k::3]) for k in range(3)]
            a["max"] = [max(values[k::3]) for k in range(3)]
        accessors.append(a)
        return len(accessors) - 1

    pos, nor, uv, idx = sphere(args.rings)
    shape = {"POSITION": accessor(pos, "VEC3", 5126, True), "NORMAL": accessor(nor, "VEC3", 5126),
             "TEXCOORD_0": accessor(uv, "VEC2", 5126)}
    shape_indices = accessor(idx, "SCALAR", 5125)
    half = 0.75 * args.count
    ground = {"POSITION": accessor([-half, 0, -half, half, 0, -half, half, 0, half, -half, 0, half], "VEC3",
                                   5126, True),
              "NORMAL": accessor([0, 1, 0] * 4, "VEC3", 5126)}
    ground_indices = accessor([0, 2, 1, 0, 3, 2], "SCALAR", 5125)

    materials = [
        {"name": "clay", "pbrMetallicRoughness": {"baseColorFactor": [0.75, 0.35, 0.2, 1], "metallicFactor": 0.0,
                                                  "roughnessFactor": 0.6}},
        {"name": "brass", "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.7, 0.3, 1], "metallicFactor": 1.0,
                                                   "roughnessFactor": 0.3}},
        {"name": "ground", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1], "metallicFactor": 0.0,
                                                    "roughnessFactor": 1.0}},
    ]
    meshes = [{"name": "ground", "primitives": [{"attributes": ground, "indices": ground_indices, "material": 2}]}]
    nodes = [{"name": "root", "children": []}, {"name": "ground", "mesh": 0}]
    rng = random.Random(7)
    shared = {}
    for row in range(args.count):
        for col in range(args.count):
            material = row % 2
            if args.copies or material not in shared:
                meshes.append({"name": "shape", "primitives": [
                    {"attributes": shape, "indices": shape_indices, "material": material}]})
                shared[material] = len(meshes) - 1
            scale = 0.3 + 0.2 * rng.random()
            turn = quaternion((0, 1, 0), rng.uniform(0, 2 * math.pi))
            tilt = quaternion((1, 0, 0), rng.uniform(-0.4, 0.4))
            nodes.append({
                "name": "shape-%d-%d" % (row, col),
                "mesh": shared[material],
                "translation": [1.5 * (col - (args.count - 1) / 2), scale * 1.05, 1.5 * (row - (args.count - 1) / 2)],
                "rotation": multiply(turn, tilt),
                "scale": [scale, scale * (0.8 + 0.4 * rng.random()), scale],
            })
    nodes[0]["children"] = list(range(1, len(nodes)))
    doc = {
        "asset": {"version": "2.0", "generator": "lightsplit scripts/make-instances-gltf.py"},
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": nodes, "meshes": meshes, "materials": materials,
        "accessors": accessors, "bufferViews": views, "buffers": [{"byteLength": len(bin_)}],
    }
    text = json.dumps(doc, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    bin_ += b"\0" * (-len(bin_) % 4)
    total = 12 + 8 + len(text) + 8 + len(bin_)
    with open(args.out, "wb") as f:
        f.write(struct.pack("<4sII", b"glTF", 2, total))
        f.write(struct.pack("<I4s", len(text), b"JSON") + text)
        f.write(struct.pack("<I4s", len(bin_), b"BIN\0") + bytes(bin_))
    print("%s: %d nodes, %d meshes, %d triangles placed" % (
        args.out, len(nodes) - 2, len(meshes), (len(nodes) - 2) * len(idx) // 3 + 2))


if __name__ == "__main__":
    main()
