#!/usr/bin/env bash
# Compares lightsplit's speed with two peers on the same scene, scenes/embree-cornell.toml (the
# Cornell box as Embree's pathtracer tutorial renders cornell_box.ecs): Mitsuba 3 (scalar_rgb,
# `path` integrator) and Embree's `pathtracer` tutorial itself. Checks first that the three images
# agree in mean, then times whole processes in alternating order, and prints a Markdown table
# and the render time alone that lightsplit and Mitsuba each report (the tutorial reports none);
# writes it, with the machine and the exact commands, into its section of docs/RESULTS.md,
# `bench-peers` (through scripts/results-section.py: replaced where it is, appended when missing,
# the rest of the file left as it was).
#
#   scripts/bench-peers.sh                       # 256x256, 64 spp, 5 rounds
#   scripts/bench-peers.sh --size 64 --spp 16 --rounds 1 --no-write    # a quick check
#
# Options (each also an environment variable):
#   --size N      (SIZE)     image width and height, default 256
#   --spp N       (SPP)      samples per pixel, default 64
#   --rounds N    (ROUNDS)   timed rounds, default 5
#   --threads N   (THREADS)  threads for every program, default: the number of CPUs (nproc)
#   --no-write               print the table only; leave docs/RESULTS.md alone
# Environment:
#   LIGHTSPLIT=BIN           time this binary instead of building with `cargo build --profile dist`
#   LIGHTSPLIT_PEERS_VENV=DIR  Mitsuba's virtual environment, outside the checkout
#                            (default ${XDG_CACHE_HOME:-$HOME/.cache}/lightsplit/peers-venv)
#   MITSUBA_PIP=SPEC         what pip installs there when Mitsuba is missing (default "mitsuba>=3,<4")
#   PYTHON=BIN               the Python that makes the environment (default python3)
#   PATHTRACER=BIN           Embree's tutorial (default pathtracer, from Debian's embree-tools)
#   EMBREE_ECS=FILE          its cornell_box.ecs (default: found under /usr/share/doc/embree*/models)
#   PEER_TIMEOUT=S           longest any one render may take (default 1800)
#
# Mitsuba runs as its `mitsuba` command (the venv's), writing PFM: that command (3.9.1) never
# returns from writing OpenEXR with -t 1 or -t 2. The helpers are in scripts/peers/.
#
# Installs what is missing (Debian or Ubuntu; root or sudo): embree-tools, python3 and
# python3-venv, and, for a build, what scripts/setup.sh installs. Exit status: 0 when the means
# agree and the timing ran, 1 on a failure (a mean outside its limit, a program that failed),
# 2 on bad options. Leaves nothing in the checkout but docs/RESULTS.md (and cargo's target/).
set -euo pipefail
export PYTHONDONTWRITEBYTECODE=1

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
scene_rel=scenes/embree-cornell.toml
scene=$root/$scene_rel
results=$root/docs/RESULTS.md

usage() { sed -n '2,/^set -euo/p' "${BASH_SOURCE[0]}" | sed '$d' | sed 's/^# \{0,1\}//'; }
bad_usage() {
    echo "bench-peers: $*" >&2
    echo "usage: scripts/bench-peers.sh [--size N] [--spp N] [--rounds N] [--threads N] [--no-write] (--help for more)" >&2
    exit 2
}
fail() { echo "bench-peers: error: $*" >&2; exit 1; }
note() { echo "bench-peers: $*" >&2; }

size=${SIZE:-256}
spp=${SPP:-64}
rounds=${ROUNDS:-5}
threads=${THREADS:-$(nproc)}
write=1
while [ $# -gt 0 ]; do
    case $1 in
        --size | --spp | --rounds | --threads)
            [ $# -ge 2 ] || bad_usage "$1 needs a value"
            case $1 in
                --size) size=$2 ;;
                --spp) spp=$2 ;;
                --rounds) rounds=$2 ;;
                --threads) threads=$2 ;;
            esac
            shift 2
            ;;
        --size=* | --spp=* | --rounds=* | --threads=*)
            value=${1#*=}
            case $1 in
                --size=*) size=$value ;;
                --spp=*) spp=$value ;;
                --rounds=*) rounds=$value ;;
                --threads=*) threads=$value ;;
            esac
            shift
            ;;
        --no-write) write=0; shift ;;
        -h | --help) usage; exit 0 ;;
        *) bad_usage "unknown argument: $1" ;;
    esac
