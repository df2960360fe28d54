#!/usr/bin/env bash
# Issue 37's compressed-glTF goal: the scenes of the repository gkjohnson/3d-demo-data that
# require EXT_meshopt_compression, each loaded (`lightsplit info`) and rendered at 320x240,
# 16 spp, into OUT_DIR/NAME.png, with a line a scene in OUT_DIR/report.md. Point it at a
# checkout (or an extracted snapshot) of that repository; its files are never committed here.
# A texture the checkout lacks (a snapshot may leave large files out) is replaced by a grey
# 1x1 PNG in the copy the script renders, and the report counts such textures.
#
#   scripts/meshopt-scenes.sh DEMO_DATA_DIR [OUT_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
src=${1:?usage: scripts/meshopt-scenes.sh DEMO_DATA_DIR [OUT_DIR]}
out=${2:-/tmp/lightsplit-meshopt-scenes}
bin=${LIGHTSPLIT:-target/dist/lightsplit}
bin=$(realpath "$bin")
mkdir -p "$out"
echo "| scene | triangles | missing textures replaced | result |" > "$out/report.md"
echo "|---|---:|---:|---|" >> "$out/report.md"
for gltf in "$src"/models/*/*.gltf; do
  grep -q '"EXT_meshopt_compression"' "$gltf" || continue
  name=$(basename "$(dirname "$gltf")")
  copy="$out/$name"
  rm -rf "$copy" && mkdir -p "$copy" && cp -r "$(dirname "$gltf")"/. "$copy"/
  # Grey stand-ins for the images the checkout lacks.
  missing=$(python3 - "$copy/$(basename "$gltf")" <<'EOF'
import json, os, sys
path = sys.argv[1]
doc = json.load(open(path))
import struct, zlib
def chunk(kind, data):
    body = kind + data
    return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)
grey = (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 1, 1, 8, 0, 0, 0, 0))
        + chunk(b"IDAT", zlib.compress(b"\x00\x80")) + chunk(b"IEND", b""))
n = 0
for image in doc.get("images", []):
    uri = image.get("uri")
    if uri and not uri.startswith("data:"):
        f = os.path.join(os.path.dirname(path), uri)
        if not os.path.isfile(f) or os.path.getsize(f) == 0:
            os.makedirs(os.path.dirname(f), exist_ok=True)
            open(f, "wb").write(grey)
            n += 1
print(n)
EOF
)
  file="$copy/$(basename "$gltf")"
  if info=$("$bin" info "$file" 2>&1) && "$bin" render "$file" --width 320 --height 240 --spp 16 -o "$out/$name.png" >/dev/null 2>&1; then
    triangles=$(echo "$info" | sed -n 's/^geometry: \([0-9]*\) triangles.*/\1/p')
    result="rendered ($name.png)"
  else
    triangles="-"
    result="failed: $(echo "$info" | grep -m1 error || true)"
  fi
  echo "| $name | $triangles | $missing | $result |" | tee -a "$out/report.md"
done
