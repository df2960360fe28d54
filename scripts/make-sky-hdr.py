#!/usr/bin/env python3
"""Makes scenes/sky.hdr, the project's own small HDRI: a latitude-longitude map (512x256,
Radiance RGBE) of a clear afternoon sky with a few soft clouds, a sun 5 degrees across and a
ground lit by both. The sun is about 1000 times brighter than the sky and gives about three
times the sky's irradiance: the high dynamic range that makes sampling the map by its light
matter.

The orientation is lightsplit's (docs/scene-format.md, `environment`): the top row looks up, the
centre column along +x, columns turning from +x toward +z as they grow.

    python3 scripts/make-sky-hdr.py [OUT]     # default scenes/sky.hdr
"""

import math
import struct
import sys

WIDTH, HEIGHT = 512, 256
SUN_ELEVATION, SUN_AZIMUTH = math.radians(32.0), math.radians(-35.0)  # azimuth from +x toward +z
SUN_RADIUS = math.radians(2.5)
SUN_IRRADIANCE = 6.0  # W/m^2 at normal incidence, against about 2 from the sky on the ground
ZENITH, HORIZON = (0.18, 0.36, 0.85), (0.85, 0.88, 0.95)
GROUND_ALBEDO = (0.28, 0.24, 0.19)


def direction(u, v):
    phi, theta = 2.0 * math.pi * (u - 0.5), math.pi * v
    s = math.sin(theta)
    return (s * math.cos(phi), math.cos(theta), s * math.sin(phi))


def clouds(d):
    """Soft cloud cover in [0, 1]: a few sums of sines over the sky dome, thresholded."""
    x, z = d[0] / (d[1] + 0.25), d[2] / (d[1] + 0.25)
    n = (math.sin(2.1 * x + 0.3) * math.sin(1.7 * z + 1.1)
         + 0.5 * math.sin(4.3 * x - 2.0 * z + 0.7)
         + 0.25 * math.sin(8.9 * z + 3.1 * x + 2.3))
    return max(0.0, min(1.0, (n - 0.35) * 1.6))


sun = (math.cos(SUN_ELEVATION) * math.cos(SUN_AZIMUTH), math.sin(SUN_ELEVATION),
       math.cos(SUN_ELEVATION) * math.sin(SUN_AZIMUTH))
sun_radiance = SUN_IRRADIANCE / (2.0 * math.pi * (1.0 - math.cos(SUN_RADIUS)))
# Irradiance on the ground: the sun's, and a sky of mean radiance about 0.6 over the hemisphere.
ground_irradiance = SUN_IRRADIANCE * math.sin(SUN_ELEVATION) + math.pi * 0.6


def radiance(d):
    if d[1] < 0.0:
        # The ground: a Lambertian plane under sun and sky, a little darker toward the nadir.
        shade = ground_irradiance / math.pi * (1.0 - 0.3 * (-d[1]))
        return tuple(a * shade for a in GROUND_ALBEDO)
    cos_sun = sum(a * b for a, b in zip(d, sun))
    if cos_sun >= math.cos(SUN_RADIUS):
        return (sun_radiance, sun_radiance * 0.96, sun_radiance * 0.88)
    t = d[1] ** 0.5
    sky = [h + (z - h) * t for h, z in zip(HORIZON, ZENITH)]
    # A glow around the sun, and a brighter band at the horizon.
    glow = 0.9 * math.exp(-(1.0 - cos_sun) * 12.0) + 0.25 * math.exp(-d[1] * 10.0)
    sky = [c + glow * w for c, w in zip(sky, (1.0, 0.95, 0.85))]
    c = clouds(d)
    lit = 0.75 + 0.5 * max(cos_sun, 0.0)
    return tuple(s * (1.0 - c) + lit * c for s in sky)


def rgbe(r, g, b):
    v = max(r, g, b)
    if v < 1e-32:
        return b"\0\0\0\0"
    m, e = math.frexp(v)
    scale = m * 256.0 / v
    return bytes([min(255, int(r * scale + 0.5)), min(255, int(g * scale + 0.5)),
                  min(255, int(b * scale + 0.5)), e + 128])


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else "scenes/sky.hdr"
    rows = []
    for y in range(HEIGHT):
        row = bytearray()
        for x in range(WIDTH):
            # 2x2 samples a pixel, so the sun's edge is smooth.
            acc = [0.0, 0.0, 0.0]
            for sy in (0.25, 0.75):
                for sx in (0.25, 0.75):
                    c = radiance(direction((x + sx) / WIDTH, (y + sy) / HEIGHT))
                    acc = [a + b / 4.0 for a, b in zip(acc, c)]
            row += rgbe(*acc)
        rows.append(bytes(row))
    header = f"#?RADIANCE\n# made by lightsplit's scripts/make-sky-hdr.py\nFORMAT=32-bit_rle_rgbe\n\n-Y {HEIGHT} +X {WIDTH}\n"
    with open(out, "wb") as f:
        f.write(header.encode("ascii"))
        for row in rows:
            f.write(row)
    print(f"wrote {out} ({WIDTH}x{HEIGHT})")


if __name__ == "__main__":
    main()
