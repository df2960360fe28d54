#!/usr/bin/env python3
"""Issue 40's check that a real client reads lightsplit's Cryptomatte mattes: for every name in
each Cryptomatte type of a lightsplit EXR (`render --cryptomatte`), the matte Blender's
compositor makes (scripts/peers/cryptomatte_blender.py) against the matte `lightsplit matte`
reads from the same file. Runs in the peers' Python (bpy 5, numpy):

    python cryptomatte_check.py --lightsplit BIN --exr IN.exr --out DIR [--types T,T]

A name passes when its two mattes differ by at most 1/255 on at least 99.9% of the pixels.
Prints one JSON object: {"rows": [{"type", "name", "pixels_covered", "within", "max_difference",
"pass"}, ...], "skipped": [names Blender cannot ask for], "blender": version}, and writes the
same as Markdown table rows to OUT/rows.md (first column --label). Exit status 0 when every
name passes, 1 when one does not or a tool fails, 2 on bad arguments.
"""

import argparse
import json
import os
import subprocess
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from cryptomatte_blender import exr_header  # noqa: E402

TOLERANCE = 1 / 255
SHARE = 0.999


def read_pfm(path):
    """A PFM's first channel, row 0 at the top (PFM stores the bottom row first)."""
    with open(path, "rb") as f:
        kind = f.readline().strip()
        width, height = map(int, f.readline().split())
        scale = float(f.readline())
        data = np.fromfile(f, dtype="<f4" if scale < 0 else ">f4")
    channels = 3 if kind == b"PF" else 1
    return data.reshape(height, width, channels)[::-1, :, 0]


def manifests(path):
    """{type name: [names]} from the EXR's cryptomatte/<key>/name and .../manifest attributes."""
    header = exr_header(path)
    text = {k: v[1].rstrip(b"\0").decode("utf-8") for k, v in header.items() if k.startswith("cryptomatte/")}
    out = {}
    for key, value in text.items():
        if key.endswith("/name"):
            manifest = text.get(key[: -len("name")] + "manifest", "{}")
            out[value] = sorted(json.loads(manifest))
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--lightsplit", required=True, help="the lightsplit binary")
    p.add_argument("--exr", required=True, help="a lightsplit render with --cryptomatte")
    p.add_argument("--out", required=True, help="directory for the mattes")
    p.add_argument("--types", default="CryptoObject,CryptoMaterial", help="the types to check, commas")
    p.add_argument("--label", default="", help="the first column of OUT/rows.md (the scene)")
    a = p.parse_args()
    if not os.path.isfile(a.exr):
        p.error(f"no file {a.exr}")
    found = manifests(a.exr)
    rows, skipped, blender = [], [], None
    for kind in a.types.split(","):
        if kind not in found:
            print(f"cryptomatte_check: error: {a.exr} has no Cryptomatte type {kind}", file=sys.stderr)
            sys.exit(1)
        names = [n for n in found[kind] if n and "," not in n and n == n.strip(" ") and "/" not in n]
        skipped += [f"{kind}:{n}" for n in found[kind] if n not in names]
        out = os.path.join(a.out, kind)
        os.makedirs(out, exist_ok=True)
        args = [sys.executable, os.path.join(os.path.dirname(os.path.abspath(__file__)), "cryptomatte_blender.py"),
                "--exr", a.exr, "--type", kind, "--out", out]
        for n in names:
            args += ["--name", n]
        done = subprocess.run(args, capture_output=True, text=True)
        if done.returncode != 0:
            print(done.stderr, file=sys.stderr)
            sys.exit(1)
        result = json.loads(done.stdout.strip().splitlines()[-1])
        blender = result["blender"]
        for i, name in enumerate(names):
            pfm = os.path.join(out, f"lightsplit-{i}.pfm")
            subprocess.run([a.lightsplit, "matte", a.exr, name, "--type", kind, "-o", pfm],
                           check=True, capture_output=True)
            ours, theirs = read_pfm(pfm), np.load(result["mattes"][name])
            if ours.shape != theirs.shape:
                print(f"cryptomatte_check: error: {name}: {ours.shape} against {theirs.shape}", file=sys.stderr)
                sys.exit(1)
            diff = np.abs(ours.astype(np.float64) - theirs)
            within = float(np.mean(diff <= TOLERANCE))
            rows.append({"type": kind, "name": name, "pixels_covered": int(np.count_nonzero(ours)),
                         "within": within, "max_difference": float(diff.max()), "pass": within >= SHARE})
    print(json.dumps({"rows": rows, "skipped": skipped, "blender": blender}))
    with open(os.path.join(a.out, "rows.md"), "w") as f:
        for r in rows:
            verdict = "pass" if r["pass"] else "FAIL"
            f.write(f"| {a.label} | {r['type']} | {r['name']} | {r['pixels_covered']} | "
                    f"{100 * r['within']:.2f}% | {r['max_difference']:.2e} | {verdict} |\n")
        for s in skipped:
            kind, name = s.split(":", 1)
            f.write(f"| {a.label} | {kind} | {name} | | | | skipped: Blender cannot ask for it |\n")
    sys.exit(0 if all(r["pass"] for r in rows) and rows else 1)


if __name__ == "__main__":
    main()
