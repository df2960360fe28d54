#!/usr/bin/env bash
# Two builds of lightsplit side by side on the scenes both read: the time a sample takes, and the
# time each needs to reach the same error. Each build is compared with its own converged image,
# so the error is its noise alone; the two converged images are compared with each other too,
# to show where the builds render different light (a change of method, not noise).
#
# Usage: scripts/bench-regression.sh OLD_BINARY NEW_BINARY [OUT_DIR]
#   SCENES="cornell sky-sphere"  the scenes (default: the six the render-regression section uses)
#   SPP="16 64"                  samples per pixel of the timed renders
#   SEEDS=3                      seeds per row (rounds alternate the builds)
#   REF_SPP=2048                 samples per pixel of each build's converged image
#   SIZE=128                     width and height
#
# Renders run on one thread, each build's `render --json` giving the render time alone. The
# error is the trimmed one of `compare` (the worst 0.1% of pixels left out), so one firefly in a
# render does not decide a row; the untrimmed figures are in the CSV. "to equal error" is
# (new time x new MSE) / (old time x old MSE): below 1, the new build reaches the old one's
# error sooner. Writes OUT_DIR/regression.csv and prints a Markdown table.
set -euo pipefail

if [ $# -lt 2 ]; then
    sed -n '2,18p' "$0" | sed 's/^# \{0,1\}//' >&2
    exit 2
fi
old=$1
new=$2
out=${3:-target/bench-regression}
for b in "$old" "$new"; do
    [ -x "$b" ] || { echo "error: $b is not an executable" >&2; exit 2; }
done
here=$(cd "$(dirname "$0")/.." && pwd)
scenes=${SCENES:-cornell embree-cornell materials paper-sky sky-sphere terrain-1m}
spps=${SPP:-16 64}
seeds=${SEEDS:-3}
ref_spp=${REF_SPP:-2048}
size=${SIZE:-128}
mkdir -p "$out"
csv="$out/regression.csv"
echo "scene,spp,seed,build,seconds,rmse,relmse,rmse_trimmed,relmse_trimmed" >"$csv"

render() { # binary scene spp seed threads output -> seconds
    "$1" render "$here/scenes/$2.toml" --width "$size" --height "$size" --spp "$3" --seed "$4" \
        --threads "$5" -o "$6" --json 2>/dev/null | python3 -c 'import json,sys; print(json.load(sys.stdin)["seconds"])'
}
errors() { # image reference -> rmse,relmse,rmse_trimmed,relmse_trimmed
    "$new" compare "$1" "$2" --json | python3 -c '
import json, sys
d = json.load(sys.stdin)
print(",".join(str(d[k]) for k in ("rmse", "relmse", "rmse_trimmed", "relmse_trimmed")))'
}

for s in $scenes; do
    for b in old new; do
        ref="$out/$s-$b-ref.pfm"
        if [ ! -f "$ref" ]; then
            echo "$s: the $b build's converged image ($ref_spp spp)" >&2
            render "${!b}" "$s" "$ref_spp" 999 2 "$ref" >/dev/null
        fi
    done
    echo "$s,,,between,,$(errors "$out/$s-new-ref.pfm" "$out/$s-old-ref.pfm")" >>"$csv"
    for spp in $spps; do
        for seed in $(seq 1 "$seeds"); do
            # Alternate which build goes first, round by round.
            order="old new"
            [ $((seed % 2)) -eq 0 ] && order="new old"
            for b in $order; do
                img="$out/$s-$b-$spp-$seed.pfm"
                sec=$(render "${!b}" "$s" "$spp" "$seed" 1 "$img")
                echo "$s,$spp,$seed,$b,$sec,$(errors "$img" "$out/$s-$b-ref.pfm")" >>"$csv"
            done
        done
    done
done

python3 - "$csv" <<'PY'
import csv, statistics, sys
rows = list(csv.DictReader(open(sys.argv[1])))
print("| scene | spp | seconds old / new | per sample | trimmed MSE old / new | to equal error (MSE, relMSE) | converged images apart (relMSE, trimmed) |")
print("| --- | ---: | ---: | ---: | ---: | ---: | ---: |")
scenes = list(dict.fromkeys(r["scene"] for r in rows))
for s in scenes:
    between = next(r for r in rows if r["scene"] == s and r["build"] == "between")
    for spp in list(dict.fromkeys(r["spp"] for r in rows if r["scene"] == s and r["spp"])):
        def med(b, k):
            return statistics.median(float(r[k]) for r in rows if r["scene"] == s and r["spp"] == spp and r["build"] == b)
        t = {b: med(b, "seconds") for b in ("old", "new")}
        mse = {b: med(b, "rmse_trimmed") ** 2 for b in ("old", "new")}
        rel = {b: med(b, "relmse_trimmed") for b in ("old", "new")}
        eq = (t["new"] * mse["new"]) / (t["old"] * mse["old"])
        eq_rel = (t["new"] * rel["new"]) / (t["old"] * rel["old"])
        print(f"| `{s}` | {spp} | {t['old']:.3f} / {t['new']:.3f} | {t['new'] / t['old']:.2f}x | "
              f"{mse['old']:.2e} / {mse['new']:.2e} | {eq:.2f}x, {eq_rel:.2f}x | "
              f"{float(between['relmse_trimmed']):.1e} |")
PY
