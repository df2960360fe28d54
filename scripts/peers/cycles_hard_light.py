#!/usr/bin/env python3
"""lightsplit against Blender's Cycles on the scenes of issue 39 (scenes/many-lights.toml and
scenes/window-room.toml, made by scripts/make-hard-light-scenes.py): render time to equal error,
each program with its many-light and guiding methods on. Run by scripts/compare-cycles.sh, which
makes the virtual environment (bpy, OpenEXR, numpy); by hand:

    python cycles_hard_light.py --lightsplit BIN --out DIR [--size N] [--spp LIST]
        [--reference-spp N] [--threads N] [--scenes LIST] [--lightsplit-args ARGS]

For each scene NAME, scenes/NAME.toml places one glTF file (its geometry, materials, lights and
camera) and may add a uniform sky; nothing else. Both programs render that glTF:

- lightsplit renders scenes/NAME.toml (the glTF, its camera, and the sky) at --size x --size,
  with --lightsplit-args (e.g. `--light-sampler tree --guiding`) appended.
- Blender imports the glTF with its own importer, lighting mode 'SPEC' (glTF's candela and lux
  turned into watts at 683 lm/W: a point light of I cd gets 4 pi I / 683 W, which Cycles emits
  as I / 683 W/sr, and a sun of E lx gets E / 683 W/m^2, lightsplit's own reading of the same
  file), renders through the glTF's camera (checked against the TOML's) with the sky as its
  world's colour (black when there is none), and Cycles' CPU path tracer with the light tree
  and path guiding (surface guiding, not volumes) on, no denoising, no adaptive sampling, 8
  bounces of every kind, no clamping, a box filter one pixel wide (lightsplit's). Point lights
  keep the importer's radius 0 (lightsplit's points), the sun gets lightsplit's 0.53 degrees,
  and each emissive material is sampled from its front side only (Cycles' emission sampling
  'FRONT'), as lightsplit's emitters emit only from their front (Cycles still emits from the
  back, which the scenes turn to a wall 5 mm away). Cycles' other settings are its defaults
  (its sampling pattern, its guiding's 128 training samples).

Each renders a reference (--reference-spp, seed 1) and a render at each of --spp (seed 0), on
--threads threads, timed from the first sample: lightsplit's render seconds (its --json),
Cycles' from its status line "Sample 0/N" to the end of bpy.ops.render.render. Before that
Cycles syncs the scene from Blender's data (most of a second for the city's thousand objects,
at any size) and builds its BVH and light tree; the "whole" times count that (Cycles' render
operator, lightsplit's render and build seconds) and get a ratio of their own. The image is
saved afterwards, untimed, and one 1-spp render warms Cycles up first. The error is the
relative RMSE (the square root of `lightsplit compare`'s relMSE) of each render against its own
program's reference: the binary's metric, not a second implementation. The target error is
what Cycles reaches at the middle of --spp; the time each program needs for it is read off the
log-log line through its (time, error) points (with slope -1/2 past the ends), and the table
gives Cycles' time over lightsplit's. The two references' channel means are compared too
(`lightsplit compare --blocks`): a check that the programs render the same scene.

Writes DIR/table.md (also printed), DIR/rows.json, each render (DIR/NAME-PROGRAM-SPP.exr) and
DIR/NAME-side-by-side.png (lightsplit's reference left, Cycles' right; then the two renders at
the middle spp). Exit status: 0 when every scene rendered, 1 when a program failed, 2 on bad
arguments.
"""

import argparse
import contextlib
import importlib.util
import json
import math
import os
import shlex
import struct
import subprocess
import sys
import time
import tomllib
import warnings
import zlib

ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
SUN_DEGREES = 0.53  # lightsplit's angular diameter of a glTF directional light


def fail(message, status=1):
    print(f"compare-cycles: error: {message}", file=sys.stderr)
    sys.exit(status)


def note(message):
    print(f"compare-cycles: {message}", file=sys.stderr, flush=True)


def scene_parts(name):
    """The TOML's glTF file, camera and sky radiance (None without a sky); refuses a TOML that
    holds anything Blender would not get from the glTF and the world colour."""
    path = os.path.join(ROOT, "scenes", name + ".toml")
    if not os.path.isfile(path):
        fail(f"no scene {path}", 2)
    with open(path, "rb") as f:
        scene = tomllib.load(f)
    shapes = scene.get("shape", [])
    if len(shapes) != 1 or shapes[0].get("type") != "gltf" or set(shapes[0]) != {"type", "file"}:
        fail(f"{path}: must place exactly one glTF file, untransformed", 2)
    lights = scene.get("light", [])
    if any(l.get("type") != "sky" or set(l) != {"type", "radiance"} for l in lights) or len(lights) > 1:
        fail(f"{path}: the only light it may add is one uniform sky (`radiance`)", 2)
    glb = os.path.join(os.path.dirname(path), shapes[0]["file"])
    return path, glb, scene["camera"], lights[0]["radiance"] if lights else None


