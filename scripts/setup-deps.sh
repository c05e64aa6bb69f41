#!/usr/bin/env bash
# Installs every Debian package gsd needs to build, test and run, plus any packages named as
# arguments (scripts/sanitizer-build.sh adds clang's). Idempotent and quiet; returns at once
# when everything is already there.
set -euo pipefail

packages=(
  cmake ninja-build g++ ccache pkg-config
  libeigen3-dev libnanoflann-dev libsuitesparse-dev coinor-libclp-dev liblemon-dev libspectra-dev
  libvulkan-dev libvulkan-volk-dev glslang-tools spirv-tools mesa-vulkan-drivers vulkan-validationlayers
  libcli11-dev libstb-dev nlohmann-json3-dev doctest-dev libopenvdb-dev libboost-dev python3-openvdb
  libopenblas0-pthread
  python3 python3-numpy python3-dev pybind11-dev python3-pytest
  "$@"
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0

echo "setup-deps: installing ${missing[*]}"
SUDO=""
[ "$(id -u)" -ne 0 ] && SUDO="sudo"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
