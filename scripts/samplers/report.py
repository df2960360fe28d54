#!/usr/bin/env python3
"""The docs/RESULTS.md section of scripts/bench-samplers.sh.

    python3 report.py OUT SPEED.tsv SECONDS SIZE SPP SEEDS REFERENCE_SPP ROUNDS SCENE...
        NPOT_SCENES (environment): scenes also measured between the powers of two, in
        OUT/SCENE-npot/summary.md.
        OUT/SCENE/summary.md: each scene's `converge --sampler independent,sobol` summary, whose
        "samplers compared" tables this reads (lightsplit computes the figures; this only
        arranges them). SPEED.tsv: lines "ROUND<TAB>SCENE<TAB>SAMPLER<TAB>RENDER_JSON".
Prints the section, markers included.
"""

import json
import os
import statistics
import sys

# Written from the run committed with this section (fixed seeds: a rerun gives the same errors
# up to float rounding; only the seconds differ).
FINDINGS = "FINDINGS"


def fail(message):
    print(f"samplers report: {message}", file=sys.stderr)
    sys.exit(1)


def table_after(lines, header_start):
    """The rows (lists of cells) of the Markdown table whose header line starts with
    header_start."""
    for i, line in enumerate(lines):
        if line.startswith(header_start):
            rows = []
            for row in lines[i + 2:]:
                if not row.startswith("|"):
                    break
                rows.append([c.strip() for c in row.strip().strip("|").split("|")])
            return rows
    return []