def run(args):
    r = subprocess.run(args, capture_output=True, text=True)
    if r.returncode != 0:
        fail(f"{shlex.join(args)} failed:\n{r.stderr}")
    return r.stdout


def lightsplit_render(a, toml, spp, seed, out):
    """Renders and returns (the render's seconds, with the build's too)."""
    args = [a.lightsplit, "render", toml, "--width", str(a.size), "--height", str(a.size), "--spp", str(spp),
            "--seed", str(seed), "--threads", str(a.threads), "--json", "-o", out] + shlex.split(a.lightsplit_args)
    summary = json.loads(run(args))
    return summary["seconds"], summary["seconds"] + summary["build_seconds"]


@contextlib.contextmanager
def quiet(log):
    """Blender's importer and Cycles print a line per node and per status: into the log file, at
    the file-descriptor level (they write from C as well as from Python)."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = os.dup(1), os.dup(2)
    os.dup2(log.fileno(), 1)
    os.dup2(log.fileno(), 2)
    try:
        yield
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        os.close(saved[0])
        os.close(saved[1])


def compare(a, test, reference, blocks=None):
    args = [a.lightsplit, "compare", test, reference, "--json"] + (["--blocks", str(blocks)] if blocks else [])
    return json.loads(run(args))


def relative_rmse(a, test, reference):
    return math.sqrt(compare(a, test, reference)["relmse"])


def _mitsuba_compare():
    """scripts/mitsuba/compare.py, loaded for its `time_to`: the time at which the log-log line
    through (time, error) points reaches a target error, the same reading for both peers."""
    path = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "mitsuba", "compare.py")
    spec = importlib.util.spec_from_file_location("mitsuba_compare", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


time_to = _mitsuba_compare().time_to


class Cycles:
    """One glTF file imported into Blender and set up for Cycles as the module's docstring says."""

    def __init__(self, glb, camera, sky, size, threads, log):
        import bpy

        self.bpy = bpy
        self.log = log
        with quiet(log):
            bpy.ops.wm.read_factory_settings(use_empty=True)
            bpy.ops.import_scene.gltf(filepath=glb, export_import_convert_lighting_mode="SPEC")
        scene = self.scene = bpy.context.scene
        cameras = [o for o in scene.objects if o.type == "CAMERA"]
        if len(cameras) != 1:
            fail(f"{glb}: {len(cameras)} cameras in Blender's import, not one")
        scene.camera = cameras[0]
        self.check_camera(glb, cameras[0], camera)
        for o in scene.objects:
            if o.type == "LIGHT" and o.data.type == "POINT":
                o.data.shadow_soft_size = 0.0
            elif o.type == "LIGHT" and o.data.type == "SUN":
                o.data.angle = math.radians(SUN_DEGREES)
            elif o.type == "LIGHT":
                fail(f"{glb}: a {o.data.type} light; only point and sun lights are set up")
        self.emitters = 0
        for m in bpy.data.materials:
            bsdf = m.node_tree.nodes.get("Principled BSDF") if m.node_tree else None
            if bsdf is not None and bsdf.inputs["Emission Strength"].default_value > 0:
                m.cycles.emission_sampling = "FRONT"
                self.emitters += 1
        world = bpy.data.worlds.new("sky")
        with warnings.catch_warnings():  # Blender 5 deprecates use_nodes; 4.x needs it
            warnings.simplefilter("ignore", DeprecationWarning)
            world.use_nodes = True
        background = world.node_tree.nodes["Background"]
        background.inputs["Color"].default_value = (*(sky or (0.0, 0.0, 0.0)), 1.0)
        background.inputs["Strength"].default_value = 1.0 if sky else 0.0
        scene.world = world

        scene.render.engine = "CYCLES"
        c = scene.cycles
        c.device = "CPU"
        c.use_light_tree = True
        c.use_guiding = True
        c.use_surface_guiding = True
        c.use_volume_guiding = False
        c.use_denoising = False
        c.use_adaptive_sampling = False
        c.max_bounces = c.diffuse_bounces = c.glossy_bounces = c.transmission_bounces = c.volume_bounces = 8
        c.transparent_max_bounces = 8
        c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
        c.blur_glossy = 0.0
        # lightsplit's pixel filter: a box one pixel wide.
        c.pixel_filter_type = "BOX"
        c.filter_width = 1.0
        scene.render.threads_mode = "FIXED"
        scene.render.threads = threads
        scene.render.resolution_x = scene.render.resolution_y = size
        scene.render.resolution_percentage = 100
        scene.view_settings.view_transform = "Standard"
        settings = scene.render.image_settings
        if hasattr(settings, "media_type"):  # Blender 5: a single-layer image is a media type
            settings.media_type = "IMAGE"
        settings.file_format = "OPEN_EXR"
        settings.color_mode = "RGB"
        settings.color_depth = "32"
        # Cycles' status line says when it starts sampling: the render's time is from there
        # (the scene's sync from Blender's data, BVH and light tree before it are Cycles' setup).
        self.sampling_from = None

        def stats(text):
            if self.sampling_from is None and "Sample 0/" in text:
                self.sampling_from = time.perf_counter()

        bpy.app.handlers.render_stats.clear()
        bpy.app.handlers.render_stats.append(stats)
        self.warm_up = self.render(1, 0, None)[1]  # kernels, first sync: not counted

    def check_camera(self, glb, obj, camera):
        """The glTF's camera as Blender imported it must be the TOML's: the same position, view
        direction and vertical field of view (within rounding), in glTF's y-up coordinates."""
        m = obj.matrix_world
        to_gltf = lambda v: (v[0], v[2], -v[1])  # noqa: E731  Blender's z-up to glTF's y-up
        position = to_gltf(m.translation)
        view = to_gltf(-m.col[2].xyz.normalized())
        want = [b - a for a, b in zip(camera["position"], camera["look_at"])]
        norm = math.sqrt(sum(x * x for x in want))
        want = [x / norm for x in want]
        fov = math.degrees(obj.data.angle_y)
        if (max(abs(a - b) for a, b in zip(position, camera["position"])) > 1e-4
                or max(abs(a - b) for a, b in zip(view, want)) > 1e-4
                or abs(fov - camera.get("fov", 40.0)) > 1e-3):
            fail(f"{glb}: its camera in Blender ({position}, looking along {view}, {fov} degrees) is not the "
                 f"TOML's ({camera})")

    def render(self, spp, seed, out):
        """Renders and returns (the seconds from the first sample, the render operator's)."""
        self.scene.cycles.samples = spp
        self.scene.cycles.seed = seed
        self.sampling_from = None
        with quiet(self.log):
            start = time.perf_counter()
            self.bpy.ops.render.render()
            end = time.perf_counter()
            if out is not None:
                self.bpy.data.images["Render Result"].save_render(filepath=out)
        if self.sampling_from is None:
            fail("Cycles' status never said it started sampling (\"Sample 0/\")")
        return end - self.sampling_from, end - start


