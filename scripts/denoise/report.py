#!/usr/bin/env python3
"""The denoising section of docs/RESULTS.md from scripts/bench-denoise.sh's rows.

    python3 report.py ROWS.csv --spp N --seeds N --reference-spp N [--write docs/RESULTS.md]

Per scene and method: the mean over seeds of RMSE and relMSE against the reference, RMSE as a
ratio of the unfiltered RMSE, and the filter's seconds; then, for each of lightsplit's filters,
whether it is at or below OIDN in both metrics on every scene. Prints the section; with --write,
puts it between `<!-- denoise:begin -->` and `<!-- denoise:end -->` (appended when missing).
"""

import argparse
import collections
import csv
import re

BEGIN, END = "<!-- denoise:begin -->", "<!-- denoise:end -->"
PEER = "OIDN 2.5 (beauty + albedo + normal)"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("rows")
    ap.add_argument("--spp", type=int, required=True)
    ap.add_argument("--seeds", type=int, required=True)
    ap.add_argument("--reference-spp", type=int, required=True)
    ap.add_argument("--write")
    args = ap.parse_args()

    cells = collections.defaultdict(list)
    scenes, methods = [], []
    for r in csv.DictReader(open(args.rows)):
        key = (r["scene"], r["method"])
        cells[key].append((float(r["rmse"]), float(r["relmse"]), float(r["seconds"])))
        if r["scene"] not in scenes:
            scenes.append(r["scene"])
        if r["method"] not in methods:
            methods.append(r["method"])
    mean = {k: tuple(sum(x[i] for x in v) / len(v) for i in range(3)) for k, v in cells.items()}

    out = [BEGIN, "## Denoising: the à-trous filter against a learned denoiser", ""]
    out.append(
        f"`scripts/bench-denoise.sh`: {args.spp} spp (sobol, the default), the mean of seeds 1 to {args.seeds}, "
        f"against a {args.reference_spp}-spp reference (independent sampling, seed 1000), 256x256. Every method "
        "filters the very same renders. RMSE is given as a ratio of the unfiltered RMSE, then RMSE / relMSE; "
        "seconds are the filter's alone (OIDN's `execute()` on 2 threads; lightsplit's `filter --json`). "
        "The reference's own noise is part of every figure: at 4096 independent samples it is about 1/8 of "
        "the unfiltered RMSE at 64 independent samples."
    )
    out.append("")
    out.append("| method | " + " | ".join(f"`{s}.toml`" for s in scenes) + " |")
    out.append("|---|" + "---|" * len(scenes))
    for m in methods:
        row = [m]
        for s in scenes:
            if (s, m) not in mean:
                row.append("-")
                continue
            rmse, rel, sec = mean[(s, m)]
            base = mean.get((s, "unfiltered"), (rmse,))[0]
            row.append(f"{rmse / base:.2f}x: {rmse:.2e} / {rel:.2e}, {sec * 1000:.0f} ms")
        out.append("| " + " | ".join(row) + " |")
    out.append("")
    verdicts = []
    for m in methods:
        if m in ("unfiltered", PEER):
            continue
        wins, losses = [], []
        for s in scenes:
            if (s, m) not in mean or (s, PEER) not in mean:
                continue
            (r, q, _), (pr, pq, _) = mean[(s, m)], mean[(s, PEER)]
            for metric, a, b in (("RMSE", r, pr), ("relMSE", q, pq)):
                (wins if a <= b else losses).append(f"{s} {metric} {b / a:.2f}x" if a <= b else f"{s} {metric} {a / b:.2f}x worse")
        if losses:
            verdicts.append(f"- **{m}**: not at or below OIDN everywhere: {', '.join(losses)}; better in {', '.join(wins) or 'nothing'}.")
        else:
            verdicts.append(f"- **{m}**: at or below OIDN in both metrics on every scene ({', '.join(wins)}).")
    out += ["Against OIDN (a factor is OIDN's error over ours):", ""] + verdicts + ["", END]
    section = "\n".join(out) + "\n"
    print(section)
    if args.write:
        text = open(args.write).read()
        if BEGIN in text and END in text:
            text = re.sub(re.escape(BEGIN) + ".*?" + re.escape(END) + "\n?", lambda _: section, text, flags=re.S)
        else:
            text = text.rstrip("\n") + "\n\n" + section
        open(args.write, "w").write(text)


if __name__ == "__main__":
    main()
