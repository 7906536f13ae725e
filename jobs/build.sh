#!/usr/bin/env bash
# Configures and builds nimbus (Release) into build/. Usage: jobs/build.sh [extra cmake args]
set -euo pipefail
cd "$(dirname "$0")/.."
bash jobs/install_deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release "$@" > build.log 2>&1 || { cat build.log; exit 1; }
cmake --build build -j "$(nproc)" >> build.log 2>&1 || { tail -50 build.log; exit 1; }
echo "build: ok (log in build.log)"
