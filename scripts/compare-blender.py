"""Compares lightsplit's render of a glTF with Blender's (scripts/blender-gltf.py), both linear
EXRs of the same camera and size: per region (lightsplit's object IDs; the background is its own
region), the mean colour of each image and their ratio, and the layout (the fraction of pixels
whose two values agree within 25%, which a shifted or mirrored object would lower).

    python scripts/compare-blender.py LIGHTSPLIT.exr BLENDER.exr [SIDE_BY_SIDE.png]

Needs the OpenEXR and numpy modules (pip). Exit status 1 when a region's mean luminance differs
by more than 5%.
"""

import sys

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
    ids = ours["objectid.ID"].astype(int)
    la, lb = luminance(a), luminance(b)
    worst = 0.0
    print(f"{'region':>10} {'pixels':>7} {'lightsplit':>28} {'blender':>28} {'ratio':>7}")
    for region in sorted(set(ids.ravel())):
        m = ids == region
        # Pixels on a region's edge mix it with its neighbours differently in each renderer:
        # only pixels whose four neighbours are in the same region count.
        inner = m.copy()
        inner[1:, :] &= m[:-1, :]
        inner[:-1, :] &= m[1:, :]
        inner[:, 1:] &= m[:, :-1]
        inner[:, :-1] &= m[:, 1:]
        if inner.sum() < 20:
            continue
        ma, mb = a[inner].mean(axis=0), b[inner].mean(axis=0)
        ratio = luminance(ma) / max(luminance(mb), 1e-9)
        name = "background" if region < 0 else f"object {region}"
        print(f"{name:>10} {inner.sum():>7} {np.array2string(ma, precision=4):>28} "
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
