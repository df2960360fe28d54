"""Compares lightsplit's render of a glTF with Blender's (scripts/blender-gltf.py), both linear
EXRs of the same camera and size: per region (lightsplit's object IDs; the background is its own
region), the mean colour of each image and their ratio, and the layout (the fraction of pixels
whose two values agree within 25%, which a shifted or mirrored object would lower). The
per-region figures are the binary's own (`lightsplit compare --by-object --json`, over each
region's inner pixels); Blender's Combined pass is written as a plain RGB EXR for it first.

    python scripts/compare-blender.py LIGHTSPLIT.exr BLENDER.exr [SIDE_BY_SIDE.png]

The binary is target/release/lightsplit, or $LIGHTSPLIT.

Needs the OpenEXR and numpy modules (pip). Exit status 1 when a region's mean luminance differs
by more than 5%.
"""

import json
import os
import subprocess
import sys
import tempfile

import numpy as np
import OpenEXR


def channels(path):
    with OpenEXR.File(path, separate_channels=True) as f:
        return {k: np.asarray(v.pixels, dtype=np.float64) for k, v in f.channels().items()}


def rgb(ch, prefix=""):
    return np.stack([ch[prefix + c] for c in "RGB"], axis=-1)


def luminance(c):
    return c @ np.array([0.2126, 0.7152, 0.0722])


def main():
    ours, theirs = channels(sys.argv[1]), channels(sys.argv[2])
    a = rgb(ours)
    blender_prefix = next((k[: -len("R")] for k in theirs if k.endswith("Combined.R")), "")
    b = rgb(theirs, blender_prefix)
    if a.shape != b.shape:
        sys.exit(f"sizes differ: {a.shape} and {b.shape}")
    la, lb = luminance(a), luminance(b)
    binary = os.environ.get("LIGHTSPLIT", "target/release/lightsplit")
    with tempfile.TemporaryDirectory() as tmp:
        plain = os.path.join(tmp, "blender-rgb.exr")
        header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
        rgb_channels = {c: b[..., i].astype(np.float32) for i, c in enumerate("RGB")}
        with OpenEXR.File(header, rgb_channels) as f:
            f.write(plain)
        out = subprocess.run([binary, "compare", sys.argv[1], plain, "--by-object", "--json"],
                             check=True, capture_output=True, text=True).stdout
    worst = 0.0
    print(f"{'region':>10} {'pixels':>7} {'lightsplit':>28} {'blender':>28} {'ratio':>7}")
    for r in json.loads(out)["regions"]:
        # Pixels on a region's edge mix it with its neighbours differently in each renderer:
        # the binary's means and ratio are over its inner pixels alone.
        if r["inner"] < 20:
            continue
        ma, mb = np.array(r["test_mean"]), np.array(r["reference_mean"])
        # Black in Blender: they agree when lightsplit's is black too, and differ wholly when not.
        # (below 1e-4, a region's mean is black, whatever rounding left in it).
        black = luminance(ma) < 1e-4
        ratio = r["ratio"] if r["ratio"] is not None else (1.0 if black else float("inf"))
        print(f"{r['name']:>10} {r['inner']:>7} {np.array2string(ma, precision=4):>28} "
              f"{np.array2string(mb, precision=4):>28} {ratio:>7.3f}")
        worst = max(worst, abs(ratio - 1.0))
    agree = np.mean(np.abs(la - lb) <= 0.25 * np.maximum(lb, 0.05))
    print(f"layout: {100 * agree:.1f}% of pixels agree within 25%")
    print(f"worst region mean differs by {100 * worst:.1f}%")
    if len(sys.argv) > 3:
        def png(c):
            return (np.clip(c, 0, 1) ** (1 / 2.2) * 255).astype(np.uint8)
        side = np.concatenate([png(a), png(b)], axis=1)
        h, w, _ = side.shape
        with open(sys.argv[3], "wb") as f:
            import struct, zlib
            raw = b"".join(b"\0" + side[y].tobytes() for y in range(h))
            def chunk(t, d):
                return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d))
            f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
                    + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))
    sys.exit(1 if worst > 0.05 else 0)


if __name__ == "__main__":
    main()
