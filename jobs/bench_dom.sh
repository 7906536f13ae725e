#!/usr/bin/env bash
# Discrete-ordinates sweep benchmark (jobs/bench/bench_dom.cpp): Kripke grind time for
# 32³-96³, S4 (the model default), S8, S16 and the 96 cube-face directions, 1 band, on 1 and 2 ranks.
#   jobs/bench_dom.sh [build-dir] [N ...]          e.g. jobs/bench_dom.sh build 32 64
# QUADS="S4 S8 S16 cube96" ITERATIONS=5 LEGENDRE=4 TILE_ROWS=8 override the defaults.
# Kripke v1.2.7 on this machine kind: about 10.5 ns (32³ and 64³, 96 directions, 1 group, 1 rank).
# KBA 2-rank efficiency = time/iteration on 1 rank / (2 x time/iteration on 2 ranks).
set -euo pipefail
BUILD=${1:-build}
shift || true
SIZES=${*:-32 64 96}
BIN="$BUILD/bin/bench_dom"
[ -x "$BIN" ] || { echo "missing $BIN: cmake --build $BUILD --target bench_dom" >&2; exit 1; }
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
echo "| zones | quadrature | directions | moments | ranks | iterations | s/iteration | grind ns | sweep ns | moments ns | pipeline eff. | state B/cell |"
echo "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"
for n in $SIZES; do
  for q in ${QUADS:-S4 S8 S16 cube96}; do
    for np in 1 2; do
      mpiexec -n "$np" --oversubscribe --bind-to none "$BIN" "$n" "$q" "${ITERATIONS:-5}" "${LEGENDRE:-4}" "${TILE_ROWS:-8}"
    done
  done
done
