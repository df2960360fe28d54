#!/usr/bin/env bash
# Renders Mitsuba XML scenes in lightsplit and in Mitsuba 3 (scalar_rgb) from the same file and
# compares them (scripts/mitsuba/compare.py does the work; its docstring has the method): the
# channel means of both high-spp references (limit 0.5%), the worst 32x32 block (limit 2%), and
# the render time each needs to reach the same relative RMSE against its own reference, Mitsuba
# with the best of its independent, stratified and multijitter samplers. Prints a Markdown table
# and writes it, with the machine, into the `compare-mitsuba` section of docs/RESULTS.md
# (through scripts/results-section.py).
#
#   scripts/compare-mitsuba.sh SCENE.xml...           # 256 pixels, references at 1024 spp
#   scripts/compare-mitsuba.sh --size 64 --reference-spp 64 --spp 4,16 --no-write SCENE.xml
#
# The scenes are third-party files, never committed: for example Mitsuba's own
# (mitsuba-renderer/mitsuba-data: scenes/cbox/cbox.xml, docs/scenes/integrator_direct_both.xml
# for Veach's MIS scene) and Bitterli's in Mitsuba 2 XML (jgarciapueyo/mitsuba2-transient-scenes:
# cbox, cbox-spheres, staircase, staircase2, living-room, each a scene.xml).
#
# Options:
#   --size N             the longer side of every image (default 256)
#   --reference-spp N    the references' samples per pixel (default 1024)
#   --spp LIST           the sample counts timed, commas (default 4,16,64)
#   --rounds N           timed rounds, alternating the programs (default 1)
#   --threads N          threads for both programs (default: nproc)
#   --keep DIR           keep the renders (EXR) and the measured points (rows.json) in DIR
#   --no-write           print the table only; leave docs/RESULTS.md alone
# Environment:
#   LIGHTSPLIT=BIN       use this binary instead of building with `cargo build --profile dist`
#   LIGHTSPLIT_PEERS_VENV=DIR  Mitsuba's virtual environment, outside the checkout (default
#                        ${XDG_CACHE_HOME:-$HOME/.cache}/lightsplit/peers-venv, as bench-peers.sh)
#   MITSUBA_PIP=SPEC     what pip installs there when Mitsuba is missing (default "mitsuba>=3,<4")
#
# Writes each scene's copy (`.compare-NAME-SAMPLER.xml`) beside it while it runs, and removes it.
# Exit status: 0 when every scene rendered in both, 1 on a failure, 2 on bad options.
set -euo pipefail
export PYTHONDONTWRITEBYTECODE=1

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
usage() { sed -n '2,/^set -euo/p' "${BASH_SOURCE[0]}" | sed '$d' | sed 's/^# \{0,1\}//'; }
bad_usage() { echo "compare-mitsuba: $*" >&2; echo "usage: scripts/compare-mitsuba.sh [options] SCENE.xml... (--help for more)" >&2; exit 2; }
fail() { echo "compare-mitsuba: error: $*" >&2; exit 1; }
note() { echo "compare-mitsuba: $*" >&2; }

size=256 reference_spp=1024 spp=4,16,64 rounds=1 threads=$(nproc) write=1 keep=
scenes=()
while [ $# -gt 0 ]; do
    case $1 in
        --size | --reference-spp | --spp | --rounds | --threads | --keep)
            [ $# -ge 2 ] || bad_usage "$1 needs a value"
            case $1 in
                --size) size=$2 ;; --reference-spp) reference_spp=$2 ;; --spp) spp=$2 ;;
                --rounds) rounds=$2 ;; --threads) threads=$2 ;; --keep) keep=$2 ;;
            esac
            shift 2 ;;
        --no-write) write=0; shift ;;
        -h | --help) usage; exit 0 ;;
        -*) bad_usage "unknown option: $1" ;;
        *) [ -f "$1" ] || bad_usage "$1 is not a file"; scenes+=("$(cd "$(dirname "$1")" && pwd)/$(basename "$1")"); shift ;;
    esac
