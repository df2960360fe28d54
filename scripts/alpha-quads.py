#!/usr/bin/env python3
"""Many cut-outs: writes a glTF of N leaf quads (default 10,000), each a disc cut out of a
square by alphaMode MASK, scattered in a box over a ground quad, and renders it with both
backends, beside the same file with the quads opaque, printing each render's time and
samples per second (lightsplit's `render --json`).

    scripts/alpha-quads.py [--quads N] [--spp S] [--size W] [--lightsplit BIN] [--out DIR]

No third-party Python modules: the PNG and the glTF are written by hand.
"""

import argparse
import base64
import json
import math
import os
import random
import struct
import subprocess
import sys
import zlib


def png_rgba(width, height, pixel):
    """A PNG of `pixel(x, y) -> (r, g, b, a)` bytes."""
    raw = b"".join(
        b"\x00" + b"".join(bytes(pixel(x, y)) for x in range(width)) for y in range(height)
    )

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")


def leaves(n, seed, mode):
    """The glTF document (JSON, buffers embedded) of `n` quads with a disc mask, material
    `mode` (MASK or OPAQUE), over a ground quad, lit by a sun."""
    rng = random.Random(seed)
    positions, uvs, indices = [], [], []
    for k in range(n):
        cx, cy, cz = rng.uniform(-5, 5), rng.uniform(0.3, 4), rng.uniform(-5, 5)
        # A random orientation: two unit axes spanning the quad, 0.15 units on a side.
        a = [rng.gauss(0, 1) for _ in range(3)]
        la = math.sqrt(sum(x * x for x in a)) or 1.0
        a = [x / la for x in a]
        b = [rng.gauss(0, 1) for _ in range(3)]
        d = sum(x * y for x, y in zip(a, b))
        b = [y - d * x for x, y in zip(a, b)]
        lb = math.sqrt(sum(x * x for x in b)) or 1.0
        b = [x / lb for x in b]
        h = 0.075
        for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
            positions.append([cx + h * (su * a[i] + sv * b[i]) for i, cx in enumerate((cx, cy, cz))])
            uvs.append([(su + 1) / 2, (1 - sv) / 2])
        base = 4 * k
        indices += [base, base + 1, base + 2, base, base + 2, base + 3]
    ground = len(positions)
    positions += [[-8, 0, -8], [-8, 0, 8], [8, 0, 8], [8, 0, -8]]
    uvs += [[0, 0], [0, 1], [1, 1], [1, 0]]
    ground_indices = [ground, ground + 1, ground + 2, ground, ground + 2, ground + 3]

    def floats(values):
        return b"".join(struct.pack("<f", v) for row in values for v in row)

    blobs = [floats(positions), floats(uvs), struct.pack(f"<{len(indices)}I", *indices),
             struct.pack("<6I", *ground_indices)]
    buffers, views = [], []
    for blob in blobs:
        buffers.append({"uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode(),
                        "byteLength": len(blob)})
        views.append({"buffer": len(buffers) - 1, "byteLength": len(blob)})
    lo = [min(p[i] for p in positions) for i in range(3)]
    hi = [max(p[i] for p in positions) for i in range(3)]
    accessors = [
        {"bufferView": 0, "componentType": 5126, "count": len(positions), "type": "VEC3", "min": lo, "max": hi},
        {"bufferView": 1, "componentType": 5126, "count": len(uvs), "type": "VEC2"},
        {"bufferView": 2, "componentType": 5125, "count": len(indices), "type": "SCALAR"},
        {"bufferView": 3, "componentType": 5125, "count": 6, "type": "SCALAR"},
    ]
    size = 64
    disc = png_rgba(size, size, lambda x, y: (60, 140, 50, 255 if (x - 31.5) ** 2 + (y - 31.5) ** 2 < 30 ** 2 else 0))
    leaf = {"name": "leaf", "pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1], "baseColorTexture": {"index": 0},
                                                      "metallicFactor": 0.0, "roughnessFactor": 0.8}}
    if mode != "OPAQUE":
        leaf["alphaMode"] = mode
    return {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 1, 2, 3]}],
        "nodes": [
            {"mesh": 0},
            {"mesh": 1},
            {"camera": 0, "translation": [0, 3, 11], "rotation": [-0.104, 0, 0, 0.9946]},
            {"extensions": {"KHR_lights_punctual": {"light": 0}}, "rotation": [-0.5, 0.0, 0.0, 0.866]},
        ],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.7, "znear": 0.1, "aspectRatio": 1.0}}],
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": [{"type": "directional", "intensity": 2000.0}]}},
        "meshes": [
            {"name": "leaves", "primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "material": 0}]},
            {"name": "ground", "primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 3, "material": 1}]},
        ],
        "materials": [leaf, {"name": "ground", "pbrMetallicRoughness": {"baseColorFactor": [0.6, 0.55, 0.5, 1],
                                                                        "metallicFactor": 0.0, "roughnessFactor": 1.0}}],
        "images": [{"uri": "data:image/png;base64," + base64.b64encode(disc).decode()}],
        "samplers": [{"magFilter": 9729, "minFilter": 9729}],
        "textures": [{"source": 0, "sampler": 0}],
        "buffers": buffers,
        "bufferViews": views,
        "accessors": accessors,
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quads", type=int, default=10_000)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--lightsplit", default="target/dist/lightsplit")
    ap.add_argument("--out", default="alpha-quads")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    files = {}
    for mode in ("MASK", "OPAQUE"):
        path = os.path.join(args.out, f"leaves-{mode.lower()}.gltf")
        with open(path, "w") as f:
            json.dump(leaves(args.quads, 7, mode), f)
        files[mode] = path
    rows = []
    # Alternated, so that drift of the machine's speed falls on every configuration alike.
    for r in range(args.repeats):
        for accel in ("embree", "bvh"):
            for mode, path in files.items():
                image = os.path.join(args.out, f"{mode.lower()}-{accel}.png")
                out = subprocess.run(
                    [args.lightsplit, "render", path, "--accel", accel, "--width", str(args.size),
                     "--height", str(args.size), "--spp", str(args.spp), "--json", "-o", image],
                    capture_output=True, text=True)
                if out.returncode != 0:
                    sys.exit(f"{accel} {mode}: {out.stderr.strip()}")
                j = json.loads(out.stdout)
                rows.append((accel, mode, j["seconds"], j["samples_per_second"]))
    print(f"{args.quads} leaf quads, {args.size}x{args.size} at {args.spp} spp, median of {args.repeats}:")
    for accel in ("embree", "bvh"):
        med = {}
        for mode in files:
            sps = sorted(s for a, m, _, s in rows if a == accel and m == mode)
            med[mode] = sps[len(sps) // 2]
        print(f"  {accel:6}  MASK {med['MASK'] / 1e6:6.2f} M samples/s   OPAQUE {med['OPAQUE'] / 1e6:6.2f} M samples/s"
              f"   MASK/OPAQUE {med['MASK'] / med['OPAQUE']:.2f}")


if __name__ == "__main__":
    main()