def read_rgb(path):
    import numpy as np
    import OpenEXR

    with OpenEXR.File(path, separate_channels=True) as f:
        ch = {k: np.asarray(v.pixels, dtype=np.float64) for k, v in f.channels().items()}
    return np.stack([ch[c] for c in "RGB"], axis=-1)


def write_png(path, images):
    """The images side by side as an 8-bit sRGB PNG (no exposure: the scenes are made to show as
    they are)."""
    import numpy as np

    x = np.concatenate(images, axis=1)
    x = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.clip(x, 0.0031308, None) ** (1 / 2.4) - 0.055)
    x = np.ascontiguousarray((np.clip(x, 0, 1) * 255 + 0.5).astype(np.uint8))
    h, w, _ = x.shape
    raw = b"".join(b"\0" + x[y].tobytes() for y in range(h))

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
                + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--lightsplit", required=True)
    p.add_argument("--out", required=True)
    p.add_argument("--size", type=int, default=128)
    p.add_argument("--spp", default="16,64,256")
    p.add_argument("--reference-spp", type=int, default=4096)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--scenes", default="many-lights,window-room")
    p.add_argument("--lightsplit-args", default="")
    a = p.parse_args()
    try:
        spps = sorted({int(s) for s in a.spp.split(",")})
    except ValueError:
        fail("--spp takes numbers separated by commas", 2)
    if a.size < 8 or a.reference_spp < 1 or any(s < 1 for s in spps) or a.threads < 1:
        fail("--size (8 or more), --reference-spp, --spp and --threads must be positive", 2)
    names = [n for n in a.scenes.split(",") if n]
    if not names:
        fail("--scenes names no scene", 2)
    parts = {n: scene_parts(n) for n in names}
    os.makedirs(a.out, exist_ok=True)
    log = open(os.path.join(a.out, "blender.log"), "w")
    with quiet(log):
        import bpy

    rows = []
    programs = ("lightsplit", "cycles")
    for name in names:
        toml, glb, camera, sky = parts[name]
        note(f"{name}: importing {os.path.relpath(glb, ROOT)} into Blender {bpy.app.version_string}")
        cycles = Cycles(glb, camera, sky, a.size, a.threads, log)

        def render(program, spp, seed, out):
            if program == "lightsplit":
                return lightsplit_render(a, toml, spp, seed, out)
            return cycles.render(spp, seed, out)

        note(f"{name}: references at {a.reference_spp} spp")
        refs = {k: os.path.join(a.out, f"{name}-{k}-ref.exr") for k in programs}
        ref_seconds = {k: render(k, a.reference_spp, 1, refs[k]) for k in programs}
        agree = compare(a, refs["lightsplit"], refs["cycles"], blocks=max(8, a.size // 4))["agreement"]
        # Each point: (spp, render seconds, whole seconds, relative RMSE).
        points = {k: [] for k in programs}
        for spp in spps:
            for k in programs:
                out = os.path.join(a.out, f"{name}-{k}-{spp}.exr")
                seconds, whole = render(k, spp, 0, out)
                error = relative_rmse(a, out, refs[k])
                points[k].append((spp, seconds, whole, error))
                note(f"{name}: {k} {spp} spp in {seconds:.3f} s ({whole:.3f} s whole), relative RMSE {error:.4f}")
        mid = spps[len(spps) // 2]
        target = next(e for s, _, _, e in points["cycles"] if s == mid)
        times = {k: time_to([(t, e) for _, t, _, e in v], target) for k, v in points.items()}
        whole_times = {k: time_to([(w, e) for _, _, w, e in v], target) for k, v in points.items()}
        write_png(os.path.join(a.out, f"{name}-side-by-side.png"),
                  [read_rgb(refs["lightsplit"]), read_rgb(refs["cycles"]),
                   read_rgb(os.path.join(a.out, f"{name}-lightsplit-{mid}.exr")),
                   read_rgb(os.path.join(a.out, f"{name}-cycles-{mid}.exr"))])
        rows.append({"scene": name, "points": points, "target": target, "target_spp": mid,
                     "times": times, "whole_times": whole_times,
                     "ratio": times["cycles"] / times["lightsplit"],
                     "whole_ratio": whole_times["cycles"] / whole_times["lightsplit"],
                     "reference_seconds": ref_seconds, "cycles_warm_up_seconds": cycles.warm_up,
                     "lightsplit_means": agree["test_means"], "cycles_means": agree["reference_means"],
                     "worst_block": agree["worst_block_difference"], "emissive_materials": cycles.emitters})
        with open(os.path.join(a.out, "rows.json"), "w") as f:
            json.dump({"blender": bpy.app.version_string, "lightsplit_args": a.lightsplit_args, "size": a.size,
                       "threads": a.threads, "reference_spp": a.reference_spp, "rows": rows}, f, indent=1)

    extra = f"`{a.lightsplit_args}`" if a.lightsplit_args else "no extra flags"
    lines = [
        f"Blender {bpy.app.version_string}'s Cycles (CPU, light tree and surface guiding on) against lightsplit "
        f"({extra}); {a.size}x{a.size} pixels, {a.threads} threads, each against its own reference at "
        f"{a.reference_spp} spp. Seconds: from the first sample (whole: lightsplit's with its build, Cycles' "
        f"render operator with its sync from Blender).",
        "",
        "| scene | program | spp | seconds | whole seconds | relative RMSE |",
        "| --- | --- | ---: | ---: | ---: | ---: |",
    ]
    for r in rows:
        for k in programs:
            for spp, seconds, whole, error in r["points"][k]:
                lines.append(f"| {r['scene']} | {k} | {spp} | {seconds:.3f} | {whole:.3f} | {error:.4f} |")
    lines += [
        "",
        "| scene | reference means, lightsplit / Cycles (R, G, B) | target relative RMSE (Cycles at spp) "
        "| lightsplit | Cycles | time to equal error, Cycles / lightsplit | the same, whole seconds |",
        "| --- | --- | ---: | ---: | ---: | ---: | ---: |",
    ]
    for r in rows:
        ratios = ", ".join(f"{l / c:.3f}" if c > 0 else "-" for l, c in zip(r["lightsplit_means"], r["cycles_means"]))
        lines.append(f"| {r['scene']} | {ratios} | {r['target']:.4f} ({r['target_spp']}) "
                     f"| {r['times']['lightsplit']:.3f} s | {r['times']['cycles']:.3f} s | {r['ratio']:.2f}x "
                     f"| {r['whole_ratio']:.2f}x |")
    table = "\n".join(lines) + "\n"
    print(table, end="")
    with open(os.path.join(a.out, "table.md"), "w") as f:
        f.write(table)


if __name__ == "__main__":
    main()
