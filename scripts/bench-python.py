#!/usr/bin/env python3
"""Issue 42's goal, measured: `scene.render()` in the Python module against `lightsplit render`
on the same scene, rounds alternated, and the cost of making the layers arrays.

    python scripts/bench-python.py                       # scenes/cornell.toml, 256x256, 64 spp
    python scripts/bench-python.py --rounds 7 --spp 16
    python scripts/bench-python.py --write               # and writes docs/RESULTS.md's `python`

Run it with the Python that has the module (`pip install ./python`); LIGHTSPLIT names the
command line's binary (default target/release/lightsplit), which should be the module's profile.
Prints per round: the command line's render (tracing) seconds and its tracing + build, the
module's, and the module's whole `render()` call; then the medians, their ratio, and the
median time of `render.image` plus `render.layers` on a fresh render object.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import lightsplit

ROOT = Path(__file__).resolve().parents[1]


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scene", default=str(ROOT / "scenes" / "cornell.toml"))
    p.add_argument("--size", type=int, default=256)
    p.add_argument("--spp", type=int, default=64)
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--write", action="store_true",
                   help="write the figures as docs/RESULTS.md's section `python` (scripts/results-section.py)")
    args = p.parse_args()
    binary = os.environ.get("LIGHTSPLIT", str(ROOT / "target" / "release" / "lightsplit"))
    if not Path(binary).exists():
        print(f"bench-python: no binary {binary} (set LIGHTSPLIT)", file=sys.stderr)
        return 2
    scene = lightsplit.load(args.scene, width=args.size, height=args.size)
    rows = []
    with tempfile.TemporaryDirectory() as d:
        out = os.path.join(d, "cli.exr")
        for r in range(args.rounds):
            cli_first = r % 2 == 0
            result = {}
            for which in (["cli", "py"] if cli_first else ["py", "cli"]):
                if which == "cli":
                    run = subprocess.run(
                        [binary, "render", args.scene, "--width", str(args.size), "--height", str(args.size),
                         "--spp", str(args.spp), "--json", "-o", out],
                        check=True, capture_output=True, text=True)
                    s = json.loads(run.stdout)
                    result["cli"] = (s["seconds"], s["seconds"] + s["build_seconds"])
                else:
                    start = time.perf_counter()
                    render = scene.render(spp=args.spp)
                    call = time.perf_counter() - start
                    s = render.stats
                    start = time.perf_counter()
                    render.image
                    render.layers
                    arrays = time.perf_counter() - start
                    result["py"] = (s["seconds"], s["seconds"] + s["build_seconds"], call, arrays)
            rows.append(result)
            c, m = result["cli"], result["py"]
            print(f"round {r + 1} ({'cli' if cli_first else 'module'} first): command line {c[0]:.3f} s "
                  f"(+ build {c[1]:.3f}), module {m[0]:.3f} s (+ build {m[1]:.3f}, whole call {m[2]:.3f}), "
                  f"arrays {m[3] * 1000:.2f} ms")
    med = lambda xs: statistics.median(xs)  # noqa: E731
    cli_r, py_r = med([x["cli"][0] for x in rows]), med([x["py"][0] for x in rows])
    cli_b, py_b = med([x["cli"][1] for x in rows]), med([x["py"][1] for x in rows])
    call = med([x["py"][2] for x in rows])
    arrays = med([x["py"][3] for x in rows])
    print(f"medians: render {py_r:.3f} s against {cli_r:.3f} s ({py_r / cli_r:.3f}x); with the build "
          f"{py_b:.3f} against {cli_b:.3f} ({py_b / cli_b:.3f}x); the module's whole call {call:.3f} s; "
          f"arrays {arrays * 1000:.2f} ms")
    if args.write:
        write_section(args, rows, (py_r, cli_r), (py_b, cli_b), call, arrays)
    return 0


def machine() -> str:
    """The CPU's name and its widest vector extension, from /proc/cpuinfo (Linux)."""
    name, flags = "unknown CPU", set()
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                key, _, value = line.partition(":")
                if key.strip() == "model name" and name == "unknown CPU":
                    name = value.strip()
                elif key.strip() == "flags" and not flags:
                    flags = set(value.split())
    except OSError:
        pass
    vector = "AVX-512" if "avx512f" in flags else "AVX2, no AVX-512" if "avx2" in flags else "no AVX2"
    return f"{name}, {os.cpu_count()} cores, {vector}"


def write_section(args, rows, render, whole, call, arrays) -> None:
    scene = os.path.relpath(args.scene, ROOT) if os.path.isabs(args.scene) else args.scene
    lines = [
        "## The Python module against the command line (issue 42)",
        "",
        f"Machine: {machine()}; the module and the binary of the release profile. "
        f"`python scripts/bench-python.py --rounds {args.rounds} --write`: `{scene}` at "
        f"{args.size}x{args.size} and {args.spp} spp, `scene.render()` against `lightsplit render --json`, "
        "rounds alternated (the first of each pair swaps). The render's seconds are the tracing's "
        "(`stats[\"seconds\"]`, the command line's `seconds`); \"with the build\" adds the "
        "accelerator's build; the module's whole call is `render()` timed from Python; the arrays are "
        "`render.image` and every array of `render.layers`, made from a fresh render.",
        "",
        "| round | first | command line (s) | module (s) | ratio | with the build: command line | module | module's whole call (s) | arrays (ms) |",
        "| ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for r, x in enumerate(rows):
        c, m = x["cli"], x["py"]
        first = "command line" if r % 2 == 0 else "module"
        lines.append(f"| {r + 1} | {first} | {c[0]:.3f} | {m[0]:.3f} | {m[0] / c[0]:.3f}x | {c[1]:.3f} | {m[1]:.3f} | {m[2]:.3f} | {m[3] * 1000:.2f} |")
    lines += [
        "",
        f"**Medians:** the render {render[0]:.3f} s against {render[1]:.3f} s, **{render[0] / render[1]:.3f}x** "
        f"(goal: within 3%); with the build {whole[0]:.3f} against {whole[1]:.3f} s ({whole[0] / whole[1]:.3f}x); "
        f"the module's whole call {call:.3f} s; the arrays **{arrays * 1000:.2f} ms** (goal: at most 5 ms).",
    ]
    body = "\n".join(lines) + "\n"
    subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "results-section.py"), "write", str(ROOT / "docs" / "RESULTS.md"),
         "python", "scripts/bench-python.py", "-"],
        input=body, text=True, check=True,
    )


if __name__ == "__main__":
    sys.exit(main())
