#!/usr/bin/env bash
# Independent against Owen-scrambled Sobol sampling on every scene in scenes/: what sobol is
# worth in samples ("the samples independent sampling needs for sobol's RMSE"), what it costs
# in samples per second, and what the paper's filters on L_rdd gain under each. Writes its
# section of docs/RESULTS.md, `samplers` (through scripts/results-section.py: replaced where it
# is, appended when missing, the rest of the file left as it was), and its plots into
# docs/results/.
#
#   scripts/bench-samplers.sh                 # about 40 minutes on a 2-core machine
#   SCENES="cornell paper-sky" scripts/bench-samplers.sh --no-write
#
# Options (each also an environment variable):
#   --size N      (SIZE)       image width and height, default 128
#   --spp LIST    (SPP)        sample counts, default 4,8,16,32,64,128,256
#   --seeds N     (SEEDS)      renders per point, default 4
#   --reference-spp N (REFERENCE_SPP)  default 4096
#   --rounds N    (ROUNDS)     alternated rounds of the speed comparison, default 5
#   --no-write                 print the section only; leave docs/ alone
# Environment: SCENES (default: every scenes/*.toml), OUT (default target/bench-samplers; a
# stopped run continues from its rows and cached references there), LIGHTSPLIT=BIN (this binary
# instead of `cargo build --profile dist`).
set -euo pipefail
export PYTHONDONTWRITEBYTECODE=1

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$root"
SIZE=${SIZE:-128}
SPP=${SPP:-4,8,16,32,64,128,256}
SEEDS=${SEEDS:-4}
REFERENCE_SPP=${REFERENCE_SPP:-4096}
ROUNDS=${ROUNDS:-5}
OUT=${OUT:-target/bench-samplers}
write=1
bad_usage() {
    echo "bench-samplers: $*" >&2
    echo "usage: scripts/bench-samplers.sh [--size N] [--spp LIST] [--seeds N] [--reference-spp N] [--rounds N] [--no-write]" >&2
    exit 2
}
while [ $# -gt 0 ]; do
    case $1 in
        --size) SIZE=${2:?}; shift 2 ;;
        --spp) SPP=${2:?}; shift 2 ;;
        --seeds) SEEDS=${2:?}; shift 2 ;;
        --reference-spp) REFERENCE_SPP=${2:?}; shift 2 ;;
        --rounds) ROUNDS=${2:?}; shift 2 ;;
        --no-write) write=0; shift ;;
        -h | --help) sed -n '2,/^set -euo/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//'; exit 0 ;;
        *) bad_usage "unknown option $1" ;;
    esac
done
for n in "$SIZE" "$SEEDS" "$REFERENCE_SPP" "$ROUNDS"; do
    [[ $n =~ ^[1-9][0-9]*$ ]] || bad_usage "$n is not a positive count"
done
[[ $SPP =~ ^[1-9][0-9]*(,[1-9][0-9]*)*$ ]] || bad_usage "--spp takes counts such as 4,16,64"
if [ -z "${SCENES:-}" ]; then
    SCENES=$(for f in scenes/*.toml; do basename "$f" .toml; done)
fi
SCENES=$(echo $SCENES) # one line, one space apart
for s in $SCENES; do
    [ -f "scenes/$s.toml" ] || bad_usage "no scenes/$s.toml"
done

if [ -n "${LIGHTSPLIT:-}" ]; then
    BIN=$LIGHTSPLIT
else
    cargo build --profile dist --quiet
    BIN=target/dist/lightsplit
fi
mkdir -p "$OUT"
start=$(date +%s)

# The speed comparison first, on an idle machine: each scene rendered with either sampler in
# every round, the first one alternating, at 64 spp (at most the largest measured).
speed=$OUT/speed.tsv
: > "$speed"
for round in $(seq 1 "$ROUNDS"); do
    for s in $SCENES; do
        order="independent sobol"
        [ $((round % 2)) -eq 0 ] && order="sobol independent"
        for sampler in $order; do
            json=$("$BIN" render "scenes/$s.toml" -o "$OUT/speed-$s.png" --width "$SIZE" --height "$SIZE" \
                --spp 64 --sampler "$sampler" --json)
            printf '%s\t%s\t%s\t%s\n' "$round" "$s" "$sampler" "$json" >> "$speed"
        done
    done
done

# Error against samples: both samplers, the paper's filters on L_rdd, one run per scene.
for s in $SCENES; do
    echo "== $s" >&2
    "$BIN" converge "scenes/$s.toml" --sampler independent,sobol --spp "$SPP" --seeds "$SEEDS" \
        --reference-spp "$REFERENCE_SPP" --width "$SIZE" --height "$SIZE" \
        --filters none,box3,weighted3,median3,box5 --diff-spp 64 --out "$OUT/$s" > /dev/null
done
# Sample counts between the powers of two, where a Sobol net is incomplete, against the same
# references.
NPOT_SCENES=${NPOT_SCENES:-"cornell paper-sky"}
for s in $NPOT_SCENES; do
    case " $SCENES " in *" $s "*) ;; *) continue ;; esac
    reference=$(ls "$OUT/$s"/reference-*.exr | head -1)
    echo "== $s between powers of two" >&2
    "$BIN" converge "scenes/$s.toml" --sampler independent,sobol --spp 24,48,96,192 --seeds "$SEEDS" \
        --reference "$reference" --width "$SIZE" --height "$SIZE" --filters none --out "$OUT/$s-npot" > /dev/null
done
seconds=$(( $(date +%s) - start ))

section=$(mktemp)
NPOT_SCENES=$NPOT_SCENES python3 scripts/samplers/report.py "$OUT" "$speed" "$seconds" "$SIZE" "$SPP" "$SEEDS" \
    "$REFERENCE_SPP" "$ROUNDS" $SCENES > "$section"
if [ "$write" = 1 ]; then
    mkdir -p docs/results
    for s in $SCENES; do
        cp "$OUT/$s/error-vs-spp.png" "docs/results/samplers-$s-error-vs-spp.png"
    done
    for s in cornell paper-sky; do
        for d in independent-unfiltered sobol-unfiltered; do
            if [ -f "$OUT/$s/diff-64spp-$d.png" ]; then
                cp "$OUT/$s/diff-64spp-$d.png" "docs/results/samplers-$s-diff-64spp-$d.png"
            fi
        done
    done
    python3 scripts/results-section.py write docs/RESULTS.md samplers scripts/bench-samplers.sh "$section"
    echo "wrote the samplers section of docs/RESULTS.md in ${seconds} s" >&2
else
    cat "$section"
fi
rm -f "$section"
