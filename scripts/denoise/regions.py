#!/usr/bin/env python3
"""Textured regions of the gallery, for scripts/bench-denoise.sh: do the filters keep them sharp?

    python3 regions.py FILM.exr REFERENCE.exr NAME=IMAGE... --crops OUT.png

Per region (objects picked by ID from FILM's objectid layer: the carpet, the three pictures,
the marble pedestal), for each IMAGE (EXR or PFM): RMSE and relMSE against the reference in the
region alone, and how much of the reference's fine detail the image keeps: the correlation of
its high-pass (the image minus its 3x3 box blur, inside the region) with the reference's. 1 is
all of it, 0 none (a blur); noise lowers it too. The figures are the binary's own, with its
definitions: relMSE per channel as `compare` has it (before, this script divided each pixel's
mean squared error by its mean value squared), and a pixel on the image's edge inner when its
neighbours inside the image are in the region (before, they wrapped around). They come from
`lightsplit compare --ids FILM --region NAME=IDS --json`; this script prints them as a markdown
table and writes crops of the pictures and the pedestal on the carpet, side by side in the order
given, the reference last.
"""

import argparse
import json
import subprocess

import numpy as np

REGIONS = [("carpet", [0]), ("pictures", [6, 7, 8]), ("marble pedestal", [9])]


def load(path):
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    b = mi.Bitmap(path)
    names = [b.struct_()[i].name for i in range(b.channel_count())]
    a = np.array(b, copy=False).reshape(b.height(), b.width(), b.channel_count()).astype(np.float64)
    return {n: a[:, :, i] for i, n in enumerate(names)}


def rgb(layers):
    return np.stack([layers[c] for c in "RGB"], -1)


def srgb8(x):
    x = np.clip(x, 0.0, 1.0)
    y = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return (y * 255.0 + 0.5).astype(np.uint8)


def regions(binary, film, image, reference):
    """The binary's per-region errors of `image` against `reference`, by `film`'s object IDs."""
    flags = [f"--region={name}={','.join(map(str, ids))}" for name, ids in REGIONS]
    out = subprocess.run([binary, "compare", image, reference, "--ids", film, *flags, "--json"],
                         check=True, capture_output=True, text=True).stdout
    return {r["name"]: r for r in json.loads(out)["regions"]}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("film")
    ap.add_argument("reference")
    ap.add_argument("images", nargs="+")
    ap.add_argument("--crops")
    ap.add_argument("--bin", default="target/release/lightsplit", help="the lightsplit binary")
    args = ap.parse_args()
    named = [(s.split("=", 1)[0], s.split("=", 1)[1]) for s in args.images]
    rows = [(name, regions(args.bin, args.film, path, args.reference)) for name, path in named]
    print("| region (pixels) | " + " | ".join(n for n, _ in named) + " |")
    print("|---|" + "---|" * len(named))
    for name, _ in REGIONS:
        cells = []
        for _, r in rows:
            detail = "-" if r[name]["detail"] is None else f"{r[name]['detail']:.2f}"
            cells.append(f"{r[name]['rmse']:.2e} / {r[name]['relmse']:.2e}, detail {detail}")
        print(f"| {name} ({rows[0][1][name]['pixels']}) | " + " | ".join(cells) + " |")
    if args.crops:
        import mitsuba as mi

        ref = rgb(load(args.reference))
        images = [(n, rgb(load(p))) for n, p in named]

        # The middle picture with the teapot and pedestal, and the carpet in front.
        h, w = ref.shape[:2]
        y0, y1, x0, x1 = int(0.35 * h), int(0.75 * h), int(0.38 * w), int(0.62 * w)
        tiles = [img[y0:y1, x0:x1] for _, img in images] + [ref[y0:y1, x0:x1]]
        gap = np.ones((y1 - y0, 2, 3))
        row = np.concatenate(sum(([t, gap] for t in tiles), [])[:-1], axis=1)
        row = np.repeat(np.repeat(row, 3, axis=0), 3, axis=1)  # 3x, nearest: pixels stay pixels
        mi.Bitmap(srgb8(row)).write(args.crops)


if __name__ == "__main__":
    main()
