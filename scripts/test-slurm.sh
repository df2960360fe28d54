#!/usr/bin/env bash
# Renders on a real Slurm cluster: brings up a one-node cluster on this machine (munge,
# slurmctld, slurmd; as root), submits a 4-part array render of a small scene and its merge
# (scripts/slurm-render.sh), and checks that the merged image is the single-machine render of
# the same scene, seed and spp, up to float rounding. The daemons it started are stopped by
# their PIDs on the way out, also on failure. Ends with "N passed, M failed".
#
#   scripts/test-slurm.sh [N] [SCENE [RENDER OPTIONS...]]
#
# Without arguments: N = 4, scenes/cornell.toml at 64x64 and 64 spp. With --time, prints the
# wall time from submission to the merged image instead of testing (for scaling figures).
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)

time_only=0
if [ "${1:-}" = "--time" ]; then
  time_only=1
  shift
fi
n=${1:-4}
scene=${2:-scenes/cornell.toml}
shift $(($# < 2 ? $# : 2))
options=("$@")
[ ${#options[@]} -gt 0 ] || options=(--width 64 --height 64 --spp 64)

if [ "$(id -u)" != 0 ]; then
  echo "error: the one-node cluster needs root (munged and slurmd run as root here)" >&2
  exit 2
fi
if ! command -v slurmctld >/dev/null || ! command -v munged >/dev/null; then
  apt-get install -y -qq slurm-wlm munge >/dev/null 2>&1 || { apt-get update -qq && apt-get install -y -qq slurm-wlm munge >/dev/null; }
fi
# LIGHTSPLIT_TEST_PROFILE: the cargo profile of the binary (default release; CI: ci, the
# profile its tests were built with).
profile=${LIGHTSPLIT_TEST_PROFILE:-release}
cargo build --profile "$profile" --quiet
exe=$root/target/$profile/lightsplit

work=$(mktemp -d)
started=()
cleanup() {
  local status=$?
  for pid in "${started[@]}"; do
    kill "$pid" 2>/dev/null || true
  done
  for pid in "${started[@]}"; do
    for _ in $(seq 50); do
      kill -0 "$pid" 2>/dev/null || break
      sleep 0.1
    done
    kill -9 "$pid" 2>/dev/null || true
  done
  if [ $status != 0 ] && [ -d "$work" ]; then
    for log in "$work"/*.log "$work"/out-parts/*.log; do
      [ -f "$log" ] && { echo "== $log"; tail -20 "$log"; }
    done
  fi
  rm -rf "$work"
  exit $status
}
trap cleanup EXIT INT TERM

# munge: this cluster's own key and socket, so a munged already running is left alone.
mkdir -p "$work/munge" "$work/state" "$work/spool"
chmod 700 "$work/munge"
dd if=/dev/urandom of="$work/munge/munge.key" bs=1024 count=1 status=none
chmod 400 "$work/munge/munge.key"
socket=$work/munge/munge.socket
munged --force --key-file="$work/munge/munge.key" --socket="$socket" \
  --pid-file="$work/munge/munged.pid" --log-file="$work/munge/munged.log" --seed-file="$work/munge/seed"
for _ in $(seq 50); do [ -s "$work/munge/munged.pid" ] && break; sleep 0.1; done
started+=("$(cat "$work/munge/munged.pid")")

cat >"$work/slurm.conf" <<EOF
ClusterName=lightsplit
SlurmctldHost=localhost
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$socket
CredType=cred/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SchedulerType=sched/builtin
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
MpiDefault=none
ReturnToService=2
StateSaveLocation=$work/state
SlurmdSpoolDir=$work/spool
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd.pid
SlurmctldLogFile=$work/slurmctld.log
SlurmdLogFile=$work/slurmd.log
SlurmctldPort=16817
SlurmdPort=16818
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
NodeName=localhost CPUs=2 State=UNKNOWN
PartitionName=main Nodes=localhost Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF=$work/slurm.conf
slurmctld -f "$SLURM_CONF"
for _ in $(seq 100); do [ -s "$work/slurmctld.pid" ] && break; sleep 0.1; done
started+=("$(cat "$work/slurmctld.pid")")
slurmd -f "$SLURM_CONF" -N localhost
for _ in $(seq 100); do [ -s "$work/slurmd.pid" ] && break; sleep 0.1; done
started+=("$(cat "$work/slurmd.pid")")
for _ in $(seq 300); do
  sinfo -h -N -o '%T' 2>/dev/null | grep -qE '^(idle|mixed|allocated)' && break
  sleep 0.2
done
sinfo -h -N -o '%T' | grep -qE '^(idle|mixed|allocated)' || { echo "error: the node never came up" >&2; exit 1; }
echo "one-node cluster up: $(sinfo -h -N -o '%N %T %c CPUs')"

start=$(date +%s.%N)
submitted=$(LIGHTSPLIT=$exe scripts/slurm-render.sh "$scene" "$work/out.exr" "$n" "${options[@]}")
echo "$submitted"
merge_job=$(echo "$submitted" | sed -E 's/.*merge job ([0-9]+).*/\1/')
# Until the merge job has left the queue (sbatch --wait polls too coarsely to time with).
for _ in $(seq 36000); do
  squeue -h -j "$merge_job" 2>/dev/null | grep -q . || break
  sleep 0.1
done
end=$(date +%s.%N)
seconds=$(echo "$end - $start" | bc)
if [ $time_only = 1 ]; then
  [ -s "$work/out.exr" ] || { echo "error: no merged image" >&2; exit 1; }
  echo "$n parts: ${seconds} s from submission to the merged image"
  exit 0
fi

passed=0
failed=0
check() {
  if eval "$2"; then
    echo "ok: $1"
    passed=$((passed + 1))
  else
    echo "FAILED: $1"
    failed=$((failed + 1))
  fi
}
"$exe" render "$scene" "${options[@]}" -o "$work/single.exr" 2>/dev/null
check "the array job wrote $n parts" '[ "$(ls "$work"/out-parts/part-*.exr | wc -l)" = "$n" ]'
for ((i = 0; i < n; i++)); do
  check "part $i saw its own index" "grep -q 'part $i/$n' '$work/out-parts/part-$i.log'"
done
check "the merge job wrote the image" '[ -s "$work/out.exr" ]'
relmse=$("$exe" compare --json "$work/out.exr" "$work/single.exr" | sed -E 's/.*"relmse":([^,}]*).*/\1/')
echo "merged against a single render: relMSE $relmse (float rounding is about 1e-13)"
check "the merged image is the single render's up to float rounding" "awk 'BEGIN { exit !($relmse < 1e-9) }'"
echo "$passed passed, $failed failed"
[ $failed = 0 ]
