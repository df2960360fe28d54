#!/usr/bin/env bash
# Rays per second against scene size, for both backends: the terrain of scenes/terrain-1m.toml at
# 10 thousand to 10 million triangles, measured by `lightsplit bench-accel` side by side (one
# thread and all threads, back-to-back rounds), drawn as docs/accel-scaling.png with the reports
# in docs/accel-scaling.json.
#
#   scripts/bench-scaling.sh                  # 10k, 100k, 300k, 1M, 3M, 10M triangles
#   SIZES="71 224" scripts/bench-scaling.sh   # a quick check (terrain resolutions)
#
# Environment:
#   SIZES=...      terrain resolutions (2 x resolution^2 triangles), default "71 224 387 708 1225 2237"
#   RAYS=N         primary rays per set (default 300000)
#   ROUNDS=N       back-to-back rounds per row (default 3)
#   OUT=DIR        where the PNG and the JSON go (default docs)
#   LIGHTSPLIT=BIN measure this binary instead of building with `cargo build --profile dist`
# Needs a quiet machine: nothing else should run while it measures.
set -euo pipefail
cd "$(dirname "$0")/.."

SIZES=${SIZES:-"71 224 387 708 1225 2237"}
RAYS=${RAYS:-300000}
ROUNDS=${ROUNDS:-3}
OUT=${OUT:-docs}
if [ -z "${LIGHTSPLIT:-}" ]; then
  cargo build --profile dist --quiet
  LIGHTSPLIT=target/dist/lightsplit
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

scenes=()
for r in $SIZES; do
  case $r in
    '' | *[!0-9]*) echo "error: SIZES holds terrain resolutions (whole numbers), not '$r'" >&2; exit 2 ;;
  esac
  # The 1M scene with another resolution: the same terrain, finer or coarser.
  sed "s/^resolution = .*/resolution = $r/" scenes/terrain-1m.toml > "$work/terrain-$r.toml"
  scenes+=("$work/terrain-$r.toml")
done

mkdir -p "$OUT"
"$LIGHTSPLIT" bench-accel "${scenes[@]}" --rays "$RAYS" --rounds "$ROUNDS" \
  --plot "$OUT/accel-scaling.png" --json > "$work/scaling.json"
# The scene paths were temporary: name each report by its triangle count instead.
python3 - "$work/scaling.json" "$OUT/accel-scaling.json" <<'PY'
import json, sys
# One JSON object a line, a scene each.
reports = [json.loads(line) for line in open(sys.argv[1]) if line.strip()]
for r in reports:
    r["scene"] = "terrain-1m.toml at %d triangles" % r["triangles"]
json.dump(reports, open(sys.argv[2], "w"), indent=1)
print("%-10s %-11s %8s %8s %6s" % ("triangles", "rays", "embree", "bvh", "ratio"))
for r in reports:
    for e, b in zip(r["rows"][0::2], r["rows"][1::2]):
        if e["threads"] == 1:
            print("%-10d %-11s %8.2f %8.2f %5.2fx" % (r["triangles"], e["rays"], e["mrays_per_second"],
                                                    b["mrays_per_second"], b["ratio"]))
PY
echo "wrote $OUT/accel-scaling.png and $OUT/accel-scaling.json"
