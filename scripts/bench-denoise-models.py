#!/usr/bin/env python3
"""Issue 41's test of `--denoise` where noise is already low, on the Python module: third-party
models (normal maps, metals, clear coats) under the default white sky, each rendered at several
sample counts and filtered with `--denoise`, against a high-sample reference of the same model.
The goal: `--denoise` never worse than the unfiltered image, in RMSE and in relMSE, at any spp.

    python scripts/bench-denoise-models.py MODELS_DIR
    python scripts/bench-denoise-models.py MODELS_DIR --spp 4,64,1024 --size 128 --reference-spp 4096

It renders, filters and compares in one process with `import lightsplit` (install it first:
`python3 -m venv venv && venv/bin/pip install ./python`, then run this with `venv/bin/python`).
The figures are those of `lightsplit render`, `filter --denoise` and `compare`: the module runs
the same code on the same values (python/tests checks it bit for bit).

MODELS_DIR holds Khronos sample models in the layout of KhronosGroup/glTF-Sample-Assets
(MODELS_DIR/Models/NAME/glTF-Binary/NAME.glb), for example a checkout of
DRx3D/glTF-Sample-Assets-OLD (never committed here).

Prints a Markdown table (also OUT/table.md): per model and spp the unfiltered and denoised RMSE
and relMSE and their ratios, and the verdict: denoised not above unfiltered in both (holds),
above by less than 1e-4 of it (same: the filter left the image as it was), or WORSE. The
references are saved in OUT (MODEL-reference.exr) and read back by later runs of the same size.
Exit status: 0 when every row holds, 1 when one does not or a render fails, 2 on bad options.
"""

import argparse
import os
import sys
import time
from pathlib import Path

MODELS = "DamagedHelmet,NormalTangentMirrorTest,MetalRoughSpheresNoTextures,ClearcoatWicker"


def positive_list(text):
    try:
        values = [int(v) for v in text.split(",")]
    except ValueError:
        values = []
    if not values or min(values) < 1:
        raise argparse.ArgumentTypeError("takes positive integers separated by commas")
    return values


def positive(text):
    if not text.isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError("must be a positive integer")
    return int(text)


def verdict(r0, r1, q0, q1):
    """holds, same or WORSE. "same": above the unfiltered error by less than 1e-4 of it in either
    metric, far below what the reference's own noise lets this measure (its 2,048 samples leave
    it about 1/sqrt(2) of the 1024-spp row's error from the truth); the filter then left the
    image as it was, to 4 digits."""
    if r1 <= r0 and q1 <= q0:
        return "holds"
    if r1 <= r0 * (1 + 1e-4) and q1 <= q0 * (1 + 1e-4):
        return "same"
    return "WORSE"


def main():
    p = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("models_dir", type=Path, help="a checkout with Models/NAME/glTF-Binary/NAME.glb")
    p.add_argument("--models", default=MODELS, help=f"model names, commas (default {MODELS})")
    p.add_argument("--spp", type=positive_list, default=[4, 16, 64, 256, 1024], help="sample counts (default 4,16,64,256,1024)")
    p.add_argument("--size", type=positive, default=128, help="width and height (default 128)")
    p.add_argument("--reference-spp", type=positive, default=2048, help="the references' samples per pixel (default 2048)")
    p.add_argument("--threads", type=positive, default=None, help="render threads (default one per core)")
    p.add_argument("--filter", default=None, help="a filter setting to judge instead of --denoise (as `--filter` takes it)")
    p.add_argument("--target", default=None, help="that filter's target (as `--filter-target`)")
    p.add_argument("--out", type=Path, default=Path(os.environ.get("TMPDIR", "/tmp")) / "lightsplit-denoise-models",
                   help="the references and the table (default $TMPDIR/lightsplit-denoise-models)")
    args = p.parse_args()
    if args.target and not args.filter:
        p.error("--target needs --filter")
    try:
        import lightsplit
    except ImportError:
        p.error("no lightsplit module: python3 -m venv venv && venv/bin/pip install ./python, then run this with venv/bin/python")

    args.out.mkdir(parents=True, exist_ok=True)
    label = f"--filter {args.filter}" + (f" --filter-target {args.target}" if args.target else "") if args.filter else "--denoise"
    rows = [
        "| model | spp | RMSE unfiltered | RMSE denoised | ratio | relMSE unfiltered | relMSE denoised | ratio | verdict |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |",
    ]
    failed = False
    start = time.monotonic()
    for model in args.models.split(","):
        glb = args.models_dir / "Models" / model / "glTF-Binary" / f"{model}.glb"
        if not glb.is_file():
            p.error(f"no {glb}")
        try:
            scene = lightsplit.load(glb, width=args.size, height=args.size)
            path = args.out / f"{model}-reference.exr"
            reference = lightsplit.read(path) if path.is_file() else None
            if reference is None or (reference.width, reference.height) != (args.size, args.size):
                print(f"{model}: the reference, {args.reference_spp} spp", file=sys.stderr)
                reference = scene.render(spp=args.reference_spp, seed=1, threads=args.threads)
                reference.save(path)
            for n in args.spp:
                raw = scene.render(spp=n, seed=2, threads=args.threads)
                if args.filter:
                    denoised = lightsplit.filter(raw, args.filter, args.target)
                else:
                    denoised = lightsplit.filter(raw, denoise=True)
                e0, e1 = lightsplit.compare(raw, reference), lightsplit.compare(denoised, reference)
                r0, r1, q0, q1 = e0["rmse"], e1["rmse"], e0["relmse"], e1["relmse"]
                v = verdict(r0, r1, q0, q1)
                failed |= v == "WORSE"
                rows.append(
                    f"| {model} | {n} | {r0:.4g} | {r1:.4g} | {r1 / r0:.4f}x | {q0:.4g} | {q1:.4g} | {q1 / q0:.4f}x | {v} |"
                )
                print(f"{model} {n} spp: {v} ({time.monotonic() - start:.0f} s)", file=sys.stderr)
        except (ValueError, RuntimeError) as e:
            print(f"bench-denoise-models: error: {model}: {e}", file=sys.stderr)
            return 1
    rows += ["", f"{args.size}x{args.size}, references at {args.reference_spp} spp (seed 1), renders seed 2; filter: {label}."]
    table = "\n".join(rows) + "\n"
    (args.out / "table.md").write_text(table)
    print(table, end="")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
