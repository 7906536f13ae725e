#!/usr/bin/env bash
# Installs what is missing, builds, and runs the whole test suite (unit, MPI at 1, 2 and 3 ranks,
# verification) with ctest.
set -euo pipefail
cd "$(dirname "$0")/.."
bash jobs/build.sh
source jobs/env.sh
ctest --test-dir build -j "$(nproc)" --output-on-failure --timeout 600
