#!/usr/bin/env bash
# Denoisers side by side at equal samples (issue 17's table): on each scene, the unfiltered
# render, the paper's weighted3 on L_rdd, box5 on L_rdd with `--edge-aware --edge-pure`, the
# à-trous filter on L_rdd and on every component (`--denoise`), and Intel Open Image Denoise 2.5
# on the beauty with albedo and normal, all on the very same renders, against one reference.
# Then `converge` on each scene at 4 to 256 spp: --denoise against box5 --edge-pure on L_rdd.
# And on the gallery, the textured regions alone (carpet, pictures, marble): error, detail kept,
# crops. Prints its section of docs/RESULTS.md, `denoise`, and writes it there (through
# scripts/results-section.py: replaced where it is, appended when missing, the rest of the file
# left as it was).
#
#   scripts/bench-denoise.sh                  # about 15 minutes on a 2-core machine
#   SCENES=cornell scripts/bench-denoise.sh --no-write
#
# Options (each also an environment variable):
#   --spp N        (SPP)            samples per pixel of the renders, default 64
#   --seeds N      (SEEDS)          renders per scene (seeds 1..N), default 2
#   --reference-spp N (REFERENCE_SPP) default 4096 (independent sampling, seed 1000)
#   --no-write                      print the section only; leave docs/ alone
# Environment: SCENES (default "paper-sky paper-gallery cornell"), OUT (default
# target/bench-denoise; references there are reused), LIGHTSPLIT=BIN (this binary instead of
# `cargo build --profile dist`), LIGHTSPLIT_PEERS_VENV (the virtual environment for Mitsuba, which
# reads the EXR layers, and pyoidn; default ~/.cache/lightsplit/peers-venv, made when missing).
# OIDN is a comparison peer only: lightsplit never depends on it.
set -euo pipefail
export PYTHONDONTWRITEBYTECODE=1

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$root"
SPP=${SPP:-64}
SEEDS=${SEEDS:-2}
REFERENCE_SPP=${REFERENCE_SPP:-4096}
OUT=${OUT:-target/bench-denoise}
SCENES=${SCENES:-"paper-sky paper-gallery cornell"}
write=1
bad_usage() {
    echo "bench-denoise: $*" >&2
    echo "usage: scripts/bench-denoise.sh [--spp N] [--seeds N] [--reference-spp N] [--no-write]" >&2
    exit 2
}
while [ $# -gt 0 ]; do
    case $1 in
        --spp) SPP=${2:?}; shift 2 ;;
        --seeds) SEEDS=${2:?}; shift 2 ;;
        --reference-spp) REFERENCE_SPP=${2:?}; shift 2 ;;
        --no-write) write=0; shift ;;
        -h | --help) sed -n '2,/^set -euo/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//'; exit 0 ;;
        *) bad_usage "unknown option $1" ;;
    esac
done
for n in "$SPP" "$SEEDS" "$REFERENCE_SPP"; do
    [[ $n =~ ^[1-9][0-9]*$ ]] || bad_usage "$n is not a positive count"
done
for s in $SCENES; do
    [ -f "scenes/$s.toml" ] || bad_usage "no scenes/$s.toml"
done

if [ -n "${LIGHTSPLIT:-}" ]; then
    BIN=$LIGHTSPLIT
else
    cargo build --profile dist --quiet
    BIN=$root/target/dist/lightsplit
fi
venv=${LIGHTSPLIT_PEERS_VENV:-${XDG_CACHE_HOME:-$HOME/.cache}/lightsplit/peers-venv}
if [ ! -x "$venv/bin/python" ]; then
    echo "bench-denoise: creating the virtual environment $venv" >&2
    python3 -m venv "$venv" || { echo "bench-denoise: python3 -m venv failed (apt-get install python3-venv)" >&2; exit 1; }
fi
PY=$venv/bin/python
if ! "$PY" -c "import numpy, mitsuba, pyoidn" 2>/dev/null; then
    echo "bench-denoise: installing numpy, mitsuba and pyoidn into $venv" >&2
    "$PY" -m pip install --quiet numpy "mitsuba>=3,<4" "pyoidn==2.5.1.0"
fi