done
for pair in "size:$size" "spp:$spp" "rounds:$rounds" "threads:$threads"; do
    name=${pair%%:*} value=${pair#*:}
    [[ $value =~ ^[1-9][0-9]{0,5}$ ]] || bad_usage "$name must be a positive integer, got '$value'"
done
venv=${LIGHTSPLIT_PEERS_VENV:-${XDG_CACHE_HOME:-$HOME/.cache}/lightsplit/peers-venv}
case $venv in
    /*) ;;
    *) venv=$PWD/$venv ;;
esac
case $venv/ in
    "$root"/*) bad_usage "the virtual environment ($venv) must be outside the checkout" ;;
esac
if [ -n "${LIGHTSPLIT:-}" ] && [ ! -x "$LIGHTSPLIT" ]; then
    bad_usage "LIGHTSPLIT=$LIGHTSPLIT is not an executable file"
fi
timeout_s=${PEER_TIMEOUT:-1800}
[[ $timeout_s =~ ^[1-9][0-9]*$ ]] || bad_usage "PEER_TIMEOUT must be a positive integer"

tmp=$(mktemp -d "${TMPDIR:-/tmp}/bench-peers.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
trap 'exit 130' INT TERM

# ---- Installing what is missing ------------------------------------------------------------

apt_updated=0
apt_install() {
    command -v apt-get >/dev/null || fail "install $* with your package manager"
    local sudo=()
    if [ "$(id -u)" != 0 ]; then
        command -v sudo >/dev/null || fail "run as root, or install sudo, to install $*"
        sudo=(sudo)
    fi
    if [ "$apt_updated" = 0 ]; then
        "${sudo[@]}" apt-get update -qq
        apt_updated=1
    fi
    note "installing $* with apt-get"
    "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "$@" >/dev/null
}

# Embree's tutorial and its Cornell box.
pathtracer=${PATHTRACER:-pathtracer}
if ! command -v "$pathtracer" >/dev/null; then
    [ -z "${PATHTRACER:-}" ] || bad_usage "PATHTRACER=$PATHTRACER is not a command"
    apt_install embree-tools
    command -v "$pathtracer" >/dev/null || fail "embree-tools installed no '$pathtracer' command"
fi
pathtracer=$(command -v "$pathtracer")
if [ -n "${EMBREE_ECS:-}" ]; then
    [ -f "$EMBREE_ECS" ] || bad_usage "EMBREE_ECS=$EMBREE_ECS is not a file"
    ecs=$EMBREE_ECS
else
    ecs=
    for f in /usr/share/doc/embree*/models/cornell_box.ecs /usr/share/doc/embree*/models/cornell_box.ecs.gz; do
        if [ -f "$f" ]; then ecs=$f; break; fi
    done
    [ -n "$ecs" ] || fail "no cornell_box.ecs under /usr/share/doc/embree*/models: is embree-tools' documentation installed (a dpkg path-exclude on /usr/share/doc drops it)? Set EMBREE_ECS."
    # Debian compresses larger documentation files: the tutorial needs them plain.
    models=$(dirname "$ecs")
    if [ "${ecs%.gz}" != "$ecs" ] || [ ! -f "$models/cornell_box.obj" ]; then
        mkdir -p "$tmp/embree-models"
        cp "$models"/cornell_box.* "$tmp/embree-models/"
        gunzip -f "$tmp/embree-models"/*.gz 2>/dev/null || true
        ecs=$tmp/embree-models/cornell_box.ecs
    fi
fi
embree_version=$(dpkg-query -W -f='${Version}' embree-tools 2>/dev/null || echo unknown)

# Mitsuba 3 in a virtual environment of its own.
python=${PYTHON:-python3}
if ! command -v "$python" >/dev/null; then
    [ -z "${PYTHON:-}" ] || bad_usage "PYTHON=$PYTHON is not a command"
    apt_install python3
fi
if [ ! -x "$venv/bin/python" ]; then
    # Only a new or empty directory: a failed attempt removes what it made.
    if [ -e "$venv" ] && [ -n "$(ls -A "$venv" 2>/dev/null)" ]; then
        fail "$venv exists and is not a virtual environment: remove it or set LIGHTSPLIT_PEERS_VENV"
    fi
    note "creating the virtual environment $venv"
    mkdir -p "$(dirname "$venv")"
    if ! "$python" -m venv "$venv" >"$tmp/venv.log" 2>&1; then
        # Debian's python3 has no ensurepip without python3-venv.
        rm -rf "$venv"
        apt_install python3-venv
        "$python" -m venv "$venv" >"$tmp/venv.log" 2>&1 || { cat "$tmp/venv.log" >&2; rm -rf "$venv"; fail "could not create $venv"; }
    fi
fi
pip_seconds=
if ! "$venv/bin/python" -c 'import sys, mitsuba, numpy; sys.version_info >= (3, 11) or __import__("tomli")' 2>/dev/null; then
    spec=${MITSUBA_PIP:-mitsuba>=3,<4}
    note "installing $spec and numpy into $venv with pip"
    start=$(date +%s.%N)
    "$venv/bin/python" -m pip install -q --disable-pip-version-check "$spec" numpy "tomli; python_version < '3.11'" \
        || fail "pip could not install $spec"
    pip_seconds=$(awk -v a="$start" -v b="$(date +%s.%N)" 'BEGIN { printf "%.1f", b - a }')
    note "pip install took $pip_seconds s"
fi
read -r mitsuba_version drjit_version < <("$venv/bin/python" -c 'import mitsuba, drjit; print(mitsuba.__version__, drjit.__version__)')
[ -x "$venv/bin/mitsuba" ] || fail "$venv has no mitsuba command"

# lightsplit.
if [ -n "${LIGHTSPLIT:-}" ]; then
    lightsplit=$(cd "$(dirname "$LIGHTSPLIT")" && pwd)/$(basename "$LIGHTSPLIT")
    lightsplit_shown=lightsplit
else
    "$root/scripts/setup.sh"
    note "building lightsplit: cargo build --profile dist"
    (cd "$root" && cargo build --profile dist)
    lightsplit=$root/target/dist/lightsplit
    lightsplit_shown=target/dist/lightsplit
fi
commit=$(git -C "$root" rev-parse --short HEAD 2>/dev/null || echo unknown)
if [ "$commit" != unknown ] && ! git -C "$root" diff --quiet HEAD -- 2>/dev/null; then
    commit="$commit (with uncommitted changes)"
fi

# ---- The scene for each program ------------------------------------------------------------

helpers=$root/scripts/peers
max_depth=$("$venv/bin/python" -c '
import sys
try:
    import tomllib
except ImportError:
    import tomli as tomllib
with open(sys.argv[1], "rb") as f:
    print(tomllib.load(f).get("render", {}).get("max_depth", 8))' "$scene")
"$venv/bin/python" "$helpers/mitsuba_scene.py" "$scene" "$tmp/mitsuba" \
    --width "$size" --height "$size" --spp "$spp" >/dev/null
mitsuba_depth=$(sed -n 's/.*name="max_depth" value="\([0-9]*\)".*/\1/p' "$tmp/mitsuba/scene.xml")

lightsplit_cmd=("$lightsplit" render "$scene" --width "$size" --height "$size" --spp "$spp"
    --threads "$threads" -o lightsplit.pfm)
# Mitsuba's -t counts its main thread, which only waits: -t 2 renders on one core (measured:
# CPU time equal to wall time), so N rendering threads are -t N+1.
mitsuba_cmd=("$venv/bin/mitsuba" -m scalar_rgb -t "$((threads + 1))" -o mitsuba.pfm mitsuba/scene.xml)
tutorial_cmd=("$pathtracer" -c "$ecs" --size "$size" "$size" --spp "$spp"
    --max-path-length "$max_depth" --threads "$threads" -o tutorial.ppm)
declare -A output=([lightsplit]=lightsplit.pfm [mitsuba]=mitsuba.pfm [tutorial]=tutorial.ppm)
peers=(lightsplit mitsuba tutorial)

# A command as a reader can run it: relative to the checkout or the working directory.
shown() {
    local s=" $* " mitsuba=$venv/bin/mitsuba in_root=$root/ in_tmp=$tmp/
    s=${s//" $lightsplit "/" $lightsplit_shown "}
    s=${s//" $mitsuba "/" mitsuba "}
    s=${s//" $pathtracer "/" $(basename "$pathtracer") "}
    s=${s//" $in_root"/" "}
    s=${s//" $in_tmp"/" "}
    s=${s# }
    echo "${s% }"
}
command_of() {
    case $1 in
        lightsplit) shown "${lightsplit_cmd[@]}" ;;
        mitsuba) shown "${mitsuba_cmd[@]}" ;;
        tutorial) shown "${tutorial_cmd[@]}" ;;
    esac
}

# Runs one program in $tmp; sets `wall` and `cpu` (user + sys of it and its children).
run() {
    local peer=$1 cmd rc=0 user sys
    case $peer in
        lightsplit) cmd=("${lightsplit_cmd[@]}") ;;
        mitsuba) cmd=("${mitsuba_cmd[@]}") ;;
        tutorial) cmd=("${tutorial_cmd[@]}") ;;
    esac
    rm -f "$tmp/${output[$peer]}"
    local TIMEFORMAT='%3R %3U %3S'
    # (No `exec` in the subshell: bash then reports no time.)
    { time (cd "$tmp" && timeout "$timeout_s" "${cmd[@]}" >"$tmp/$peer.log" 2>&1); } 2>"$tmp/time" || rc=$?
    if [ "$rc" != 0 ] || [ ! -s "$tmp/${output[$peer]}" ]; then
        tail -n 20 "$tmp/$peer.log" >&2
        [ "$rc" != 124 ] || fail "$peer took longer than $timeout_s s: $(command_of "$peer")"
        fail "$peer failed (exit status $rc, output ${output[$peer]} $([ -s "$tmp/${output[$peer]}" ] && echo written || echo missing)): $(command_of "$peer")"
    fi
    read -r wall user sys < <(tail -n 1 "$tmp/time")
    cpu=$(awk -v u="$user" -v s="$sys" 'BEGIN { printf "%.3f", u + s }')
    render_s=$(render_seconds "$peer" "$tmp/$peer.log")
}

# The render time a program reports itself, loading the scene, building the acceleration
# structure and writing the image left out: lightsplit's "in X s" (to 0.01 s), Mitsuba's
# "Rendering finished. (took X)" (to the millisecond, as "6.344s" or "402ms"); "-" for the
# tutorial, which reports none, or for a line not found.
render_seconds() {
    case $1 in
        lightsplit) sed -n 's/.* in \([0-9.]*\) s (.*/\1/p' "$2" | tail -n 1 | grep . || echo - ;;
        mitsuba)
            sed -n 's/.*Rendering finished\. (took \([^)]*\)).*/\1/p' "$2" | tail -n 1 | awk '
                match($0, /^[0-9.]+/) {
                    v = substr($0, 1, RLENGTH); u = substr($0, RLENGTH + 1)
                    f = u == "ms" ? 0.001 : u == "s" ? 1 : u == "m" ? 60 : u == "h" ? 3600 : -1
                    if (f > 0) { printf "%.3f\n", v * f; found = 1 }
                }
                END { if (!found) print "-" }'
            ;;
        *) echo - ;;
    esac
}

