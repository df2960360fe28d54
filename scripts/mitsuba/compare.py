#!/usr/bin/env python3
"""Renders Mitsuba XML scenes in lightsplit and in Mitsuba 3 (scalar_rgb) from the same file, and
writes a Markdown table: the channel means of both high-spp references, the worst 32x32 block,
and the render time each needs to reach the same relative RMSE against its own reference.

Run by scripts/compare-mitsuba.sh (which makes the virtual environment); by hand:

    python3 compare.py --lightsplit BIN --out DIR [options] SCENE.xml...

For each scene a copy of the file is written beside it (`.compare-NAME.xml`, removed at the end,
so that its relative paths resolve as the original's do), its includes inlined and its
parameters substituted, with only these changes: the film's size scaled to --size pixels on
its longer side (the aspect kept), the sampler's type and count, and the film's
`high_quality_edges` (a Mitsuba 2 property that Mitsuba 3 refuses) left out. Both programs render that copy. Everything else (camera, filter, integrator and its
max_depth, materials) is the scene's own.

- References: lightsplit at --reference-spp with its default sampler, Mitsuba at --reference-spp
  with `independent` (unbiased, and the same in expectation whatever the sampler).
- Agreement: `lightsplit compare --blocks 32` of lightsplit's reference against Mitsuba's.
  Channel means within 0.5% and every block within 2% pass; the noise of the two references
  is given beside them (the standard error of the worst block's mean, from each reference's
  own pixel differences), since a block cannot agree better than its noise.
- Equal-error time: each program renders at each of --spp (lightsplit with its default
  sampler; Mitsuba with each of `independent`, `stratified` and `multijitter`), timed: the
  render alone, no scene loading (lightsplit's own "in S s", Mitsuba's mi.render). The relative
  RMSE (the square root of the per-pixel relative MSE, so that a few bright pixels do not
  decide it) against its own reference is measured with `lightsplit compare`; the time to reach the target error is read off the log-log line
  through the measured points (extended with slope -1/2 past the ends). The target is the
  error Mitsuba's best sampler reaches at the middle of --spp. Rounds alternate the programs.

Exit status: 0 when every scene rendered (the verdicts are in the table), 1 when a program
failed, 2 on bad arguments.
"""

import argparse
import json
import math
import os
import re
import subprocess
import sys
import time
import xml.etree.ElementTree as ET

MITSUBA_SAMPLERS = ["independent", "stratified", "multijitter"]
MEANS_LIMIT = 0.005
BLOCK_LIMIT = 0.02


def fail(message, status=1):
    print(f"compare-mitsuba: error: {message}", file=sys.stderr)
    sys.exit(status)


def note(message):
    print(f"compare-mitsuba: {message}", file=sys.stderr, flush=True)


def inlined(path, top_dir, params, depth=0):
    """The root of `path` with its <include>s spliced in (each resolved against the top file's
    directory, as Mitsuba's resolver does) and its <default>s gathered into `params` (the
    first of a name wins), removed from the tree."""
    if depth > 15:
        fail(f"{path}: includes nest deeper than 15", 2)
    root = ET.parse(path).getroot()
    out = []
    for child in list(root):
        if child.tag == "default":
            params.setdefault(child.get("name"), child.get("value"))
        elif child.tag == "include":
            name = child.get("filename")
            included = inlined(os.path.join(top_dir, name), top_dir, params, depth + 1)
            out.extend(list(included) if included.tag == "scene" else [included])
        else:
            out.append(child)
    for child in list(root):
        root.remove(child)
    root.extend(out)
    return root


def substitute(node, params):
    for k, v in node.attrib.items():
        for name in sorted(params, key=len, reverse=True):
            v = v.replace("$" + name, params[name])
        node.set(k, v)
    for child in node:
        substitute(child, params)


def scaled_copy(scene, size, sampler, spp):
    """The copy of `scene` (its includes inlined, its parameters substituted) with its film at
    most `size` pixels on a side and its sampler `sampler` with `spp` samples; returns its
    path."""
    params = {}
    root = inlined(scene, os.path.dirname(os.path.abspath(scene)), params)
    substitute(root, params)
    tree = ET.ElementTree(root)
    sensors = root.findall("sensor")
    if not sensors:
        fail(f"{scene}: no <sensor> at the top of the file (an included sensor cannot be resized)", 2)
    sensor = sensors[0]
    film = sensor.find("film")
    if film is None:
        film = ET.SubElement(sensor, "film", {"type": "hdrfilm"})
    # Mitsuba 2's film property that Mitsuba 3 refuses as unreferenced (Bitterli's files have it).
    for node in film.findall("boolean[@name='high_quality_edges']"):
        film.remove(node)
    dims = {}
    for name in ("width", "height"):
        node = film.find(f"integer[@name='{name}']")
        if node is None:
            node = ET.SubElement(film, "integer", {"name": name, "value": "768" if name == "width" else "576"})
        value = node.get("value", "")
        dims[name] = (node, int(value))
    (wn, w), (hn, h) = dims["width"], dims["height"]
    scale = size / max(w, h)
    wn.set("value", str(max(1, round(w * scale))))
    hn.set("value", str(max(1, round(h * scale))))
    old = sensor.find("sampler")
    if old is not None:
        sensor.remove(old)
    s = ET.SubElement(sensor, "sampler", {"type": sampler})
    ET.SubElement(s, "integer", {"name": "sample_count", "value": str(spp)})
    stem = os.path.splitext(os.path.basename(scene))[0]
    path = os.path.join(os.path.dirname(os.path.abspath(scene)), f".compare-{stem}-{sampler}.xml")
    tree.write(path)
    return path


