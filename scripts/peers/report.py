#!/usr/bin/env python3
"""The table of scripts/bench-peers.sh's section of docs/RESULTS.md (scripts/results-section.py
writes the section).

    python3 report.py table RUNS.tsv SAMPLES ROW...
        RUNS.tsv: lines "ROUND PEER WALL_S CPU_S" (tab-separated), one per timed run.
        SAMPLES: pixels x spp of one render, for samples per second.
        ROW: "PEER<TAB>LABEL<TAB>COMMAND<TAB>MEAN<TAB>DIFFERENCE", PEER as in RUNS.tsv, the first
        row lightsplit's. Every ratio is lightsplit's speed over the peer's: the median of the
        per-round ratios (peer seconds over lightsplit seconds in the same round).
"""

import statistics
import sys


def fail(message, status=1):
    print(f"report: {message}", file=sys.stderr)
    sys.exit(status)


def table(runs_path, samples, rows):
    runs = {}
    with open(runs_path, encoding="utf-8") as f:
        for line in f:
            if not line.strip():
                continue
            rnd, peer, wall, cpu = line.rstrip("\n").split("\t")
            runs.setdefault(peer, {})[int(rnd)] = (float(wall), float(cpu))
    rows = [r.split("\t") for r in rows]
    base = rows[0][0]
    if base not in runs:
        fail(f"no runs of {base}")

    def ratio(peer, k):
        per_round = [runs[peer][r][k] / runs[base][r][k] for r in runs[base] if r in runs[peer]]
        return statistics.median(per_round)

    out = [
        "| program | command | wall s | CPU s | M samples/s (wall) | lightsplit/peer speed, wall "
        "| lightsplit/peer speed, CPU | image mean | mean difference |",
        "| --- | --- | ---: | ---: | ---: | ---: | ---: | --- | --- |",
    ]
    for peer, label, command, mean, difference in rows:
        if peer not in runs:
            fail(f"no runs of {peer}")
        wall = statistics.median(w for w, _ in runs[peer].values())
        cpu = statistics.median(c for _, c in runs[peer].values())
        if peer == base:
            ratios = ["—", "—"]
        else:
            ratios = [f"{ratio(peer, 0):.2f}x", f"{ratio(peer, 1):.2f}x"]
        out.append(
            f"| {label} | `{command}` | {wall:.3f} | {cpu:.3f} | {samples / wall / 1e6:.2f} "
            f"| {ratios[0]} | {ratios[1]} | {mean} | {difference} |"
        )
    print("\n".join(out))


def main():
    if len(sys.argv) >= 5 and sys.argv[1] == "table":
        table(sys.argv[2], float(sys.argv[3]), sys.argv[4:])
    else:
        fail(__doc__.strip(), 2)


if __name__ == "__main__":
    main()
