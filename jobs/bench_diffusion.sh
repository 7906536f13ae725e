#!/usr/bin/env bash
# Diffusion model benchmark (jobs/bench/bench_diffusion.cpp) at 1 and 2 ranks.
#   jobs/bench_diffusion.sh [build-dir] [N ...]      e.g. jobs/bench_diffusion.sh build 64 128
# Prints one markdown table per (N, ranks). SOLVERS="pfmg-pcg smg-pcg" limits the solvers;
# BENCH_MEDIUM=smooth runs the cumulus without edge noise, BENCH_OCTAVES (1-8, default 4) and
# BENCH_NOISE_SCALE (grid fractions, default 0.12) change the noise (no effect with smooth; the
# tables' title names them); BENCH_REPS=3 prints medians of 3 runs (bare and solvers alternating).
set -euo pipefail
cd "$(dirname "$0")/.."  # the build directory is relative to the source tree, as in the other scripts
source jobs/env.sh
source jobs/bench_args.sh
BUILD=${1:-build}
shift || true
SIZES=${*:-64 128}
BIN="$BUILD/bin/bench_diffusion"
need_binary "$BIN" bench_diffusion "$BUILD"
for n in $SIZES; do need_count "N" "$n"; done
[ -z "${BENCH_REPS:-}" ] || need_count BENCH_REPS "$BENCH_REPS"
for n in $SIZES; do
  for np in 1 2; do
    mpiexec -n "$np" --oversubscribe --bind-to none "$BIN" "$n" ${SOLVERS:-}
  done
done