mean() { "$venv/bin/python" "$helpers/images.py" mean "$@"; }

# ---- The images must agree -----------------------------------------------------------------

note "${size}x${size}, $spp spp, max_depth $max_depth (Mitsuba max_depth $mitsuba_depth), $threads threads"
note "checking the images (one untimed run each)"
for peer in "${peers[@]}"; do
    run "$peer"
done
m_lightsplit=$(mean "$tmp/lightsplit.pfm")
m_lightsplit8=$(mean "$tmp/lightsplit.pfm" --as-tutorial-ppm)
m_mitsuba=$(mean "$tmp/mitsuba.pfm")
m_tutorial=$(mean "$tmp/tutorial.ppm")
# Mitsuba against lightsplit, both linear: within 1%.
d_mitsuba=$(awk -v a="$m_mitsuba" -v b="$m_lightsplit" 'BEGIN { printf "%+.2f", (a / b - 1) * 100 }')
# The tutorial against lightsplit quantised as the tutorial writes its PPM: within 1% plus half an
# 8-bit step. The quantisation is reproduced exactly, so what it leaves is each pixel's rounding
# of a different noise, which averages out; half a step is the whole of what truncating rather
# than rounding would shift a mean by, a generous bound on anything the quantisation leaves.
d_tutorial=$(awk -v a="$m_tutorial" -v b="$m_lightsplit8" 'BEGIN { printf "%+.2f", (a / b - 1) * 100 }')
limit_tutorial=$(awk -v b="$m_lightsplit8" 'BEGIN { printf "%.2f", (0.01 * b + 0.5 / 255) / b * 100 }')
mitsuba_ok=$(awk -v d="$d_mitsuba" 'BEGIN { print (d <= 1 && d >= -1) ? 1 : 0 }')
tutorial_ok=$(awk -v d="$d_tutorial" -v l="$limit_tutorial" 'BEGIN { print (d <= l && d >= -l) ? 1 : 0 }')
echo "image means: lightsplit $m_lightsplit linear ($m_lightsplit8 quantised as the tutorial's PPM)," \
    "Mitsuba $m_mitsuba linear ($d_mitsuba%, limit 1%), tutorial $m_tutorial as 8-bit linear" \
    "($d_tutorial%, limit $limit_tutorial%)"
