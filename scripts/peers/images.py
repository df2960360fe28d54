#!/usr/bin/env python3
"""Image means for scripts/bench-peers.sh.

    python3 images.py mean IMAGE [--as-tutorial-ppm]
    python3 images.py noise IMAGE [--as-tutorial-ppm]

Prints the mean over pixels and R, G, B of IMAGE: an OpenEXR or PFM file (its R, G, B channels,
read with Mitsuba's Bitmap; lightsplit's other EXR layers are ignored) as linear values, or a
binary PPM (P6, 8 bit) as byte / 255.

--as-tutorial-ppm first encodes a linear image the way Embree's pathtracer tutorial writes its PPM,
so that the two can be compared in the same space: the tutorial stores each pixel's average
linearly (no gamma) as the byte trunc(255.01 * clamp(x, 0, 1)) in single precision, and its PPM
writer turns the byte back to a float (times 1/255) and out again (times 255, truncated), which
gives back the same byte for all 256 values. The mean of those bytes / 255 is printed.

`noise` prints an estimate of the standard error of that mean from the render's own noise: each
pixel's variance taken as half the mean squared difference of horizontally adjacent pixels (an
overestimate where the image has edges), the pixels independent.
"""

import argparse
import sys

import numpy as np


def read_ppm(path):
    with open(path, "rb") as f:
        data = f.read()
    # Header: magic, width, height, maxval, separated by whitespace (comments allowed).
    fields, pos = [], 0
    while len(fields) < 4:
        while data[pos:pos + 1].isspace():
            pos += 1
        if data[pos:pos + 1] == b"#":
            pos = data.index(b"\n", pos) + 1
            continue
        start = pos
        while not data[pos:pos + 1].isspace():
            pos += 1
        fields.append(data[start:pos])
    pos += 1  # the single whitespace after maxval
    if fields[0] != b"P6" or int(fields[3]) != 255:
        raise ValueError(f"{path}: not an 8-bit binary PPM (P6, maxval 255)")
    w, h = int(fields[1]), int(fields[2])
    pixels = np.frombuffer(data, dtype=np.uint8, count=w * h * 3, offset=pos)
    return pixels.reshape(h, w, 3).astype(np.float64) / 255.0


def read_float_rgb(path):
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    bitmap = mi.Bitmap(path)
    names = [bitmap.struct_()[i].name for i in range(bitmap.channel_count())]
    array = np.array(bitmap, copy=False)
    array = array.reshape(bitmap.height(), bitmap.width(), bitmap.channel_count())
    try:
        rgb = [names.index(c) for c in ("R", "G", "B")]
    except ValueError:
        raise ValueError(f"{path}: no R, G, B channels (it has {', '.join(names)})") from None
    return array[:, :, rgb].astype(np.float32)


def tutorial_bytes(linear):
    """The bytes Embree's pathtracer tutorial writes for these linear pixel values."""
    x = np.clip(np.nan_to_num(linear.astype(np.float32), nan=0.0), np.float32(0), np.float32(1))
    first = np.floor(np.float32(255.01) * x).astype(np.uint8)
    # The PPM writer's round trip through Color4 (byte * (1/255)) and back (* 255, truncated).
    back = (first.astype(np.float32) * (np.float32(1) / np.float32(255))).astype(np.float32)
    return np.floor(np.clip(back, 0, 1) * np.float32(255)).astype(np.uint8)


def noise(image):
    """Standard error of the image mean, from differences of horizontally adjacent pixels."""
    c = image.astype(np.float64).mean(axis=2)
    if c.shape[1] < 2:
        return float("nan")
    variance = np.mean((c[:, 1:] - c[:, :-1]) ** 2) / 2
    return float(np.sqrt(variance / c.size))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="command", required=True)
    for name in ("mean", "noise"):
        m = sub.add_parser(name)
        m.add_argument("image")
        m.add_argument("--as-tutorial-ppm", action="store_true")
    a = ap.parse_args()
    try:
        if a.image.lower().endswith(".ppm"):
            if a.as_tutorial_ppm:
                raise ValueError("--as-tutorial-ppm applies to a linear EXR or PFM")
            image = read_ppm(a.image)
        else:
            image = read_float_rgb(a.image)
            if a.as_tutorial_ppm:
                image = tutorial_bytes(image).astype(np.float64) / 255.0
        if not np.all(np.isfinite(image)):
            raise ValueError(f"{a.image}: has non-finite values")
    except (OSError, ValueError, RuntimeError) as e:
        print(f"images: {e}", file=sys.stderr)
        sys.exit(1)
    value = noise(image) if a.command == "noise" else float(np.mean(image, dtype=np.float64))
    print(f"{value:.6g}")


if __name__ == "__main__":
    main()