done
[ ${#scenes[@]} -gt 0 ] || bad_usage "no scene given"
for pair in "size:$size" "reference-spp:$reference_spp" "rounds:$rounds" "threads:$threads"; do
    [[ ${pair#*:} =~ ^[1-9][0-9]{0,5}$ ]] || bad_usage "--${pair%%:*} must be a positive integer, got '${pair#*:}'"
done
[[ $spp =~ ^[1-9][0-9]*(,[1-9][0-9]*)*$ ]] || bad_usage "--spp takes positive integers separated by commas"

venv=${LIGHTSPLIT_PEERS_VENV:-${XDG_CACHE_HOME:-$HOME/.cache}/lightsplit/peers-venv}
case $venv/ in "$root"/*) bad_usage "the virtual environment ($venv) must be outside the checkout" ;; esac
if [ ! -x "$venv/bin/python" ]; then
    note "creating the virtual environment $venv"
    mkdir -p "$(dirname "$venv")"
    python3 -m venv "$venv" || fail "could not create $venv (Debian: apt-get install python3-venv)"
fi
if ! "$venv/bin/python" -c 'import mitsuba, numpy' 2>/dev/null; then
    spec=${MITSUBA_PIP:-mitsuba>=3,<4}
    note "installing $spec and numpy into $venv with pip"
    "$venv/bin/python" -m pip install -q --disable-pip-version-check "$spec" numpy || fail "pip could not install $spec"
fi
read -r mitsuba_version drjit_version < <("$venv/bin/python" -c 'import mitsuba, drjit; print(mitsuba.__version__, drjit.__version__)')

if [ -n "${LIGHTSPLIT:-}" ]; then
    [ -x "$LIGHTSPLIT" ] || bad_usage "LIGHTSPLIT=$LIGHTSPLIT is not an executable file"
    lightsplit=$(cd "$(dirname "$LIGHTSPLIT")" && pwd)/$(basename "$LIGHTSPLIT")
    about="a prebuilt binary given by LIGHTSPLIT"
else
    "$root/scripts/setup.sh"
    note "building lightsplit: cargo build --profile dist"
    (cd "$root" && cargo build --profile dist)
    lightsplit=$root/target/dist/lightsplit
    about="built with cargo build --profile dist"
fi
commit=$(git -C "$root" rev-parse --short HEAD 2>/dev/null || echo unknown)

tmp=$(mktemp -d "${TMPDIR:-/tmp}/compare-mitsuba.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
"$venv/bin/python" "$root/scripts/mitsuba/compare.py" --lightsplit "$lightsplit" --out "${keep:-$tmp/out}" \
    --size "$size" --reference-spp "$reference_spp" --spp "$spp" --rounds "$rounds" --threads "$threads" \
    --table "$tmp/table.md" "${scenes[@]}"
[ "$write" = 1 ] || exit 0

cpu=$(lscpu 2>/dev/null | sed -n 's/^Model name: *//p' | head -1)
flags=$(grep -o -w 'avx512f\|avx2' /proc/cpuinfo | sort -u | tr '\n' ' ')
{
    echo "## Against Mitsuba 3 on Mitsuba's own scenes"
    echo
    "$venv/bin/python" -c 'import sys, textwrap
print(textwrap.fill(" ".join(sys.stdin.read().split()), 100, break_long_words=False, break_on_hyphens=False))' <<TEXT
Written by \`scripts/compare-mitsuba.sh\` on $(date -u +%Y-%m-%d): ${cpu:-unknown CPU} (${flags:-no AVX2}), $(nproc) CPUs;
Mitsuba $mitsuba_version (Dr.Jit $drjit_version, \`scalar_rgb\`); lightsplit at $commit, $about. Each scene's
file unchanged but for its film's size ($size pixels on the longer side) and its sampler; references at
$reference_spp spp; timed at $spp spp, $rounds round(s), $threads threads each, render time alone. Means and
blocks compare lightsplit's reference with Mitsuba's (the block's noise, from both references, in brackets);
"sooner" is Mitsuba's time to the target relative RMSE (its best sampler's error at the middle spp) over
lightsplit's, each against its own reference.
TEXT
    echo
    cat "$tmp/table.md"
} >"$tmp/section.md"
"$venv/bin/python" "$root/scripts/results-section.py" write "$root/docs/RESULTS.md" compare-mitsuba scripts/compare-mitsuba.sh "$tmp/section.md"
note "wrote the compare-mitsuba section of docs/RESULTS.md"