def main(argv):
    if len(argv) < 10:
        fail(__doc__)
    out, speed_path, seconds, size, spps, seeds, reference_spp, rounds = argv[1:9]
    scenes = argv[9:]
    spp_list = [int(s) for s in spps.split(",")]

    worth, verdicts, gains = {}, {}, {}
    for scene in scenes:
        try:
            with open(f"{out}/{scene}/summary.md", encoding="utf-8") as f:
                lines = f.read().splitlines()
        except OSError as e:
            fail(f"{scene}: {e}")
        rows = table_after(lines, "| spp | independent RMSE | sobol RMSE")
        if not rows:
            fail(f"{scene}: no sampler comparison in its summary")
        worth[scene] = {int(r[0]): (r[1], r[2], r[3], r[4]) for r in rows}
        verdicts[scene] = {int(r[0]): r[5] for r in rows}
        gains[scene] = table_after(lines, "| setting | spp | independent | sobol |")

    speeds = {}
    with open(speed_path, encoding="utf-8") as f:
        for line in f:
            if not line.strip():
                continue
            round_, scene, sampler, text = line.rstrip("\n").split("\t", 3)
            speeds.setdefault(scene, {}).setdefault(round_, {})[sampler] = json.loads(text)["samples_per_second"]

    p = print
    p("<!-- samplers:begin -->")
    p("## Low-discrepancy sampling: independent against Owen-scrambled Sobol")
    p()
    p(f"Written by `scripts/bench-samplers.sh` ({seconds} s on this project's 2-core machine).")
    p(f"Every scene in `scenes/` at {size}x{size}, rendered with `--sampler independent` and")
    p(f"`--sampler sobol` at {spps.replace(',', ', ')} spp, {seeds} seeds a point, against a")
    p(f"{reference_spp}-spp reference (`converge --sampler independent,sobol`). \"Sobol is worth Nx\"")
    p("means independent sampling needs N times sobol's samples for sobol's mean RMSE, read off")
    p("independent sampling's log-log curve of the same run; in brackets, the range for sobol's")
    p("mean RMSE plus or minus twice its standard error over seeds. A cell marked *worse* or *same*")
    p("is where sobol's mean RMSE is above, or within twice the standard error of the difference")
    p("of, independent sampling's at the same spp; every other cell is better by more than that.")
    p("The reference's own noise is a floor under both curves, so at the highest spp the factor")
    p("is an underestimate.")
    p()
    p(FINDINGS)
    p()
    p("### What sobol is worth in samples")
    p()
    p("| scene | " + " | ".join(f"{s} spp" for s in spp_list) + " |")
    p("| --- |" + " --- |" * len(spp_list))
    for scene in scenes:
        cells = []
        for s in spp_list:
            if s not in worth[scene]:
                cells.append("-")
                continue
            _, _, w, rng = worth[scene][s]
            v = verdicts[scene][s]
            mark = "" if v == "better" else f" *{v}*"
            cells.append(f"{w} ({rng}){mark}")
        p(f"| `{scene}` | " + " | ".join(cells) + " |")
    p()
    p("Unfiltered RMSE, independent against sobol (mean ± standard deviation over seeds):")
    p()
    p("| scene | spp | independent | sobol |")
    p("| --- | --- | --- | --- |")
    for scene in scenes:
        for s in spp_list:
            if s in worth[scene]:
                ind, sob, _, _ = worth[scene][s]
                p(f"| `{scene}` | {s} | {ind} | {sob} |")
    p()
    npot = [s for s in os.environ.get("NPOT_SCENES", "").split() if s in scenes]
    if npot:
        p("Between the powers of two (24, 48, 96 and 192 spp, against the same references): a")
        p("Sobol sequence's first N points are a net only when N is a power of two, so there sobol")
        p("keeps less of its gain:")
        p()
        p("| scene | spp | independent | sobol | sobol is worth |")
        p("| --- | --- | --- | --- | --- |")
        for scene in npot:
            try:
                with open(f"{out}/{scene}-npot/summary.md", encoding="utf-8") as f:
                    rows = table_after(f.read().splitlines(), "| spp | independent RMSE | sobol RMSE")
            except OSError as e:
                fail(f"{scene}: {e}")
            for r in rows:
                mark = "" if r[5] == "better" else f" *{r[5]}*"
                p(f"| `{scene}` | {r[0]} | {r[1]} | {r[2]} | {r[3]} ({r[4]}){mark} |")
        p()
    p("### What it costs")
    p()
    p(f"Samples per second of `render --json` at {size}x{size}, 64 spp, two threads, both samplers")
    p(f"in each of {rounds} rounds, the first alternating; the ratio is the median of the per-round")
    p("ratios (tracing time only, the accelerator's build excluded).")
    p()
    p("| scene | independent (M samples/s) | sobol (M samples/s) | sobol / independent |")
    p("| --- | --- | --- | --- |")
    for scene in scenes:
        rs = speeds.get(scene, {})
        pairs = [(r["independent"], r["sobol"]) for r in rs.values() if "independent" in r and "sobol" in r]
        if not pairs:
            p(f"| `{scene}` | - | - | - |")
            continue
        ind = statistics.median(a for a, _ in pairs) / 1e6
        sob = statistics.median(b for _, b in pairs) / 1e6
        ratio = statistics.median(b / a for a, b in pairs)
        p(f"| `{scene}` | {ind:.3f} | {sob:.3f} | {ratio:.3f}x |")
    p()
    p("### The paper's filters under each sampler")
    p()
    p("Each filter on L_rdd (the paper's method): its RMSE over the unfiltered RMSE of the same")
    p("renders, under each sampler (below 1: the filter helps). The paper's section 3 assumes")
    p("noise uncorrelated from pixel to pixel; the Sobol points here are scrambled per pixel, so")
    p("neighbouring pixels stay independent, while each pixel's own error falls faster.")
    p()
    shown = {16, 64, 256}
    p("| scene | filter | spp | independent | sobol |")
    p("| --- | --- | --- | --- | --- |")
    for scene in scenes:
        for r in gains[scene]:
            if len(r) >= 4 and r[1].isdigit() and int(r[1]) in shown:
                p(f"| `{scene}` | {r[0]} | {r[1]} | {r[2]} | {r[3]} |")
    p()
    p("### Plots")
    p()
    p("RMSE against spp, both samplers, every filter (the raw rows and summaries are in")
    p("`target/bench-samplers/SCENE/` after a run):")
    p()
    for scene in scenes:
        p(f"![{scene}](results/samplers-{scene}-error-vs-spp.png)")
    p()
    p("Difference images at 64 spp (darker is a larger difference, at the unfiltered image's")
    p("scale), independent then sobol: `cornell.toml`, then `paper-sky.toml`.")
    p()
    for scene in ("cornell", "paper-sky"):
        if scene in scenes:
            p(
                f"![{scene} independent](results/samplers-{scene}-diff-64spp-independent-unfiltered.png) "
                f"![{scene} sobol](results/samplers-{scene}-diff-64spp-sobol-unfiltered.png)"
            )
    p("<!-- samplers:end -->")


if __name__ == "__main__":
    main(sys.argv)
