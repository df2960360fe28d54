#!/usr/bin/env python3
"""Intel Open Image Denoise on a lightsplit render, for scripts/bench-denoise.sh.

    python3 oidn.py FILM.exr OUT.pfm [--layer raw] [--threads 2]

Reads the beauty (or another RGB layer) of a lightsplit EXR and its first-hit guides, the albedo
and normal layers (averages over the pixel's samples, so left as they are: cleanAux off), runs
OIDN's "RT" filter in HDR mode on the CPU, and writes the result as a PFM. Prints one JSON line:
{"seconds": the filter's execution time, without reading and writing}. A comparison peer only:
lightsplit never depends on it.
"""

import argparse
import json
import sys
import time

import numpy as np


def read_layers(path, names):
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    bitmap = mi.Bitmap(path)
    channels = [bitmap.struct_()[i].name for i in range(bitmap.channel_count())]
    array = np.array(bitmap, copy=False).reshape(bitmap.height(), bitmap.width(), bitmap.channel_count())
    out = {}
    for name, suffixes in names.items():
        prefix = "" if name == "" else name + "."
        try:
            idx = [channels.index(prefix + s) for s in suffixes]
        except ValueError:
            sys.exit(f"{path}: no {name or 'RGB'} layer (channels: {', '.join(channels)})")
        out[name] = np.ascontiguousarray(array[:, :, idx], dtype=np.float32)
    return out


def write_pfm(path, rgb):
    h, w, _ = rgb.shape
    with open(path, "wb") as f:
        f.write(f"PF\n{w} {h}\n-1.0\n".encode())
        # PFM stores rows bottom-up, little-endian.
        f.write(np.ascontiguousarray(rgb[::-1], dtype="<f4").tobytes())


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("film")
    ap.add_argument("out")
    ap.add_argument("--layer", default="raw", help="the RGB layer to denoise (default: raw, the beauty)")
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    if not args.out.endswith(".pfm"):
        sys.exit("the output must be a .pfm")

    import pyoidn

    layers = read_layers(args.film, {args.layer: "RGB", "albedo": "RGB", "normal": "XYZ"})
    color = layers[args.layer]
    albedo = np.clip(layers["albedo"], 0.0, 1.0)
    normal = np.clip(layers["normal"], -1.0, 1.0)
    output = np.zeros_like(color)

    device = pyoidn.Device()
    device.set_int("numThreads", args.threads)
    device.commit()
    filt = pyoidn.Filter(device, "RT")
    filt.set_image(pyoidn.OIDN_IMAGE_COLOR, color, pyoidn.OIDN_FORMAT_FLOAT3)
    filt.set_image(pyoidn.OIDN_IMAGE_ALBEDO, albedo, pyoidn.OIDN_FORMAT_FLOAT3)
    filt.set_image(pyoidn.OIDN_IMAGE_NORMAL, normal, pyoidn.OIDN_FORMAT_FLOAT3)
    filt.set_image(pyoidn.OIDN_IMAGE_OUTPUT, output, pyoidn.OIDN_FORMAT_FLOAT3)
    # set_bool: the generic setter would take True for an int.
    filt.set_bool("hdr", True)
    filt.commit()
    start = time.perf_counter()
    filt.execute()
    seconds = time.perf_counter() - start
    error = device.get_error()
    if error is not None:
        sys.exit(f"OIDN: {error}")
    write_pfm(args.out, output)
    print(json.dumps({"seconds": seconds}))


if __name__ == "__main__":
    main()
