#!/usr/bin/env bash
# Installs the Debian packages nimbus builds and runs with. Idempotent: when everything is
# present it only checks (about a second). Needs root (or sudo) only when something is missing.
set -euo pipefail

PACKAGES=(
  build-essential cmake pkg-config
  openmpi-bin libopenmpi-dev
  libhypre-dev petsc-dev
  libhdf5-openmpi-dev hdf5-tools
  libopenexr-dev libpng-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libcli11-dev libtoml11-dev nlohmann-json3-dev libfmt-dev libspdlog-dev
  python3-numpy python3-h5py python3-matplotlib
)

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install_deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi
echo "install_deps: installing ${missing[*]}"
SUDO=""
[ "$(id -u)" -ne 0 ] && SUDO="sudo"
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