def lightsplit_render(binary, scene, spp, out, threads):
    args = [binary, "render", scene, "--spp", str(spp), "-o", out, "--threads", str(threads)]
    r = subprocess.run(args, capture_output=True, text=True)
    if r.returncode != 0:
        fail(f"{' '.join(args)} failed:\n{r.stderr}")
    m = re.search(r" in ([0-9.]+) s \(", r.stderr + r.stdout)
    if not m:
        fail(f"no render time in lightsplit's output:\n{r.stderr}")
    return float(m.group(1))


def mitsuba_render(mi, scene, spp, out, seed):
    loaded = mi.load_file(scene)
    start = time.perf_counter()
    image = mi.render(loaded, spp=spp, seed=seed)
    seconds = time.perf_counter() - start
    mi.Bitmap(image).write(out)
    return seconds


def compare(binary, test, reference, blocks=None):
    args = [binary, "compare", test, reference, "--json"] + (["--blocks", str(blocks)] if blocks else [])
    r = subprocess.run(args, capture_output=True, text=True)
    if r.returncode != 0:
        fail(f"{' '.join(args)} failed:\n{r.stderr}")
    return json.loads(r.stdout)


def relative_rmse(binary, test, reference):
    """The relative RMSE: the square root of `lightsplit compare`'s relMSE, the mean over
    pixels and channels of (x - y)^2 / (y^2 + 0.01), so every pixel counts by its own
    brightness rather than the brightest ones deciding."""
    return math.sqrt(compare(binary, test, reference)["relmse"])


def time_to(points, target):
    """The time at which the log-log line through (time, error) points reaches `target`."""
    points = sorted(points)
    logs = [(math.log(t), math.log(e)) for t, e in points if t > 0 and e > 0]
    lt = math.log(target)
    for (t0, e0), (t1, e1) in zip(logs, logs[1:]):
        if (e0 - lt) * (e1 - lt) <= 0 and e0 != e1:
            return math.exp(t0 + (lt - e0) * (t1 - t0) / (e1 - e0))
    # Past the ends: error ~ time^(-1/2) from the nearer end.
    t, e = logs[0] if lt > logs[0][1] else logs[-1]
    return math.exp(t - 2.0 * (lt - e))


