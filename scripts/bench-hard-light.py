#!/usr/bin/env python3
"""Issue 39's figures: the light tree against power and uniform light selection, and path
guiding against none, each at equal time, measured side by side with the binary's own
`render --json` (time) and `compare --json` (error).

For each scene: a reference of REF_SPP samples a pixel (seed 1, the default settings), then
each setting at each spp of SPP (seed 0), the settings alternated within each spp and the
whole repeated ROUNDS times (the machine is noisy: the times are each setting's median). The
error of a render is its MSE (RMSE squared, over the three channels) against the reference;
at equal time the MSE of an unbiased render falls as 1/time, so a setting's MSE at the
baseline's time is its MSE x its time / the baseline's time, and the figure is the baseline's
MSE over that: above 1, the setting reaches a lower error in the same time. Render times
include the accelerator's build and, for guiding, its training.

    python3 scripts/bench-hard-light.py [--size N] [--spp 16,64] [--reference-spp 2048]
        [--rounds 2] [--out DIR] [--section]

`--section` writes the `hard-light` section of docs/RESULTS.md (scripts/results-section.py).
The binary is $LIGHTSPLIT or target/dist/lightsplit (built with `cargo build --profile dist`
when missing).
"""

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# (scene, baseline flags, [(name, flags)]): the settings measured against each baseline.
LIGHTS = [
    ("many-lights.toml", ["--light-sampler", "power"],
     [("tree", ["--light-sampler", "tree"]), ("uniform", ["--light-sampler", "uniform"])]),
    ("cornell.toml", ["--light-sampler", "power"], [("tree", ["--light-sampler", "tree"])]),
    ("embree-cornell.toml", ["--light-sampler", "power"], [("tree", ["--light-sampler", "tree"])]),
    ("paper-gallery.toml", ["--light-sampler", "power"], [("tree", ["--light-sampler", "tree"])]),
]
GUIDING = [
    (scene, ["--guiding", "off"], [("guiding all", ["--guiding", "all"]), ("guiding indirect", ["--guiding", "indirect"])])
    for scene in ["window-room.toml", "paper-gallery.toml", "cornell.toml", "sky-sphere.toml"]
]


def binary():
    path = os.environ.get("LIGHTSPLIT", os.path.join(ROOT, "target", "dist", "lightsplit"))
    if not os.path.exists(path):
        subprocess.run(["cargo", "build", "--profile", "dist", "-q"], cwd=ROOT, check=True)
    return path


def render(exe, scene, out, size, spp, seed, flags):
    args = [exe, "render", os.path.join(ROOT, "scenes", scene), "-o", out, "--width", str(size),
            "--height", str(size), "--spp", str(spp), "--seed", str(seed), "--json"] + flags
    done = subprocess.run(args, check=True, capture_output=True, text=True)
    j = json.loads(done.stdout)
    return j["seconds"] + j["build_seconds"]


def mse(exe, test, ref):
    done = subprocess.run([exe, "compare", test, ref, "--json"], check=True, capture_output=True, text=True)
    return json.loads(done.stdout)["rmse"] ** 2


def cpu():
    flags = open("/proc/cpuinfo").read() if os.path.exists("/proc/cpuinfo") else ""
    simd = "AVX-512" if "avx512f" in flags else "AVX2" if "avx2" in flags else "no AVX2"
    return f"{platform.machine()}, {os.cpu_count()} cores, {simd}"


def measure(exe, groups, args, out):
    rows = []
    for scene, base_flags, settings in groups:
        ref = os.path.join(out, scene + ".ref.exr")
        if not os.path.exists(ref):
            render(exe, scene, ref, args.size, args.reference_spp, 1, [])
        for spp in args.spp:
            named = [("baseline", base_flags)] + settings
            times = {name: [] for name, _ in named}
            errors = {}
            for _ in range(args.rounds):
                for name, flags in named:
                    path = os.path.join(out, f"{scene}.{name.replace(' ', '-')}.{spp}.exr")
                    times[name].append(render(exe, scene, path, args.size, spp, 0, flags))
                    errors[name] = mse(exe, path, ref)
            t0, e0 = statistics.median(times["baseline"]), errors["baseline"]
            for name, _ in settings:
                t, e = statistics.median(times[name]), errors[name]
                gain = e0 / (e * t / t0) if e > 0 else float("inf")
                rows.append((scene, " ".join(base_flags), name, spp, t0, e0, t, e, gain))
                print(f"{scene} {spp} spp: {name} {t:.3f} s MSE {e:.4e} against {t0:.3f} s {e0:.4e}: "
                      f"{gain:.2f}x at equal time", file=sys.stderr)
    return rows


def table(rows):
    lines = ["| scene | baseline | setting | spp | baseline s | baseline MSE | setting s | setting MSE | "
             "MSE ratio at equal time |", "| --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for scene, base, name, spp, t0, e0, t, e, gain in rows:
        lines.append(f"| {scene} | {base} | {name} | {spp} | {t0:.3f} | {e0:.3e} | {t:.3f} | {e:.3e} | {gain:.2f}x |")
    return "\n".join(lines)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--size", type=int, default=128)
    p.add_argument("--spp", type=lambda s: [int(x) for x in s.split(",")], default=[16, 64])
    p.add_argument("--reference-spp", type=int, default=2048)
    p.add_argument("--rounds", type=int, default=2)
    p.add_argument("--out", default="/tmp/lightsplit-hard-light")
    p.add_argument("--only", choices=["lights", "guiding"], default=None)
    p.add_argument("--section", action="store_true")
    args = p.parse_args()
    os.makedirs(args.out, exist_ok=True)
    exe = binary()
    parts = []
    if args.only in (None, "lights"):
        parts.append(("Light selection", measure(exe, LIGHTS, args, args.out)))
    if args.only in (None, "guiding"):
        parts.append(("Path guiding", measure(exe, GUIDING, args, args.out)))
    text = (f"Measured by `python3 scripts/bench-hard-light.py --size {args.size} --spp "
            f"{','.join(map(str, args.spp))} --reference-spp {args.reference_spp} --rounds {args.rounds}` "
            f"({cpu()}; times include the build and the guide's training; each setting against the "
            f"baseline of its row, alternated).\n")
    for title, rows in parts:
        text += f"\n{title}:\n\n{table(rows)}\n"
    print(text)
    if args.section:
        subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "results-section.py"), "write",
                        os.path.join(ROOT, "docs", "RESULTS.md"), "hard-light-bench",
                        "scripts/bench-hard-light.py", "-"], input=text, text=True, check=True)


if __name__ == "__main__":
    main()
