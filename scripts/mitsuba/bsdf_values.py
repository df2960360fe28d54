#!/usr/bin/env python3
"""Prints Mitsuba 3's own values (scalar_rgb) of the BSDFs lightsplit reads from Mitsuba files,
for the test `mitsuba_bsdfs_agree_with_mitsubas_own_values` in src/render/bsdf/tests.rs: each
case's f(wi, wo) cos(wo) at a handful of direction pairs, as Rust literals to paste there.

    python3 scripts/mitsuba/bsdf_values.py      (with Mitsuba installed: pip install mitsuba)

Directions are local (z the normal). Mitsuba's si.wi is lightsplit's `wo` (towards the viewer)
and Mitsuba's `wo` is lightsplit's `wi` (towards the light).
"""

import math

import mitsuba as mi

mi.set_variant("scalar_rgb")

CASES = [
    ("ggx_conductor", {"type": "roughconductor", "distribution": "ggx", "alpha": 0.3,
                       "eta": {"type": "rgb", "value": [0.2, 0.9, 1.1]},
                       "k": {"type": "rgb", "value": [3.9, 2.4, 2.2]}}),
    ("beckmann_anisotropic", {"type": "roughconductor", "distribution": "beckmann",
                              "alpha_u": 0.1, "alpha_v": 0.4, "material": "Au"}),
    ("rough_plastic", {"type": "roughplastic", "distribution": "ggx", "alpha": 0.2, "int_ior": 1.5,
                       "diffuse_reflectance": {"type": "rgb", "value": [0.5, 0.3, 0.1]}}),
    ("smooth_plastic", {"type": "plastic", "int_ior": 1.6,
                        "diffuse_reflectance": {"type": "rgb", "value": [0.2, 0.6, 0.4]}}),
]


# A rough glass seen from outside (the view above) and from inside (below): reflection, and
# transmission (the light on the other side: theta over 90 degrees).
GLASS = {"type": "roughdielectric", "distribution": "ggx", "alpha": 0.2, "int_ior": 1.5}
GLASS_PAIRS = {
    "rough_glass_outside": [((10, 0), (15, 180)), ((40, 30), (50, 200)), ((10, 0), (160, 180)),
                            ((40, 30), (140, 200)), ((60, 90), (150, 260))],
    "rough_glass_inside": [((170, 0), (165, 180)), ((160, 30), (140, 200)), ((170, 0), (20, 180)),
                           ((160, 30), (40, 200)), ((150, 90), (15, 260))],
}


def direction(theta, phi):
    t, p = math.radians(theta), math.radians(phi)
    return [math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)]


PAIRS = [((10, 0), (15, 180)), ((40, 30), (50, 200)), ((70, 90), (20, 270)), ((30, 0), (60, 100)), ((5, 0), (80, 45))]

def print_values(name, spec, pairs):
    """Prints `spec`'s f cos at each pair of (view, light) directions, as Rust rows."""
    bsdf = mi.load_dict(spec)
    ctx = mi.BSDFContext()
    print(f"// {name}")
    for (a, b) in pairs:
        si = mi.SurfaceInteraction3f()
        si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
        si.wi = mi.Vector3f(*direction(*a))
        v = bsdf.eval(ctx, si, mi.Vector3f(*direction(*b)))
        print(f"(({a[0]:.1f}, {a[1]:.1f}), ({b[0]:.1f}, {b[1]:.1f}), [{v[0]:.5e}, {v[1]:.5e}, {v[2]:.5e}]),")


for name, spec in CASES:
    print_values(name, spec, PAIRS)
for name, pairs in GLASS_PAIRS.items():
    print_values(name, GLASS, pairs)

# White furnaces: the mean sample weight (with its standard error) of the white rough
# conductors (`none`: eta 0, k 1) at view angles 0, 45 and 80 degrees, azimuth 10, for
# `mitsuba_bsdfs_sample_their_density_are_reciprocal_and_keep_energy`.
import random

random.seed(1)
FURNACES = [
    ("rough_glass", GLASS),
    ("white_rough_ggx", {"type": "roughconductor", "distribution": "ggx", "alpha": 0.5}),
    ("white_rough_beckmann", {"type": "roughconductor", "distribution": "beckmann", "alpha_u": 0.2, "alpha_v": 0.6}),
]
for name, spec in FURNACES:
    bsdf = mi.load_dict(spec)
    ctx = mi.BSDFContext()
    row = []
    for theta in (0.0, 45.0, 80.0):
        si = mi.SurfaceInteraction3f()
        si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
        si.wi = mi.Vector3f(*direction(theta, 10.0))
        n, s, s2 = 100000, 0.0, 0.0
        for _ in range(n):
            bs, w = bsdf.sample(ctx, si, random.random(), mi.Point2f(random.random(), random.random()))
            # Radiance crossing into the glass is divided by eta^2: counted back, so a white
            # boundary that loses nothing scores 1.
            v = w[0] * (bs.eta * bs.eta if bs.eta != 1.0 else 1.0)
            s += v
            s2 += v * v
        mean = s / n
        row.append(f"({mean:.5f}, {math.sqrt(max(s2 / n - mean * mean, 0.0) / n):.5f})")
    print(f'("{name}", [{", ".join(row)}]),')
