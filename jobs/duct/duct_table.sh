#!/usr/bin/env bash
# The void-duct table of solvers/dom/README.md: DOM at S4..S16, cube96 and a 16 x 32 product set
# against the stored Monte Carlo reference (tests/data/duct_mc_reference.csv), per region:
# relative L2, max relative error, RMS and max of the error in reference standard errors, bias.
# Usage: jobs/duct/duct_table.sh [build dir] [ranks]   (builds test_dom_emission first)
set -euo pipefail
here="$(cd "$(dirname "$0")/../.." && pwd)"
build="${1:-$here/build}"
ranks="${2:-1}"
source "$here/jobs/env.sh"
cmake --build "$build" --target test_dom_emission -j2 >/dev/null
mpiexec -n "$ranks" "$build/tests/verification/dom/test_dom_emission" \
  --gtest_filter='DomEmission.VoidDuct*' | grep -E '^(void|  )'
