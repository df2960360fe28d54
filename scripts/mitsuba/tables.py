"""Prints the numbers lightsplit's Mitsuba reader takes from Mitsuba 3 itself (scalar_rgb):
the CIE 1931 colour matching functions and D65 at 5 nm, as Mitsuba tabulates them (for turning a
scene's <spectrum> into RGB as Mitsuba's RGB variants do), and the conductors' complex indices
of refraction reduced to RGB. Run with the peers' venv Python, which has `mitsuba`:

    python scripts/mitsuba/tables.py cie > src/scene/mitsuba/cie.rs
    python scripts/mitsuba/tables.py conductors
"""
import sys

import mitsuba as mi

mi.set_variant("scalar_rgb")


def cie():
    lo, hi = int(mi.MI_CIE_MIN), int(mi.MI_CIE_MAX)
    ws = list(range(lo, hi + 1, 5))
    print("//! The CIE 1931 2-degree colour matching functions and the D65 illuminant at 5 nm from")
    print(f"//! {lo} to {hi} nm, as Mitsuba {mi.__version__} evaluates them (`cie1931_xyz`, `cie_d65`),")
    print("//! printed by `scripts/mitsuba/tables.py cie`.")
    print()
    print(f"pub const MIN: f64 = {lo}.0;")
    print(f"pub const MAX: f64 = {hi}.0;")
    print(f"pub const Y_NORMALIZATION: f64 = {mi.MI_CIE_Y_NORMALIZATION!r};")
    print()
    print(f"pub const XYZ: [[f64; 3]; {len(ws)}] = [")
    for w in ws:
        x = mi.cie1931_xyz(float(w))
        print(f"    [{x[0]!r}, {x[1]!r}, {x[2]!r}],")
    print("];")
    print()
    print(f"pub const D65: [f64; {len(ws)}] = [")
    for w in ws:
        print(f"    {float(mi.cie_d65(float(w)))!r},")
    print("];")


def conductors():
    names = ("a-C Ag Al AlAs AlAs_palik AlSb Au Be Cr CsI Cu Cu2O CuO d-C Hg HgTe Ir K Li MgO Mo "
             "Na_palik Nb Ni_palik Rh Se SiC SnTe Ta Te ThF4 TiC TiN TiO2 VC V_palik VN W").split()
    for n in names:
        p = mi.traverse(mi.load_dict({"type": "conductor", "material": n}))
        e, k = p["eta.value"], p["k.value"]
        print(f'    ("{n}", [{e[0]:.6}, {e[1]:.6}, {e[2]:.6}], [{k[0]:.6}, {k[1]:.6}, {k[2]:.6}]),')


{"cie": cie, "conductors": conductors}[sys.argv[1]]()
