#!/usr/bin/env bash
# Issue 39's comparison with Blender's Cycles on the two hard-light scenes (made by
# scripts/make-hard-light-scenes.py): scenes/many-lights.toml (a city at night: 640 emissive
# windows and 384 point lights) and scenes/window-room.toml (a room lit through one window by a
# sun and a sky). Both programs render the same glTF file (scenes/gltf/NAME.glb, which the TOML
# places, adding only the sky): lightsplit with LIGHTSPLIT_ARGS (e.g. its light tree and path
# guiding), Cycles (bpy from PyPI) with its light tree and path guiding on. Each program's
# error is its relative RMSE against its own high-spp reference, measured by `lightsplit
# compare`; the table gives the time each needs to reach the error Cycles reaches at the middle
# spp, and their ratio. scripts/peers/cycles_hard_light.py does the work (its docstring has the
# method: units, camera, settings, timing). Comparison only: Blender is not a dependency.
#
#   scripts/compare-cycles.sh                                    # 128x128, refs at 4096 spp
#   LIGHTSPLIT_ARGS="--light-sampler tree --guiding" scripts/compare-cycles.sh
#   scripts/compare-cycles.sh --size 48 --spp 4,16 --reference-spp 64    # a quick check
#
# Options:
#   --size N             image width and height (default 128)
#   --spp LIST           the sample counts timed, commas (default 16,64,256)
#   --reference-spp N    the references' samples per pixel (default 4096)
#   --scenes LIST        scene names under scenes/, commas (default many-lights,window-room)
#   --threads N          threads for both programs (default 2)
#   --out DIR            where the renders, PNGs and table go (default ${TMPDIR:-/tmp}/lightsplit-cycles)
# Environment:
#   LIGHTSPLIT=BIN       use this binary instead of building with `cargo build --profile dist`
#   LIGHTSPLIT_ARGS=ARGS extra flags for every lightsplit render (default none)
#   LIGHTSPLIT_PEERS_VENV=DIR  the virtual environment, outside the checkout, made with
#                        Python 3.11 (bpy's) (default ${XDG_CACHE_HOME:-$HOME/.cache}/lightsplit/peers-venv)
#   PYTHON=BIN           the Python that makes it (default python3.11)
#
# Writes OUT/table.md (also printed, Markdown), OUT/rows.json, every render (EXR),
# OUT/NAME-side-by-side.png (lightsplit's reference, Cycles' reference, then each at the middle
# spp) and OUT/blender.log. Exit status: 0 when every scene rendered in both, 1 on a failure,
# 2 on bad options.
set -euo pipefail
export PYTHONDONTWRITEBYTECODE=1

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
usage() { sed -n '2,/^set -euo/p' "${BASH_SOURCE[0]}" | sed '$d' | sed 's/^# \{0,1\}//'; }
bad_usage() { echo "compare-cycles: $*" >&2; echo "usage: scripts/compare-cycles.sh [options] (--help for more)" >&2; exit 2; }
fail() { echo "compare-cycles: error: $*" >&2; exit 1; }
note() { echo "compare-cycles: $*" >&2; }

size=128 spp=16,64,256 reference_spp=4096 scenes=many-lights,window-room threads=2
out=${TMPDIR:-/tmp}/lightsplit-cycles
while [ $# -gt 0 ]; do
    case $1 in
        --size | --spp | --reference-spp | --scenes | --threads | --out)
            [ $# -ge 2 ] || bad_usage "$1 needs a value"
            case $1 in
                --size) size=$2 ;; --spp) spp=$2 ;; --reference-spp) reference_spp=$2 ;;
                --scenes) scenes=$2 ;; --threads) threads=$2 ;; --out) out=$2 ;;
            esac
            shift 2 ;;
        -h | --help) usage; exit 0 ;;
        *) bad_usage "unknown argument: $1" ;;
    esac
done
for pair in "size:$size" "reference-spp:$reference_spp" "threads:$threads"; do
    [[ ${pair#*:} =~ ^[1-9][0-9]{0,5}$ ]] || bad_usage "--${pair%%:*} must be a positive integer, got '${pair#*:}'"
done
[ "$size" -ge 8 ] || bad_usage "--size must be at least 8"
[[ $spp =~ ^[1-9][0-9]*(,[1-9][0-9]*)*$ ]] || bad_usage "--spp takes positive integers separated by commas"
[[ $scenes =~ ^[a-z0-9-]+(,[a-z0-9-]+)*$ ]] || bad_usage "--scenes takes scene names separated by commas"
for name in ${scenes//,/ }; do
    [ -f "$root/scenes/$name.toml" ] || bad_usage "no scene scenes/$name.toml"
done

venv=${LIGHTSPLIT_PEERS_VENV:-${XDG_CACHE_HOME:-$HOME/.cache}/lightsplit/peers-venv}
case $venv/ in "$root"/*) bad_usage "the virtual environment ($venv) must be outside the checkout" ;; esac
python=${PYTHON:-python3.11}
if [ ! -x "$venv/bin/python" ]; then
    note "creating the virtual environment $venv with $python"
    mkdir -p "$(dirname "$venv")"
    "$python" -m venv "$venv" || fail "could not create $venv with $python (bpy needs Python 3.11)"
fi
# bpy's wheels are for one Python version: a venv another script made with another Python
# cannot take it.
version=$("$venv/bin/python" -c 'import sys; print("%d.%d" % sys.version_info[:2])')
if ! "$venv/bin/python" -c 'import bpy, OpenEXR, numpy' 2>/dev/null; then
    [ "$version" = 3.11 ] || fail "$venv is Python $version; bpy needs 3.11 (set LIGHTSPLIT_PEERS_VENV to another directory)"
    note "installing bpy, OpenEXR and numpy into $venv with pip"
    "$venv/bin/python" -m pip install -q --disable-pip-version-check bpy OpenEXR numpy || fail "pip could not install bpy"
fi

if [ -n "${LIGHTSPLIT:-}" ]; then
    [ -x "$LIGHTSPLIT" ] || bad_usage "LIGHTSPLIT=$LIGHTSPLIT is not an executable file"
    lightsplit=$(cd "$(dirname "$LIGHTSPLIT")" && pwd)/$(basename "$LIGHTSPLIT")
else
    "$root/scripts/setup.sh"
    note "building lightsplit: cargo build --profile dist"
    (cd "$root" && cargo build --profile dist)
    lightsplit=$root/target/dist/lightsplit
fi

mkdir -p "$out"
"$venv/bin/python" "$root/scripts/peers/cycles_hard_light.py" --lightsplit "$lightsplit" --out "$out" \
    --size "$size" --spp "$spp" --reference-spp "$reference_spp" --scenes "$scenes" --threads "$threads" \
    "--lightsplit-args=${LIGHTSPLIT_ARGS:-}" \
    || fail "the comparison failed (Blender's messages are in $out/blender.log)"
note "wrote $out/table.md and $out/*-side-by-side.png"