# What the renders' own noise alone makes of a difference of means: two standard errors, in % of
# lightsplit's mean (an estimate from the images, on the high side). Told on a failure.
noise_of() { # peer's image, lightsplit's image, lightsplit's mean, [--as-tutorial-ppm]
    local a b
    a=$("$venv/bin/python" "$helpers/images.py" noise "$1")
    b=$("$venv/bin/python" "$helpers/images.py" noise "$2" ${4:+"$4"})
    awk -v a="$a" -v b="$b" -v m="$3" 'BEGIN { printf "%.2f", 2 * sqrt(a * a + b * b) / m * 100 }'
}
status=0
if [ "$mitsuba_ok" != 1 ]; then
    echo "bench-peers: FAIL: Mitsuba's image mean differs from lightsplit's by $d_mitsuba% (more than 1%;" \
        "noise alone makes about ±$(noise_of "$tmp/mitsuba.pfm" "$tmp/lightsplit.pfm" "$m_lightsplit")% at this size and spp)" >&2
    status=1
fi
if [ "$tutorial_ok" != 1 ]; then
    echo "bench-peers: FAIL: the tutorial's image mean differs from lightsplit's (quantised the same way) by" \
        "$d_tutorial% (more than $limit_tutorial%; noise alone makes about" \
        "±$(noise_of "$tmp/tutorial.ppm" "$tmp/lightsplit.pfm" "$m_lightsplit8" --as-tutorial-ppm)% at this size and spp)" >&2
    status=1
