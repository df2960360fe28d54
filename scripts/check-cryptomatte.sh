#!/usr/bin/env bash
# Issue 40's check that real clients read lightsplit's Cryptomatte output. Each scene is
# rendered with `--cryptomatte`; then
#   1. OpenImageIO (`oiiotool --info -v`, Debian's openimageio-tools) must list the six rank
#      layers of CryptoObject and CryptoMaterial and their four header attributes each;
#   2. Blender 5's compositor (bpy from PyPI) makes, in a Cryptomatte node, the matte of every
#      name of each type's manifest, and each must equal the matte `lightsplit matte` reads from
#      the same file within 1/255 on at least 99.9% of the pixels
#      (scripts/peers/cryptomatte_check.py, scripts/peers/cryptomatte_blender.py).
# The scenes: scenes/cornell.toml (the pixel's box), the same with a thin lens and a splatted
# Gaussian filter (defocused, filtered edges: coverage shared between pixels), and
# scenes/paper-gallery.toml. Comparison only: Blender and OpenImageIO are not dependencies.
#
#   scripts/check-cryptomatte.sh                     # 128x128, 64 spp
#   scripts/check-cryptomatte.sh --size 64 --spp 16  # quicker
#
# Options:
#   --size N     image width and height (default 128)
#   --spp N      samples per pixel (default 64)
#   --out DIR    where the renders, mattes and table go (default ${TMPDIR:-/tmp}/lightsplit-cryptomatte)
#   --write      also write the table into docs/RESULTS.md (its `cryptomatte` section)
# Environment:
#   LIGHTSPLIT=BIN       use this binary instead of building with `cargo build --profile dist`
#   LIGHTSPLIT_PEERS_VENV=DIR  the virtual environment, outside the checkout, made with
#                        Python 3.11 (bpy's) (default ${XDG_CACHE_HOME:-$HOME/.cache}/lightsplit/peers-venv)
#   PYTHON=BIN           the Python that makes it (default python3.11)
#
# Writes OUT/table.md (also printed), OUT/SCENE.exr, OUT/SCENE.oiio.txt and the mattes. Exit
# status: 0 when every check passes, 1 when one fails, 2 on bad options.
set -euo pipefail
export PYTHONDONTWRITEBYTECODE=1

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
usage() { sed -n '2,/^set -euo/p' "${BASH_SOURCE[0]}" | sed '$d' | sed 's/^# \{0,1\}//'; }
bad_usage() { echo "check-cryptomatte: $*" >&2; echo "usage: scripts/check-cryptomatte.sh [options] (--help for more)" >&2; exit 2; }
fail() { echo "check-cryptomatte: error: $*" >&2; exit 1; }
note() { echo "check-cryptomatte: $*" >&2; }

size=128 spp=64 out=${TMPDIR:-/tmp}/lightsplit-cryptomatte write=0
while [ $# -gt 0 ]; do
    case $1 in
        --size | --spp | --out)
            [ $# -ge 2 ] || bad_usage "$1 needs a value"
            case $1 in --size) size=$2 ;; --spp) spp=$2 ;; --out) out=$2 ;; esac
            shift 2 ;;
        --write) write=1; shift ;;
        -h | --help) usage; exit 0 ;;
        *) bad_usage "unknown argument: $1" ;;
    esac
