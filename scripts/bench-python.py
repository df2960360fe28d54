#!/usr/bin/env python3
"""Issue 42's goal, measured: `scene.render()` in the Python module against `lightsplit render`
on the same scene, rounds alternated, and the cost of making the layers arrays.

    python scripts/bench-python.py                       # scenes/cornell.toml, 256x256, 64 spp
    python scripts/bench-python.py --rounds 7 --spp 16

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
    return 0


if __name__ == "__main__":
    sys.exit(main())
