#!/usr/bin/env bash
# Builds lightsplit and runs its tests against Debian 13's Embree 4, inside a Debian 13 root made
# with debootstrap that borrows this machine's Rust toolchain (rustup and cargo homes bind-mounted).
# The root lives outside the checkout and is reused when it exists.
#
#   scripts/test-debian13.sh            # build the root if needed, then test
#   scripts/test-debian13.sh ARGS...    # the same, with ARGS added to `cargo test` (e.g. --test integration hardening::)
#   LIGHTSPLIT_DEBIAN13_ROOT=DIR ...    # where the root lives (default /var/tmp/lightsplit-debian13)
#   LIGHTSPLIT_TEST_PROFILE=NAME ...    # the cargo profile to test with (default release; CI: ci)
#   DEBIAN13_MIRROR=URL ...             # a Debian mirror for debootstrap (default: debootstrap's own)
set -euo pipefail

src=$(cd "$(dirname "$0")/.." && pwd)
root=${LIGHTSPLIT_DEBIAN13_ROOT:-/var/tmp/lightsplit-debian13}
rustup_home=${RUSTUP_HOME:-$HOME/.rustup}
cargo_home=${CARGO_HOME:-$HOME/.cargo}
packages=libembree-dev,libclang-dev,gcc,libc6-dev,pkg-config,ca-certificates

if [ "$(id -u)" != 0 ]; then
  echo "error: $0 needs root (debootstrap, mount, chroot)" >&2
  exit 2
fi

if [ ! -f "$root/usr/include/embree4/rtcore.h" ] || [ ! -x "$root/usr/bin/gcc" ]; then
  if ! command -v debootstrap >/dev/null; then
    apt-get install -y -qq debootstrap >/dev/null 2>&1 || { apt-get update -qq && apt-get install -y -qq debootstrap >/dev/null; }
  fi
  echo "debian13: creating $root with debootstrap (about a minute)"
  rm -rf "$root.partial"
  # shellcheck disable=SC2086
  debootstrap --variant=minbase --include="$packages" trixie "$root.partial" ${DEBIAN13_MIRROR:-} \
    >"$root.log" 2>&1 || { tail -20 "$root.log" >&2; exit 1; }
  mv "$root.partial" "$root"
fi

mounts=()
cleanup() {
  local i
  for ((i = ${#mounts[@]} - 1; i >= 0; i--)); do
    umount -l "${mounts[$i]}" 2>/dev/null || true
  done
}
trap cleanup EXIT INT TERM

bind() { # bind SRC DEST-inside-root
  mkdir -p "$root$2"
  mount --bind "$1" "$root$2"
  mounts+=("$root$2")
}

bind /proc /proc
bind /dev /dev
bind "$rustup_home" /opt/rustup
bind "$cargo_home" /opt/cargo
bind "$src" /src
mkdir -p "$root/etc/ssl/certs"
cp /etc/ssl/certs/ca-certificates.crt "$root/etc/ssl/certs/ca-certificates.crt"
cp /etc/resolv.conf "$root/etc/resolv.conf" 2>/dev/null || true

# The tests the README names, with a target directory of the root's own so the two Embree builds
# never share artefacts.
chroot "$root" /usr/bin/env -i \
  HOME=/root PATH=/opt/cargo/bin:/usr/bin:/bin RUSTUP_HOME=/opt/rustup CARGO_HOME=/opt/cargo \
  CARGO_TARGET_DIR=/var/tmp/lightsplit-target CI="${CI:-}" TERM=dumb \
  /bin/bash -c 'cd /src && cargo test --profile "$0" --workspace "$@"' "${LIGHTSPLIT_TEST_PROFILE:-release}" "$@"
