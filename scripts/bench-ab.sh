#!/usr/bin/env bash
# Compares lightsplit binaries on one scene with `bench-accel`, alternating them run by run
# (A B A B ...) so that the machine's drift falls on all of them alike, and prints the medians
# of each one's BVH/Embree ratios: build time, primary, shadow and incoherent rays on one thread.
#
#   scripts/bench-ab.sh RUNS SCENE.toml OLD_BINARY NEW_BINARY...
#   scripts/bench-ab.sh 4 scenes/terrain-1m.toml /tmp/lightsplit-old target/release/lightsplit
#
# Environment: RAYS (primary rays per set, default 300000). Needs a quiet machine.
set -euo pipefail
if [ $# -lt 3 ]; then
  echo "usage: scripts/bench-ab.sh RUNS SCENE.toml BINARY..." >&2
  exit 2
fi
runs=$1 scene=$2
shift 2
case $runs in
  '' | *[!0-9]* | 0) echo "error: RUNS must be a positive whole number, not '$runs'" >&2; exit 2 ;;
esac
[ -f "$scene" ] || { echo "error: no scene file '$scene'" >&2; exit 2; }
for b in "$@"; do
  [ -x "$b" ] || { echo "error: '$b' is not an executable" >&2; exit 2; }
done
out=$(mktemp)
trap 'rm -f "$out"' EXIT
for ((i = 1; i <= runs; i++)); do
  for b in "$@"; do
    # Read once the run is over: Python starting inside a pipe would share the cores with it.
    json=$("$b" bench-accel "$scene" --threads 1 --rounds 3 --rays "${RAYS:-300000}" --seconds 0.2 --json)
    printf '%s\n' "$json" |
      python3 -c '
import json, sys
r = json.loads(sys.stdin.readline())
rows = [x for x in r["rows"] if x["threads"] == 1 and x["backend"] == "bvh"]
print(sys.argv[1], r["build_seconds"]["bvh"] / r["build_seconds"]["embree"], *[x["ratio"] for x in rows])
' "$b" >> "$out"
  done
  echo "run $i of $runs done" >&2
done
python3 - "$out" <<'PY'
import statistics, sys
runs = {}
for line in open(sys.argv[1]):
    name, *values = line.split()
    runs.setdefault(name, []).append([float(v) for v in values])
print("%-36s %6s %8s %7s %11s   %s" % ("binary", "build", "primary", "shadow", "incoherent", "primary, run by run"))
for name, rows in runs.items():
    cols = list(zip(*rows))
    print("%-36s %5.2fx %7.3fx %6.3fx %10.3fx   %s" % (name, *[statistics.median(c) for c in cols],
                                                       " ".join("%.2f" % x for x in cols[1])))
PY
