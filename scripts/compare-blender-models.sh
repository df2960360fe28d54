#!/usr/bin/env bash
# Issue 36's validation against Blender on third-party models: each model of the list is
# imported by Blender 5's own glTF importer and rendered in Cycles (scripts/blender-gltf.py
# model: lightsplit's framing of a model without a camera, a uniform white sky of radiance 1,
# 8 bounces, no blur, clamping or denoising), then rendered by lightsplit from the TOML the same
# script writes (same file, camera, film and sky, twice the samples), and compared region by
# region through the binary (`lightsplit compare --by-object`, inner pixels of each of
# lightsplit's object IDs: scripts/compare-blender.py). Writes OUT_DIR/report.md (one row a
# model: the worst region, the regions within 5%, the pixels within 25%) and each model's
# side-by-side PNG, and OUT_DIR/gallery.png, a contact sheet of them (lightsplit left, Blender
# right; docs/gallery.png is one). Comparison only: Blender is not a dependency.
#
#   scripts/compare-blender-models.sh MODELS_DIR [OUT_DIR] [SPP] [WIDTH HEIGHT]
#
# MODELS_DIR holds the Khronos sample models in the layout of KhronosGroup/glTF-Sample-Assets
# (MODELS_DIR/Models/NAME/glTF-Binary/NAME.glb, or .../glTF/NAME.gltf), for example a checkout
# of the repository DRx3D/glTF-Sample-Assets-OLD; $FLIGHT_HELMET may name FlightHelmet.gltf
# (bevyengine/bevy's assets/models/FlightHelmet). The files are never committed here.
# Defaults: /tmp/lightsplit-blender-models, 128 spp in Cycles (256 in lightsplit), 320x240.
# $MODELS, a list of names, replaces issue 36's list (for example the texture tests:
# MODELS="TextureSettingsTest VertexColorTest MultiUVTest NormalTangentMirrorTest").
set -euo pipefail
cd "$(dirname "$0")/.."
models=${1:?usage: scripts/compare-blender-models.sh MODELS_DIR [OUT_DIR] [SPP] [WIDTH HEIGHT]}
out=${2:-/tmp/lightsplit-blender-models}
spp=${3:-128}
width=${4:-320}
height=${5:-240}
venv=${LIGHTSPLIT_PEERS_VENV:-$HOME/.cache/lightsplit/peers-venv}
binary=${LIGHTSPLIT:-target/release/lightsplit}
default_names=(DamagedHelmet FlightHelmet ToyCar SheenChair SheenCloth ClearCoatTest ClearCoatCarPaint SpecularTest
  TransmissionTest TransmissionRoughnessTest AttenuationTest GlassVaseFlowers GlassHurricaneCandleHolder
  EmissiveStrengthTest StainedGlassLamp TextureTransformTest TextureTransformMultiTest UnlitTest
  SpecGlossVsMetalRough IridescenceLamp MetalRoughSpheresNoTextures)
# shellcheck disable=SC2206
names=(${MODELS:-${default_names[@]}})

mkdir -p "$out"
if [ ! -x "$venv/bin/python" ]; then
  python3.11 -m venv "$venv"
fi
"$venv/bin/python" -c "import bpy, OpenEXR, numpy, PIL" 2>/dev/null || "$venv/bin/pip" install -q bpy OpenEXR numpy pillow
[ -n "${LIGHTSPLIT:-}" ] || cargo build --release -q

report="$out/report.md"
{
  echo "Blender $("$venv/bin/python" -c 'import bpy; print(bpy.app.version_string)') Cycles at $spp spp, lightsplit at $((2 * spp)) spp, ${width}x${height}, a white sky of radiance 1."
  echo
  echo "| model | regions | within 5% | worst region (ratio) | pixels within 25% |"
  echo "|---|---:|---:|---|---:|"
} >"$report"
for name in "${names[@]}"; do
  file=""
  for f in "$models/Models/$name/glTF-Binary/$name.glb" "$models/Models/$name/glTF/$name.gltf"; do
    [ -f "$f" ] && { file=$f; break; }
  done
  [ "$name" = FlightHelmet ] && [ -n "${FLIGHT_HELMET:-}" ] && file=$FLIGHT_HELMET
  if [ -z "$file" ]; then
    echo "| $name | not found in MODELS_DIR | | | |" >>"$report"
    continue
  fi
  dir="$out/$name"
  mkdir -p "$dir"
  echo "== $name"
  if ! "$venv/bin/python" scripts/blender-gltf.py model "$file" "$dir" "$width" "$height" "$spp" >"$dir/blender.log" 2>&1; then
    echo "| $name | Blender failed: $(tail -1 "$dir/blender.log") | | | |" >>"$report"
    continue
  fi
  if ! "$binary" render "$dir/lightsplit.toml" -o "$dir/lightsplit.exr" >"$dir/lightsplit.log" 2>&1; then
    echo "| $name | lightsplit failed: $(grep -m1 error "$dir/lightsplit.log") | | | |" >>"$report"
    continue
  fi
  LIGHTSPLIT=$binary "$venv/bin/python" scripts/compare-blender.py "$dir/lightsplit.exr" "$dir/blender.exr" \
    "$dir/side-by-side.png" >"$dir/compare.txt" || true
  cat "$dir/compare.txt"
  # The regions' rows (background included), their ratios, the worst, and the layout line.
  "$venv/bin/python" - "$dir/compare.txt" "$name" >>"$report" <<'PY'
import re, sys
text = open(sys.argv[1]).read()
rows = [l.split() for l in text.splitlines()[1:] if re.match(r"\s*(background|object \d+)\s", l)]
ratios = [(f"object {r[1]}" if r[0] == "object" else r[0], float(r[-1])) for r in rows]
within = sum(abs(x - 1) <= 0.05 for _, x in ratios)
worst = max(ratios, key=lambda r: abs(r[1] - 1)) if ratios else ("-", 1.0)
layout = re.search(r"layout: ([\d.]+)%", text)
print(f"| {sys.argv[2]} | {len(ratios)} | {within} | {worst[0]} ({worst[1]:.3f}) | {layout.group(1) if layout else '-'}% |")
PY
done
# The contact sheet: each model's side-by-side (lightsplit | Blender), named, three a row.
"$venv/bin/python" - "$out" "${names[@]}" <<'PY'
import os, sys
from PIL import Image, ImageDraw
out, names = sys.argv[1], sys.argv[2:]
tiles = [(n, Image.open(os.path.join(out, n, "side-by-side.png")).convert("RGB"))
         for n in names if os.path.exists(os.path.join(out, n, "side-by-side.png"))]
if tiles:
    w, h = tiles[0][1].size
    cols = 3
    rows = (len(tiles) + cols - 1) // cols
    sheet = Image.new("RGB", (cols * (w + 8), rows * (h + 22)), (40, 40, 40))
    draw = ImageDraw.Draw(sheet)
    for i, (name, tile) in enumerate(tiles):
        x, y = (i % cols) * (w + 8), (i // cols) * (h + 22)
        sheet.paste(tile.resize((w, h)), (x, y + 18))
        draw.text((x + 4, y + 3), f"{name}: lightsplit | Blender Cycles", fill=(230, 230, 230))
    sheet.save(os.path.join(out, "gallery.png"))
    print(f"wrote {os.path.join(out, 'gallery.png')}")
PY
cat "$report"