done
for pair in "size:$size" "spp:$spp"; do
    [[ ${pair#*:} =~ ^[1-9][0-9]{0,4}$ ]] || bad_usage "--${pair%%:*} must be a positive integer, got '${pair#*:}'"
done

if ! command -v oiiotool >/dev/null; then
    note "installing openimageio-tools (oiiotool)"
    apt-get install -y -qq openimageio-tools >/dev/null 2>&1 \
        || { apt-get update -qq && apt-get install -y -qq openimageio-tools >/dev/null; } \
        || fail "oiiotool is missing: apt-get install openimageio-tools"
fi
venv=${LIGHTSPLIT_PEERS_VENV:-${XDG_CACHE_HOME:-$HOME/.cache}/lightsplit/peers-venv}
case $venv/ in "$root"/*) bad_usage "the virtual environment ($venv) must be outside the checkout" ;; esac
python=${PYTHON:-python3.11}
if [ ! -x "$venv/bin/python" ]; then
    note "creating the virtual environment $venv with $python"
    mkdir -p "$(dirname "$venv")"
    "$python" -m venv "$venv" || fail "could not create $venv with $python (bpy needs Python 3.11)"
fi
if ! "$venv/bin/python" -c 'import bpy, numpy' 2>/dev/null; then
    note "installing bpy and numpy into $venv with pip"
    "$venv/bin/python" -m pip install -q --disable-pip-version-check bpy numpy || fail "pip could not install bpy"
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
# The Cornell box through a thin lens focused on the tall block, with a Gaussian filter.
sed -e 's/^\[camera\]$/[camera]\naperture = 12\nfocus_distance = 1050/' \
    -e 's/^\[film\]$/[film]\npixel_filter = "gaussian"/' "$root/scenes/cornell.toml" >"$out/cornell-defocus.toml"
table=$out/table.md
{
    echo "| scene | type | name | pixels covered | within 1/255 | largest difference | verdict |"
    echo "| --- | --- | --- | ---: | ---: | ---: | --- |"
} >"$table"
failed=0
for scene in "$root/scenes/cornell.toml" "$out/cornell-defocus.toml" "$root/scenes/paper-gallery.toml"; do
    name=$(basename "$scene" .toml)
    exr=$out/$name.exr
    "$lightsplit" render "$scene" -o "$exr" --width "$size" --height "$size" --spp "$spp" --cryptomatte \
        || fail "$name: the render failed"
    oiiotool --info -v "$exr" >"$out/$name.oiio.txt" || fail "$name: oiiotool cannot read $exr"
    for kind in CryptoObject CryptoMaterial; do
        for layer in 00 01 02; do
            for c in R G B A; do
                grep -q "channel list:.*\b$kind$layer\.$c\b" "$out/$name.oiio.txt" \
                    || { note "$name: oiiotool lists no channel $kind$layer.$c"; failed=1; }
            done
        done
        grep -qE "cryptomatte/[0-9a-f]{7}/name: \"$kind\"" "$out/$name.oiio.txt" \
            || { note "$name: oiiotool lists no cryptomatte/…/name \"$kind\""; failed=1; }
    done
    for attr in hash conversion manifest; do
        count=$(grep -cE "cryptomatte/[0-9a-f]{7}/$attr: " "$out/$name.oiio.txt" || true)
        [ "$count" = 2 ] || { note "$name: oiiotool lists $count cryptomatte/…/$attr attributes, not 2"; failed=1; }
    done
    "$venv/bin/python" "$root/scripts/peers/cryptomatte_check.py" --lightsplit "$lightsplit" \
        --exr "$exr" --out "$out/$name" --label "$name" >"$out/$name.json" || failed=1
    [ -f "$out/$name/rows.md" ] || fail "$name: the Blender check wrote no rows"
    cat "$out/$name/rows.md" >>"$table"
done
{
    echo
    echo "Blender $("$venv/bin/python" -c 'import bpy; print(bpy.app.version_string)' 2>/dev/null | tail -1)," \
        "oiiotool $(oiiotool --version 2>/dev/null | head -1); ${size}x${size}, $spp spp."
} >>"$table"
cat "$table"
[ "$failed" = 0 ] || fail "a check failed (above; oiiotool's listings are OUT/*.oiio.txt)"
note "every check passed; wrote $table"
if [ "$write" = 1 ]; then
    section=$out/section.md
    {
        echo "## Cryptomatte, read by Blender and OpenImageIO (issue 40)"
        echo
        echo "Written by \`scripts/check-cryptomatte.sh --size $size --spp $spp --write\`: every scene"
        echo "rendered with \`--cryptomatte\`; \`oiiotool --info -v\` lists the six rank layers and four"
        echo "header attributes of both types in each file; and for every name of each manifest, Blender's"
        echo "compositor (a Cryptomatte node on the EXR) makes a matte, compared with \`lightsplit matte\`'s"
        echo "of the same file. The goal: within 1/255 on 99.9% of the pixels."
        echo "\`cornell-defocus\` is the Cornell box through a thin lens (aperture radius 12, focused at"
        echo "1,050) with a splatted Gaussian filter."
        echo
        cat "$table"
    } >"$section"
    python3 "$root/scripts/results-section.py" write "$root/docs/RESULTS.md" cryptomatte scripts/check-cryptomatte.sh "$section"
    note "wrote the cryptomatte section of docs/RESULTS.md"
fi