# The filters measured, as `name|flags of lightsplit filter` (no comma in a name: rows.csv).
SETTINGS=(
    "unfiltered|"
    "weighted3 indirect|--filter weighted3"
    "box5 indirect --edge-pure|--filter box5 --edge-aware --edge-pure"
    "atrous on indirect|--filter atrous:taps=3:passes=4:sigma_l=6:sigma_n=32:sigma_z=2"
    "--denoise (atrous on components; edge-pure)|--denoise"
)
mkdir -p "$OUT"
rows=$OUT/rows.csv
echo "scene,seed,method,rmse,relmse,seconds" > "$rows"
metric() { # IMAGE REFERENCE -> "rmse,relmse"
    "$BIN" compare "$1" "$2" --json | "$PY" -c 'import json,sys; d=json.load(sys.stdin); print("%.6e,%.6e" % (d["rmse"], d["relmse"]))'
}
for s in $SCENES; do
    dir=$OUT/$s
    mkdir -p "$dir"
    ref=$dir/reference-${REFERENCE_SPP}spp.exr
    if [ ! -f "$ref" ]; then
        echo "bench-denoise: $s: the ${REFERENCE_SPP}-spp reference" >&2
        "$BIN" render "scenes/$s.toml" --spp "$REFERENCE_SPP" --sampler independent --seed 1000 -o "$ref" --json >/dev/null
    fi
    for seed in $(seq 1 "$SEEDS"); do
        echo "bench-denoise: $s: seed $seed" >&2
        film=$dir/film-$seed.exr
        "$BIN" render "scenes/$s.toml" --spp "$SPP" --seed "$seed" -o "$film" --json >/dev/null
        for entry in "${SETTINGS[@]}"; do
            name=${entry%%|*}
            flags=${entry#*|}
            out=$dir/filtered-$seed.exr
            # The JSON read once the filter is over: Python starting inside a pipe shares the
            # cores with the filter it times (paper-sky's 12 to 16 ms filter read 21 to 36 ms).
            # shellcheck disable=SC2086
            json=$("$BIN" filter "$film" -o "$out" $flags --json)
            seconds=$(printf '%s\n' "$json" | "$PY" -c 'import json,sys; print(json.load(sys.stdin)["filter_seconds"])')
            echo "$s,$seed,$name,$(metric "$out" "$ref"),$seconds" >> "$rows"
        done
        oidn=$dir/oidn-$seed.pfm
        seconds=$("$PY" scripts/peers/oidn.py "$film" "$oidn" --threads 2 | "$PY" -c 'import json,sys; print(json.load(sys.stdin)["seconds"])')
        echo "$s,$seed,OIDN 2.5 (beauty + albedo + normal),$(metric "$oidn" "$ref"),$seconds" >> "$rows"
    done
done
# The textured regions of the gallery (seed 1): error and detail kept, and crops.
if [[ " $SCENES " == *" paper-gallery "* ]]; then
    dir=$OUT/paper-gallery
    "$BIN" filter "$dir/film-1.exr" -o "$dir/denoised-1.exr" --denoise
    "$PY" scripts/denoise/regions.py --bin "$BIN" "$dir/film-1.exr" "$dir/reference-${REFERENCE_SPP}spp.exr" \
        "unfiltered=$dir/film-1.exr" "denoise=$dir/denoised-1.exr" "OIDN 2.5=$dir/oidn-1.pfm" \
        --crops "$OUT/gallery-crops.png" > "$OUT/regions.md"
fi
# Against box5 --edge-pure at every spp from 4 to 256: converge, which renders each spp once per
# seed and filters that render both ways.
# --denoise's filter as converge names it, from the binary itself (`filter --json`).
first=${SCENES%% *}
DENOISE_KERNEL=$("$BIN" filter "$OUT/$first/film-1.exr" -o "$OUT/$first/denoise-name.exr" --denoise --json |
    "$PY" -c 'import json, sys; print(json.load(sys.stdin)["filter"])')
for s in $SCENES; do
    echo "bench-denoise: $s: converge at 4 to 256 spp" >&2
    # converge resumes the rows it finds for the same settings, whatever binary made them; a
    # change that keeps the filter's name (a constant of the filter) would leave them stale.
    rm -rf "$OUT/$s/converge"
    "$BIN" converge "scenes/$s.toml" --reference "$OUT/$s/reference-${REFERENCE_SPP}spp.exr" \
        --spp 4,16,64,256 --seeds "$SEEDS" --filters "none,box5,$DENOISE_KERNEL" \
        --targets indirect,components --edge-aware pure --out "$OUT/$s/converge" >/dev/null
done
args=("$rows" --spp "$SPP" --seeds "$SEEDS" --reference-spp "$REFERENCE_SPP" --regions "$OUT/regions.md"
    --curves "$OUT" --denoise-kernel "$DENOISE_KERNEL")
if [ "$write" = 1 ]; then
    mkdir -p docs/results
    [ -f "$OUT/gallery-crops.png" ] && cp "$OUT/gallery-crops.png" docs/results/denoise-gallery-crops.png
    for s in $SCENES; do
        c=$OUT/$s/converge
        cp "$c/error-vs-time.png" "docs/results/denoise-$s-error-vs-time.png"
        cp "$c/diff-${SPP}spp-unfiltered.png" "docs/results/denoise-$s-diff-unfiltered.png" 2>/dev/null || true
        cp "$c/diff-${SPP}spp-box5-indirect-edge-aware-pure.png" "docs/results/denoise-$s-diff-box5.png" 2>/dev/null || true
        cp "$c/diff-${SPP}spp-$DENOISE_KERNEL-components-edge-aware-pure.png" "docs/results/denoise-$s-diff-denoise.png" 2>/dev/null || true
    done
    args+=(--figures "$SCENES")
fi
"$PY" scripts/denoise/report.py "${args[@]}" > "$OUT/section.md"
cat "$OUT/section.md"
if [ "$write" = 1 ]; then
    "$PY" scripts/results-section.py write docs/RESULTS.md denoise scripts/bench-denoise.sh "$OUT/section.md"
    echo "bench-denoise: wrote the denoise section of docs/RESULTS.md" >&2
fi
