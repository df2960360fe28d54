#!/usr/bin/env bash
# Issue 19's check of the glTF import against Blender: Blender (bpy from PyPI, Python 3.11)
# builds a scene and exports it with its own glTF exporter; Blender's Cycles and lightsplit each
# render the exported file under scenes/sky.hdr through the same camera; the per-region means
# (lightsplit's object IDs) and the layout are compared (scripts/compare-blender.py: exit 1 when
# a region's mean differs by more than 5%). Comparison only: Blender is not a dependency.
#
#   scripts/compare-blender.sh [OUT_DIR] [SPP]    # default /tmp/lightsplit-blender, 512 spp (lightsplit 1024)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-/tmp/lightsplit-blender}
spp=${2:-512}
venv=${LIGHTSPLIT_PEERS_VENV:-$HOME/.cache/lightsplit/peers-venv}
mkdir -p "$out"
if [ ! -x "$venv/bin/python" ]; then
  python3.11 -m venv "$venv"
fi
"$venv/bin/python" -c "import bpy, OpenEXR, numpy" 2>/dev/null || "$venv/bin/pip" install -q bpy OpenEXR numpy
cargo build --release -q
"$venv/bin/python" scripts/blender-gltf.py export "$out/blender.glb"
cp scenes/sky.hdr "$out/sky.hdr"
# The exported camera, as scripts/blender-gltf.py places it, in glTF's y-up coordinates.
cat >"$out/lightsplit.toml" <<TOML
[camera]
position = [0, 2.2, 6.5]
look_at = [0, 0.6, 0]
fov = 32
[film]
width = 320
height = 200
spp = $((2 * spp))
[[shape]]
type = "gltf"
file = "blender.glb"
[[light]]
type = "environment"
file = "sky.hdr"
TOML
target/release/lightsplit render "$out/lightsplit.toml" -o "$out/lightsplit.exr"
"$venv/bin/python" scripts/blender-gltf.py render "$out/blender.glb" "$out/sky.hdr" "$out/blender.exr" 320 200 "$spp" \
  >"$out/blender.log" 2>&1 || { tail -20 "$out/blender.log"; exit 1; }
"$venv/bin/python" scripts/compare-blender.py "$out/lightsplit.exr" "$out/blender.exr" "$out/side-by-side.png"
