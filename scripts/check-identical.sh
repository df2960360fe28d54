#!/usr/bin/env bash
# Checks that a change left the images alone: every scene of scenes/ rendered by this checkout
# and by another revision (default b3f5483, the last before the components were computed
# through light path expressions), on both backends, must give bit-identical layers: the
# final image and the four components (`lightsplit compare --layer L` of the two EXRs: a sum
# of squared differences of exactly 0). Each binary reads its own revision's scene file (a
# key added since, such as `light_group`, is unknown to an older one); a scene the other
# revision lacks is left out, and named.
#
#   scripts/check-identical.sh                 # against b3f5483, 48x48, 8 spp
#   scripts/check-identical.sh --rev HEAD~3 --size 32 --spp 4
#
# Options:
#   --rev REV    the revision to compare with (default b3f5483)
#   --size N     image width and height (default 48)
#   --spp N      samples per pixel (default 8)
#   --out DIR    renders and the other revision's build (default ${TMPDIR:-/tmp}/lightsplit-identical)
# Environment:
#   LIGHTSPLIT=BIN   this checkout's binary (default: built with `cargo build --profile ci`)
#   CARGO_TARGET_DIR=DIR  where the other revision builds (default its worktree's target: from
#                    nothing, minutes; this checkout's target reuses its dependencies)
#
# The other revision is built in a git worktree under OUT, its binary kept as
# OUT/lightsplit-COMMIT. Prints
# one line per scene, backend and layer that differs, then a summary. Exit status: 0 when all
# are identical, 1 when one differs or a render fails, 2 on bad options.
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
usage() { sed -n '2,/^set -euo/p' "${BASH_SOURCE[0]}" | sed '$d' | sed 's/^# \{0,1\}//'; }
bad_usage() { echo "check-identical: $*" >&2; echo "usage: scripts/check-identical.sh [options] (--help for more)" >&2; exit 2; }
fail() { echo "check-identical: error: $*" >&2; exit 1; }
note() { echo "check-identical: $*" >&2; }

rev=b3f5483 size=48 spp=8 out=${TMPDIR:-/tmp}/lightsplit-identical
while [ $# -gt 0 ]; do
    case $1 in
        --rev | --size | --spp | --out)
            [ $# -ge 2 ] || bad_usage "$1 needs a value"
            case $1 in --rev) rev=$2 ;; --size) size=$2 ;; --spp) spp=$2 ;; --out) out=$2 ;; esac
            shift 2 ;;
        -h | --help) usage; exit 0 ;;
        *) bad_usage "unknown argument: $1" ;;
    esac
done
for pair in "size:$size" "spp:$spp"; do
    [[ ${pair#*:} =~ ^[1-9][0-9]{0,4}$ ]] || bad_usage "--${pair%%:*} must be a positive integer, got '${pair#*:}'"
done
commit=$(git -C "$root" rev-parse --verify "$rev^{commit}" 2>/dev/null) || bad_usage "no revision $rev"

if [ -n "${LIGHTSPLIT:-}" ]; then
    [ -x "$LIGHTSPLIT" ] || bad_usage "LIGHTSPLIT=$LIGHTSPLIT is not an executable file"
    new=$(cd "$(dirname "$LIGHTSPLIT")" && pwd)/$(basename "$LIGHTSPLIT")
else
    (cd "$root" && cargo build --profile ci)
    new=$root/target/ci/lightsplit
fi
mkdir -p "$out"
tree=$out/tree-$commit
old=$out/lightsplit-$commit
if [ ! -x "$old" ]; then
    [ -d "$tree" ] || git -C "$root" worktree add --detach "$tree" "$commit" >/dev/null
    # CARGO_TARGET_DIR set to this checkout's target reuses its built dependencies.
    target=${CARGO_TARGET_DIR:-$tree/target}
    # A revision from before the ci profile builds in release.
    profile=release
    grep -q '^\[profile.ci\]' "$tree/Cargo.toml" && profile=ci
    note "building $rev in $tree (--profile $profile)"
    (cd "$tree" && cargo build --profile "$profile")
    cp "$target/$profile/lightsplit" "$old"
fi

differ=0 checked=0
scenes=0
for scene in "$root"/scenes/*.toml; do
    name=$(basename "$scene" .toml)
    if [ ! -f "$tree/scenes/$name.toml" ]; then
        note "$name: not in $rev, left out"
        continue
    fi
    scenes=$((scenes + 1))
    for accel in embree bvh; do
        for which in old new; do
            bin=$old file=$tree/scenes/$name.toml
            [ "$which" = new ] && bin=$new file=$scene
            "$bin" render "$file" -o "$out/$name-$accel-$which.exr" --width "$size" --height "$size" \
                --spp "$spp" --accel "$accel" --threads 2 >/dev/null 2>"$out/$name-$accel-$which.log" \
                || fail "$name ($accel, $which): the render failed (see $out/$name-$accel-$which.log)"
        done
        for layer in final emitted direct caustic indirect; do
            sse=$("$new" compare "$out/$name-$accel-new.exr" "$out/$name-$accel-old.exr" --layer "$layer" --json \
                | python3 -c 'import json, sys; print(json.load(sys.stdin)["sse"])')
            checked=$((checked + 1))
            if [ "$sse" != 0.0 ]; then
                echo "$name, $accel, $layer: differs (sum of squared differences $sse)"
                differ=$((differ + 1))
            fi
        done
    done
done
echo "$((checked - differ)) of $checked layers identical ($scenes scenes x 2 backends x 5 layers; ${size}x${size}, $spp spp; against $rev)"
[ "$differ" = 0 ]
