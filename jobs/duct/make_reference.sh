#!/usr/bin/env bash
# Monte Carlo reference of the void duct for test_dom_emission (tests/data/duct_mc_reference.csv).
# Usage: jobs/duct/make_reference.sh [build dir] [photons] [ranks]
#   default: build, 40000000 photons (the stored file's count), 2 ranks.
set -euo pipefail
here="$(cd "$(dirname "$0")/../.." && pwd)"
build="${1:-$here/build}"
photons="${2:-40000000}"
ranks="${3:-2}"
source "$here/jobs/env.sh"
out="$(mktemp -d)"
mpiexec -n "$ranks" --oversubscribe --bind-to none "$build/bin/nimbus" run "$here/scenes/duct.toml" \
  --set model.name=montecarlo --set model.montecarlo.photons="$photons" --set model.montecarlo.seed=2026 \
  --set output.image=false --out "$out"
/usr/bin/python3 "$here/jobs/duct/extract_reference.py" "$out/duct.h5" "$here/tests/data/duct_mc_reference.csv"
rm -rf "$out"
