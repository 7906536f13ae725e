#!/usr/bin/env bash
# Installs what is missing, builds, and renders the built-in default cloud on 2 MPI ranks:
# out/nimbus.exr (linear float), out/nimbus.png (sRGB preview), out/nimbus.h5 + .xdmf (ParaView).
set -euo pipefail
cd "$(dirname "$0")/.."
bash jobs/build.sh
source jobs/env.sh
mpiexec -n 2 build/bin/nimbus run --out out "$@"
