#!/usr/bin/env bash
# Reproduces the paper's Figures 5 and 6: runs `lightsplit converge` on the paper's two test
# scenes and the Cornell box, then writes docs/RESULTS.md with the plots, the tables and each
# claim of the paper checked against the numbers (small PNGs go to docs/results/).
#
#   scripts/reproduce-paper.sh            # about 12 minutes on a 2-core machine
#   OUT=somewhere scripts/reproduce-paper.sh
#
# A stopped run continues where it stopped: converge keeps its finished rows and its cached
# references in $OUT.
set -euo pipefail
cd "$(dirname "$0")/.."

OUT=${OUT:-target/reproduce}
SPP=${SPP:-1,2,4,8,16,32,64,128,256}
REFERENCE_SPP=${REFERENCE_SPP:-4096}
SEEDS=${SEEDS:-2}
SCENES=${SCENES:-"paper-sky paper-gallery cornell"}

cargo build --release --quiet
BIN=target/release/lightsplit
start=$(date +%s)

for scene in $SCENES; do
    echo "== $scene" >&2
    "$BIN" converge "scenes/$scene.toml" --spp "$SPP" --reference-spp "$REFERENCE_SPP" --seeds "$SEEDS" \
        --filters none,box3,weighted3,median3 --targets indirect,image --edge-aware off,on \
        --diff-spp 64 --out "$OUT/$scene" > /dev/null
done
seconds=$(( $(date +%s) - start ))

mkdir -p docs/results
tmp=$(mktemp)
{
    echo "# Results: the paper's Figures 5 and 6, reproduced"
    echo
    echo "Written by \`scripts/reproduce-paper.sh\` (this run: ${seconds} s on $(nproc) cores)."
    echo "Each scene: ${SEEDS} seeds a point at ${SPP} samples per pixel, against a ${REFERENCE_SPP}-spp"
    echo "reference of the same scene; filters box3 (the paper's A), weighted3 (B) and median3 (C),"
    echo "on the indirect component (the paper's method) and on the whole image (its baseline), with"
    echo "and without edge-aware filtering. The raw rows are in \`$OUT/SCENE/results.csv\`."
    echo
    echo "The reference is itself noisy: its RMSE is about that of the unfiltered render times"
    echo "sqrt(spp / ${REFERENCE_SPP}), which puts a floor under every measured error at the"
    echo "highest sample counts (a few percent of the unfiltered error at 256 spp)."
    for scene in $SCENES; do
        dir="$OUT/$scene"
        for f in error-vs-spp error-vs-time; do
            cp "$dir/$f.png" "docs/results/$scene-$f.png"
        done
        for d in unfiltered weighted3-indirect weighted3-indirect-edge-aware; do
            cp "$dir/diff-64spp-$d.png" "docs/results/$scene-diff-64spp-$d.png"
        done
        echo
        echo "## \`scenes/$scene.toml\`"
        echo
        echo "![RMSE against spp](results/$scene-error-vs-spp.png)"
        echo "![RMSE against time](results/$scene-error-vs-time.png)"
        echo
        echo "Difference images at 64 spp (Figure 6; darker is a larger difference, all at the unfiltered"
        echo "image's scale): unfiltered, weighted3 on indirect, the same edge-aware."
        echo
        for d in unfiltered weighted3-indirect weighted3-indirect-edge-aware; do
            printf '![%s](results/%s-diff-64spp-%s.png) ' "$d" "$scene" "$d"
        done
        echo
        echo
        # The summary without its title, its headings one level down.
        tail -n +2 "$dir/summary.md" | sed 's/^## /### /'
    done
} > "$tmp"
mv "$tmp" docs/RESULTS.md
echo "wrote docs/RESULTS.md in ${seconds} s" >&2