fi
[ "$status" = 0 ] || exit 1

# ---- Timing --------------------------------------------------------------------------------

load=$(cut -d' ' -f1 /proc/loadavg)
if awk -v l="$load" 'BEGIN { exit !(l > 0.5) }'; then
    note "WARNING: the load average is $load: something else is running, and the timings will show it"
fi
busy() { awk '/^cpu / { print $2 + $3 + $4 + $7 + $8 + $9 }' /proc/stat; }
busy_before=$(busy)
: >"$tmp/runs.tsv"
: >"$tmp/render.tsv"
ours=0
for ((r = 0; r < rounds; r++)); do
    order=()
    for ((k = 0; k < ${#peers[@]}; k++)); do
        order+=("${peers[(r + k) % ${#peers[@]}]}")
    done
    line="round $((r + 1))/$rounds:"
    for peer in "${order[@]}"; do
        run "$peer"
        printf '%s\t%s\t%s\t%s\n' "$r" "$peer" "$wall" "$cpu" >>"$tmp/runs.tsv"
        printf '%s\t%s\t%s\n' "$r" "$peer" "$render_s" >>"$tmp/render.tsv"
        ours=$(awk -v a="$ours" -v b="$cpu" 'BEGIN { print a + b }')
        line="$line $peer ${wall} s (CPU ${cpu} s),"
    done
    note "${line%,}"
done
others=$(awk -v a="$busy_before" -v b="$(busy)" -v hz="$(getconf CLK_TCK)" -v o="$ours" \
    'BEGIN { x = (b - a) / hz - o; printf "%.1f", x < 0 ? 0 : x }')
if awk -v x="$others" -v o="$ours" 'BEGIN { exit !(x > 0.05 * o + 0.5) }'; then
    note "WARNING: other processes used $others CPU s during the $ours CPU s timed: the timings are off"
fi

samples=$((size * size * spp))
table=$("$venv/bin/python" "$helpers/report.py" table "$tmp/runs.tsv" "$samples" \
    "$(printf 'lightsplit\tlightsplit\t%s\t%s linear (%s as 8-bit)\t—' "$(command_of lightsplit)" "$m_lightsplit" "$m_lightsplit8")" \
    "$(printf 'mitsuba\tMitsuba %s\t%s\t%s linear\t%s%% (limit ±1%%)' "$mitsuba_version" "$(command_of mitsuba)" "$m_mitsuba" "$d_mitsuba")" \
    "$(printf 'tutorial\tEmbree tutorial %s\t%s\t%s (8-bit)\t%s%% against lightsplit as 8-bit (limit ±%s%%)' "$embree_version" \
        "$(command_of tutorial)" "$m_tutorial" "$d_tutorial" "$limit_tutorial")")
# Render time alone, lightsplit against Mitsuba: the medians, and the median of the rounds'
# ratios (lightsplit's speed over Mitsuba's); "-" when either reported none.
read -r render_ls render_mi render_ratio < <("$venv/bin/python" - "$tmp/render.tsv" <<'PY'
import statistics, sys
seconds = {}
for line in open(sys.argv[1]):
    r, peer, s = line.rstrip("\n").split("\t")
    if s != "-" and float(s) > 0:
        seconds.setdefault(peer, {})[r] = float(s)
ls, mi = seconds.get("lightsplit", {}), seconds.get("mitsuba", {})
rounds = [r for r in ls if r in mi]
if not rounds:
    print("- - -")
else:
    ratio = statistics.median(mi[r] / ls[r] for r in rounds)
    print(f"{statistics.median(ls.values()):.3f} {statistics.median(mi.values()):.3f} {ratio:.2f}x")
PY
)
render_text="Render time alone, as each program reports it (loading the scene, building the acceleration
structure and writing the image left out): lightsplit $render_ls s (its \"in X s\"), Mitsuba
$render_mi s (its \"Rendering finished (took X)\"): lightsplit's speed is
$render_ratio Mitsuba's (the median of the rounds' ratios). The tutorial reports no render time."
echo
echo "$table"
echo
echo "$render_text"
echo

[ "$write" = 1 ] || exit 0

# ---- docs/RESULTS.md -----------------------------------------------------------------------

lscpu_field() { lscpu 2>/dev/null | sed -n "s/^$1: *//p" | head -1; }
cpu_model=$(lscpu_field 'Model name')
[ -n "$cpu_model" ] || cpu_model=$(sed -n 's/^model name\t*: //p' /proc/cpuinfo | head -1)
cpu_family=$(lscpu_field 'CPU family') cpu_model_number=$(lscpu_field 'Model')
hypervisor=$(lscpu_field 'Hypervisor vendor')
cpu="${cpu_model:-unknown CPU}${cpu_family:+ (family $cpu_family, model $cpu_model_number${hypervisor:+; a $hypervisor guest})}"
os_name=$(sed -n 's/^PRETTY_NAME="\{0,1\}\([^"]*\)"\{0,1\}$/\1/p' /etc/os-release 2>/dev/null || true)
if [ -n "${LIGHTSPLIT:-}" ]; then
    lightsplit_about="a prebuilt binary given by LIGHTSPLIT (the checkout was at $commit)"
else
    lightsplit_about="at $commit, built with cargo build --profile dist"
fi
# A paragraph of Markdown wrapped at 100 columns (never inside a word).
paragraph() {
    "$venv/bin/python" -c 'import sys, textwrap
print(textwrap.fill(" ".join(sys.stdin.read().split()), 100, break_long_words=False, break_on_hyphens=False))'
}
rounds_text="$rounds rounds"
[ "$rounds" != 1 ] || rounds_text="1 round"
{
    echo "## Speed against peers: Mitsuba 3 and Embree's pathtracer tutorial"
    echo
    paragraph <<TEXT
Written by \`scripts/bench-peers.sh\` on $(date -u +%Y-%m-%d): $cpu, $(nproc) CPUs (nproc)${os_name:+, $os_name}.
Embree's \`pathtracer\` tutorial from embree-tools $embree_version; Mitsuba $mitsuba_version (Dr.Jit $drjit_version,
variant \`scalar_rgb\`, from PyPI in a virtual environment); lightsplit $lightsplit_about.
TEXT
    echo
    paragraph <<TEXT
The scene \`$scene_rel\`: the Cornell box as the tutorial renders \`cornell_box.ecs\`,
${size}x${size} pixels, $spp samples per pixel, at most $max_depth scattering vertices each with
next-event estimation (lightsplit's \`max_depth\` $max_depth, the tutorial's \`--max-path-length\`
$max_depth, Mitsuba's \`path\` \`max_depth\` $mitsuba_depth, which counts the camera segment), $threads rendering threads each
(Mitsuba's \`-t $((threads + 1))\`: its \`-t\` counts a main thread that only waits, and \`-t $threads\` renders on
$((threads - 1)) core(s), its CPU time equal to its wall time).
Each program is timed as a whole process (loading the scene and writing the image included),
$rounds_text in alternating order (A B C, B C A, C A B, ...); wall and CPU seconds (user + sys
of the process and its children) are medians, and each ratio is the median of the per-round
ratios of lightsplit's speed to the peer's (above 1: lightsplit is faster). The load average
before timing was $load; other processes used $others CPU s during the $ours CPU s timed.
TEXT
    echo
    echo "$table"
    echo
    paragraph <<TEXT
$render_text
TEXT
    echo
    paragraph <<TEXT
The commands, run in a scratch directory; \`mitsuba/scene.xml\` and one OBJ file a part come
from \`python3 scripts/peers/mitsuba_scene.py $scene_rel mitsuba --width $size --height $size --spp $spp\`,
and \`mitsuba\` is the command of Mitsuba's Python package:
TEXT
    echo
    echo '```'
    for peer in "${peers[@]}"; do
        command_of "$peer"
    done
    echo '```'
    echo
    paragraph <<TEXT
The images are checked before timing. Each program writes the beauty alone (lightsplit a PFM, so
it computes no component split or guide buffers, as the peers compute none). Mitsuba's mean is
compared with lightsplit's in
linear RGB (limit 1%). The tutorial writes its PPM linearly, with no gamma: each pixel's mean
clamped to [0, 1] and stored as trunc(255.01 x); lightsplit's linear image is quantised
the same way before comparing (limit 1% plus half an 8-bit step). Mitsuba writes PFM, not
OpenEXR: its \`mitsuba\` command ($mitsuba_version) never returns from writing an OpenEXR file with
\`-t 1\` or \`-t 2\`.
TEXT
} >"$tmp/section.md"
"$venv/bin/python" "$root/scripts/results-section.py" write "$results" bench-peers scripts/bench-peers.sh "$tmp/section.md"
note "wrote the bench-peers section of docs/RESULTS.md"
