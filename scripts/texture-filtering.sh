#!/usr/bin/env bash
# Issue 37's texture filtering goal: a checker-textured floor to the horizon, rendered at 4 spp
# with image textures filtered (the camera ray cone's footprint through their mipmaps, the
# default) and looked up at a point (`--point-textures`, as before), each against a 4,096-spp
# point-sampled reference, compared by `lightsplit compare --by-object`: the floor's near part
# (to 10 units) and far part (to the horizon) are objects of their own, so the error and the
# mean of each are given apart (filtering must not darken or blur what is near). Then the same
# scene with a large texture (SIZE x SIZE texels, 8192 by default: 0.8 GB of linear RGB floats
# and its mipmaps) rendered both ways, alternated, for the speed of each.
#
#   scripts/texture-filtering.sh [OUT_DIR] [SEEDS] [SIZE]
#
# Writes OUT_DIR/report.md. Uses target/dist/lightsplit (or $LIGHTSPLIT).
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-/tmp/lightsplit-texture-filtering}
seeds=${2:-4}
size=${3:-8192}
bin=${LIGHTSPLIT:-target/dist/lightsplit}
mkdir -p "$out"

# The floor: an OBJ of two parts, its texture coordinates the world's x and z over 4 (the
# checker image holds 8 x 8 checks: each 0.5 units), near (z 0 to -10) and far (to -400).
python3 - "$out" "$size" <<'EOF'
import struct, sys, zlib
out, size = sys.argv[1], int(sys.argv[2])

def png(path, n):
    check = n // 8
    row = lambda y: b"\x00" + bytes(
        (230 if ((x // check) + (y // check)) % 2 == 0 else 25) for x in range(n))
    raw = b"".join(row(y) for y in range(n))
    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", n, n, 8, 0, 0, 0, 0))
                + chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b""))

png(f"{out}/checker.png", 256)
png(f"{out}/checker-large.png", size)
with open(f"{out}/floor.obj", "w") as f:
    k = 1
    for name, z0, z1, half in (("near", 0.0, -10.0, 20.0), ("far", -10.0, -400.0, 400.0)):
        f.write(f"o {name}\n")
        for x, z in ((-half, z0), (half, z0), (half, z1), (-half, z1)):
            f.write(f"v {x} 0 {z}\nvt {x / 4} {-z / 4}\n")
        f.write(f"f {k}/{k} {k + 1}/{k + 1} {k + 2}/{k + 2} {k + 3}/{k + 3}\n")
        k += 4
for name, image in (("floor", "checker.png"), ("floor-large", "checker-large.png")):
    with open(f"{out}/{name}.toml", "w") as f:
        f.write(f"""[camera]
position = [0, 1, 0]
look_at = [0, 0.75, -10]
fov = 40
[film]
width = 160
height = 120
[render]
max_depth = 2
[[light]]
type = "sky"
radiance = [1, 1, 1]
[[texture]]
name = "checks"
type = "image"
file = "{image}"
[[material]]
name = "floor"
type = "diffuse"
texture = "checks"
[[shape]]
type = "mesh"
file = "floor.obj"
material = "floor"
""")
EOF

"$bin" render "$out/floor.toml" --point-textures --spp 4096 -o "$out/reference.exr" >/dev/null 2>&1
row() { # name, extra args: mean RMSE (whole, near, far) and mean ratio over the seeds
  local name=$1; shift
  for s in $(seq 1 "$seeds"); do
    "$bin" render "$out/floor.toml" --spp 4 --seed "$s" "$@" -o "$out/$name-$s.exr" >/dev/null 2>&1
    "$bin" compare "$out/$name-$s.exr" "$out/reference.exr" --by-object --json
  done | python3 -c '
import json, sys
rows = [json.loads(l) for l in sys.stdin if l.strip()]
# The OBJ parts are objects 0 (near) and 1 (far), in the file order.
def objects(r):
    return {{"object 0": "near", "object 1": "far"}.get(o["name"]): o for o in r.get("regions", [])}
whole = sum(r["rmse"] for r in rows) / len(rows)
out = ["%.4f" % whole]
for part in ("near", "far"):
    os_ = [objects(r).get(part) for r in rows]
    os_ = [o for o in os_ if o]
    rm = sum(o["rmse"] for o in os_) / max(len(os_), 1)
    ratio = sum(o["ratio"] for o in os_) / max(len(os_), 1)
    out += ["%.4f" % rm, "%.4f" % ratio]
print("| '"$name"' | " + " | ".join(out) + " |")'
}
{
  echo "Checker floor to the horizon, 160x120 at 4 spp, mean of $seeds seeds, against 4,096 spp point-sampled"
  echo
  echo "| lookups | RMSE | near RMSE | near mean ratio | far RMSE | far mean ratio |"
  echo "| --- | --- | --- | --- | --- | --- |"
  row point --point-textures
  row filtered
} | tee "$out/report.md"

# Speed with a large texture, alternated (render time only, from --json).
for r in 1 2 3; do
  for mode in point filtered; do
    args=(); [ "$mode" = point ] && args=(--point-textures)
    "$bin" render "$out/floor-large.toml" --spp 16 "${args[@]}" --json -o "$out/large-$mode.exr" 2>/dev/null |
      python3 -c 'import json,sys; j=json.load(sys.stdin); print("'"$mode"'", j["seconds"], j["samples_per_second"])'
  done
done | python3 -c '
import sys, statistics as st
d = {}
for l in sys.stdin:
    m, s, sps = l.split(); d.setdefault(m, []).append(float(sps))
p, f = st.median(d["point"]), st.median(d["filtered"])
print("\nLarge texture ('"$size"'^2 texels), 16 spp, median of 3 alternated: point %.3f, filtered %.3f M samples/s (filtered/point %.2f)" % (p / 1e6, f / 1e6, f / p))' | tee -a "$out/report.md"
