#!/usr/bin/env bash
# Installs what lightsplit needs to build on Debian or Ubuntu: Embree (3.13 on Debian 12 /
# Ubuntu 22.04, 4.x on Debian 13 / Ubuntu 24.04) with its headers, libclang for bindgen, and
# Python 3 with venv (the Python module's build reads the interpreter; its tests run in a venv).
# Does nothing when everything is already there. Needs root or sudo for apt-get.
set -euo pipefail

packages=(libembree-dev libclang-dev pkg-config python3 python3-venv)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if [ ${#missing[@]} -gt 0 ]; then
  if ! command -v apt-get >/dev/null; then
    echo "error: install ${missing[*]} with your package manager (or set EMBREE_DIR)" >&2
    exit 1
  fi
  sudo=""
  if [ "$(id -u)" != 0 ]; then
    command -v sudo >/dev/null || { echo "error: run as root to install ${missing[*]}" >&2; exit 1; }
    sudo=sudo
  fi
  echo "setup: installing ${missing[*]}"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${missing[@]}" >/dev/null
fi

if ! command -v cargo >/dev/null; then
  echo "error: cargo is missing: install a current Rust toolchain with rustup (https://rustup.rs)" >&2
  exit 1
fi