def block_noise(mi, np, path, at, block):
    """The standard error of the mean of one block of a render, from its own noise (each
    pixel's variance as half the mean squared difference of horizontal neighbours)."""
    image = np.array(mi.Bitmap(path), copy=False)[..., :3].astype(np.float64)
    x0, y0 = at
    b = image[y0:y0 + block, x0:x0 + block]
    d = b[:, 1:] - b[:, :-1]
    var = 0.5 * np.mean(d * d, axis=(0, 1))
    mean = np.mean(b, axis=(0, 1))
    n = b.shape[0] * b.shape[1]
    return float(np.max(np.sqrt(var / n) / np.maximum(mean, 1e-12)))


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scenes", nargs="+")
    p.add_argument("--lightsplit", required=True)
    p.add_argument("--out", required=True)
    p.add_argument("--size", type=int, default=256)
    p.add_argument("--reference-spp", type=int, default=1024)
    p.add_argument("--spp", default="4,16,64")
    p.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    p.add_argument("--rounds", type=int, default=1)
    p.add_argument("--table", help="write the Markdown table here too")
    a = p.parse_args()
    try:
        spps = [int(s) for s in a.spp.split(",")]
    except ValueError:
        fail("--spp takes numbers separated by commas", 2)
    if a.size < 8 or a.reference_spp < 1 or any(s < 1 for s in spps) or a.threads < 1 or a.rounds < 1:
        fail("--size (8 or more), --reference-spp, --spp, --threads and --rounds must be positive", 2)
    for s in a.scenes:
        if not os.path.isfile(s):
            fail(f"{s} is not a file", 2)

    import mitsuba as mi
    import numpy as np

    mi.set_variant("scalar_rgb")
    mi.set_log_level(mi.LogLevel.Warn)
    import drjit as dr

    # Both programs get the same threads (Mitsuba renders on Dr.Jit's process-wide pool).
    dr.set_thread_count(a.threads)
    os.makedirs(a.out, exist_ok=True)
    rows = []
    # Each scene by its path from the directory the scenes share (two files may share a name).
    paths = [os.path.abspath(s) for s in a.scenes]
    common = os.path.commonpath([os.path.dirname(p) for p in paths])
    for scene in a.scenes:
        name = os.path.relpath(os.path.abspath(scene), common)
        stem = name.replace(os.sep, "-").removesuffix(".xml")
        copies = {s: scaled_copy(scene, a.size, s, a.reference_spp) for s in MITSUBA_SAMPLERS}
        try:
            note(f"{name}: references at {a.reference_spp} spp")
            lref = os.path.join(a.out, f"{stem}-lightsplit-ref.pfm")
            mref = os.path.join(a.out, f"{stem}-mitsuba-ref.exr")
            lt_ref = lightsplit_render(a.lightsplit, copies["independent"], a.reference_spp, lref, a.threads)
            mt_ref = mitsuba_render(mi, copies["independent"], a.reference_spp, mref, seed=1000)
            agree = compare(a.lightsplit, lref, mref, blocks=32)["agreement"]
            noise = math.hypot(
                block_noise(mi, np, lref, agree["worst_block_at"], 32),
                block_noise(mi, np, mref, agree["worst_block_at"], 32),
            )
            points = {"lightsplit": []}
            points.update({s: [] for s in MITSUBA_SAMPLERS})
            for r in range(a.rounds):
                for spp in spps:
                    out = os.path.join(a.out, f"{stem}-lightsplit-{spp}.pfm")
                    t = lightsplit_render(a.lightsplit, copies["independent"], spp, out, a.threads)
                    points["lightsplit"].append((t, relative_rmse(a.lightsplit, out, lref)))
                    for s in MITSUBA_SAMPLERS:
                        out = os.path.join(a.out, f"{stem}-mitsuba-{s}-{spp}.exr")
                        t = mitsuba_render(mi, copies[s], spp, out, seed=r + 1)
                        points[s].append((t, relative_rmse(a.lightsplit, out, mref)))
                note(f"{name}: round {r + 1} of {a.rounds} done")
        finally:
            for c in copies.values():
                os.remove(c)
        mid = spps[len(spps) // 2]
        # The target: the best Mitsuba sampler's error at the middle spp (its median over rounds).
        at_mid = {s: sorted(e for (t, e), k in zip(points[s], spps * a.rounds) if k == mid) for s in MITSUBA_SAMPLERS}
        target = min(v[len(v) // 2] for v in at_mid.values())
        times = {k: time_to(v, target) for k, v in points.items()}
        best = min(MITSUBA_SAMPLERS, key=lambda s: times[s])
        rows.append(
            {
                "scene": name,
                "lightsplit_means": agree["test_means"],
                "mitsuba_means": agree["reference_means"],
                "means_difference": agree["means_difference"],
                "worst_block": agree["worst_block_difference"],
                "worst_block_at": agree["worst_block_at"],
                "block_noise": noise,
                "target": target,
                "lightsplit_time": times["lightsplit"],
                "mitsuba_time": times[best],
                "mitsuba_sampler": best,
                "speedup": times[best] / times["lightsplit"],
                "reference_seconds": (lt_ref, mt_ref),
                "points": points,
            }
        )
        with open(os.path.join(a.out, "rows.json"), "w") as f:
            json.dump(rows, f, indent=1)

    lines = [
        f"| scene | means, lightsplit / Mitsuba - 1 (R, G, B) | worst 32x32 block (noise) | "
        f"relative RMSE | lightsplit | Mitsuba (best sampler) | sooner |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for r in rows:
        ratios = ", ".join(
            f"{100 * (l / m - 1):+.2f}%" if m > 0 else "-" for l, m in zip(r["lightsplit_means"], r["mitsuba_means"])
        )
        means_ok = "pass" if r["means_difference"] <= MEANS_LIMIT else "FAIL"
        block_ok = "pass" if r["worst_block"] <= BLOCK_LIMIT else "FAIL"
        lines.append(
            f"| {r['scene']} | {ratios} ({means_ok}) | {100 * r['worst_block']:.2f}% at {tuple(r['worst_block_at'])} "
            f"({100 * r['block_noise']:.2f}%) ({block_ok}) | {r['target']:.4f} | {r['lightsplit_time']:.2f} s | "
            f"{r['mitsuba_time']:.2f} s ({r['mitsuba_sampler']}) | {r['speedup']:.2f}x |"
        )
    table = "\n".join(lines) + "\n"
    print(table, end="")
    if a.table:
        with open(a.table, "w") as f:
            f.write(table)


if __name__ == "__main__":
    main()
