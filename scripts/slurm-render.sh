#!/usr/bin/env bash
# Renders a scene on a Slurm cluster: an array job of N parts (`lightsplit render --part auto`,
# one core each), then a merge job that runs once all of them have succeeded
# (`--dependency=afterok`) and writes the image. Prints the two job IDs.
#
#   scripts/slurm-render.sh [--wait] SCENE OUT N [RENDER OPTIONS...] [-- MERGE OPTIONS...]
#
# e.g.  scripts/slurm-render.sh --wait scenes/cornell.toml cornell.png 8 --spp 1024 -- --filter box3
#
# The parts go to OUT's directory as OUT-parts/part-I.exr; the render options (--spp, --seed,
# --width...) go to every part, the merge options (--filter, --exposure...) to the merge.
# LIGHTSPLIT is the binary (default: target/release/lightsplit beside this script, else
# `lightsplit` on the PATH). --wait returns when the merge has ended, with its status.
# Extra sbatch options (a partition, an account) can come in SBATCH_OPTIONS.
set -euo pipefail

wait_flag=()
if [ "${1:-}" = "--wait" ]; then
  wait_flag=(--wait)
  shift
fi
if [ $# -lt 3 ]; then
  sed -n '2,16p' "$0" >&2
  exit 2
fi
scene=$1 out=$2 n=$3
shift 3
render_options=()
merge_options=()
while [ $# -gt 0 ]; do
  if [ "$1" = "--" ]; then
    shift
    merge_options=("$@")
    break
  fi
  render_options+=("$1")
  shift
done
case $n in
  '' | *[!0-9]*) echo "error: N must be a whole number of parts, not '$n'" >&2; exit 2 ;;
esac
if [ "$n" -lt 1 ]; then
  echo "error: N must be at least 1" >&2
  exit 2
fi
[ -f "$scene" ] || { echo "error: no scene file $scene" >&2; exit 2; }
command -v sbatch >/dev/null || { echo "error: sbatch not found: is this a Slurm cluster?" >&2; exit 2; }

here=$(cd "$(dirname "$0")/.." && pwd)
if [ -z "${LIGHTSPLIT:-}" ]; then
  if [ -x "$here/target/release/lightsplit" ]; then
    LIGHTSPLIT=$here/target/release/lightsplit
  else
    LIGHTSPLIT=$(command -v lightsplit) || { echo "error: no lightsplit binary (set LIGHTSPLIT)" >&2; exit 2; }
  fi
fi
abs() { (cd "$(dirname "$1")" && printf '%s/%s\n' "$(pwd)" "$(basename "$1")"); }
scene=$(abs "$scene")
out=$(abs "$out")
parts_dir="${out%.*}-parts"
mkdir -p "$parts_dir"

quote() { [ $# -eq 0 ] || printf '%q ' "$@"; }
# Each task names its part file by its own index (the job's shell expands it; `--part auto`
# reads the same variables).
part_file="$(printf '%q' "$parts_dir")/part-\${SLURM_ARRAY_TASK_ID}.exr"
# shellcheck disable=SC2086
array=$(sbatch --parsable ${SBATCH_OPTIONS:-} --job-name=lightsplit-part --array="0-$((n - 1))" \
  --ntasks=1 --cpus-per-task=1 --output="$parts_dir/part-%a.log" \
  --wrap="$(quote "$LIGHTSPLIT" render "$scene" --part auto --threads 1) -o $part_file $(quote "${render_options[@]}")")
array=${array%%;*}
parts=()
for ((i = 0; i < n; i++)); do
  parts+=("$parts_dir/part-$i.exr")
done
# shellcheck disable=SC2086
merge=$(sbatch --parsable ${SBATCH_OPTIONS:-} "${wait_flag[@]}" --job-name=lightsplit-merge \
  --dependency="afterok:$array" --kill-on-invalid-dep=yes --ntasks=1 --cpus-per-task=1 \
  --output="$parts_dir/merge.log" \
  --wrap="$(quote "$LIGHTSPLIT" merge "${parts[@]}" -o "$out") $(quote "${merge_options[@]}")")
echo "array job $array ($n parts), merge job ${merge%%;*}: $out"
