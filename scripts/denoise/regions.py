#!/usr/bin/env python3
"""Textured regions of the gallery, for scripts/bench-denoise.sh: do the filters keep them sharp?

    python3 regions.py FILM.exr REFERENCE.exr NAME=IMAGE... --crops OUT.png

Per region (objects picked by ID from FILM's objectid layer: the carpet, the three pictures,
the marble pedestal), for each IMAGE (EXR or PFM): RMSE and relMSE against the reference in the
region alone, and how much of the reference's fine detail the image keeps: the correlation of
its high-pass (the image minus its 3x3 box blur, inside the region) with the reference's. 1 is
all of it, 0 none (a blur); noise lowers it too. Prints a markdown table; writes crops of the
pictures and the pedestal on the carpet, side by side in the order given, the reference last.
"""

import argparse

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


def box3(x):
    p = np.pad(x, ((1, 1), (1, 1), (0, 0)), mode="edge")
    return sum(p[dy:dy + x.shape[0], dx:dx + x.shape[1]] for dy in range(3) for dx in range(3)) / 9.0


def srgb8(x):
    x = np.clip(x, 0.0, 1.0)
    y = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return (y * 255.0 + 0.5).astype(np.uint8)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("film")
    ap.add_argument("reference")
    ap.add_argument("images", nargs="+")
    ap.add_argument("--crops")
    args = ap.parse_args()
    film = load(args.film)
    ref = rgb(load(args.reference))
    obj = film["objectid.ID"]
    images = [(s.split("=", 1)[0], rgb(load(s.split("=", 1)[1]))) for s in args.images]
    hp_ref = ref - box3(ref)
    print("| region (pixels) | " + " | ".join(n for n, _ in images) + " |")
    print("|---|" + "---|" * len(images))
    for name, ids in REGIONS:
        # Inside the region and away from its border, so the high-pass sees the texture.
        mask = np.isin(obj, ids)
        inner = mask & np.isin(np.roll(obj, 1, 0), ids) & np.isin(np.roll(obj, -1, 0), ids)
        inner &= np.isin(np.roll(obj, 1, 1), ids) & np.isin(np.roll(obj, -1, 1), ids)
        cells = []
        for _, img in images:
            d = (img - ref)[mask]
            rmse = np.sqrt(np.mean(d ** 2))
            rel = np.mean(np.mean(d ** 2, axis=-1) / (np.mean(ref[mask], axis=-1) ** 2 + 1e-2))
            a, b = (img - box3(img))[inner].ravel(), hp_ref[inner].ravel()
            corr = float(np.dot(a, b) / np.sqrt(np.dot(a, a) * np.dot(b, b) + 1e-30))
            cells.append(f"{rmse:.2e} / {rel:.2e}, detail {corr:.2f}")
        print(f"| {name} ({int(mask.sum())}) | " + " | ".join(cells) + " |")
    if args.crops:
        import mitsuba as mi

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
