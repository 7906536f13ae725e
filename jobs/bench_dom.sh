#!/usr/bin/env bash
# Discrete-ordinates sweep benchmark (jobs/bench/bench_dom.cpp): Kripke grind time for
# 32³-96³, S4 (the model default), S8, S16 and the 96 cube-face directions, 1 band, on 1 and 2 ranks.
#   jobs/bench_dom.sh [build-dir] [N ...]          e.g. jobs/bench_dom.sh build 32 64
# Environment overrides (defaults in brackets):
#   QUADS ["S4 S8 S16 cube96"]  ITERATIONS [5]  LEGENDRE [4: 25 moments, Kripke's default]
#   TILE_ROWS ["8"]  rows per KBA tile; a large value (e.g. 1000) = one tile per rank, where the
#                    pipeline fill matters most
#   OVERLAPS ["1 2 8"] octants swept at once ([model.dom] octant_overlap)
#   NIMBUS_DOM_PORTABLE=1 forces the portable moment kernels (for side-by-side ratios).
# Kripke v1.2.7 on this machine kind: about 10.5 ns (32³ and 64³, 96 directions, 1 group, 1 rank,
# Legendre order 4). Columns: grind = whole iteration / (zones x directions x iterations);
# sweep = the engine (transport kernel + pipeline waits); moments = moments -> directions and
# back (incl. fluence and flux); pipeline eff. = 1 - wait / sweep time (min over ranks);
# 2-rank eff. = time per iteration on 1 rank / (2 x time per iteration on 2 ranks).
# Example (the issue's comparison): QUADS=cube96 OVERLAPS="1 2" bash jobs/bench_dom.sh build 32 64
set -euo pipefail
cd "$(dirname "$0")/.."  # the build directory is relative to the source tree, as in the other scripts
source jobs/env.sh
source jobs/bench_args.sh
BUILD=${1:-build}
shift || true
SIZES=${*:-32 64 96}
BIN="$BUILD/bin/bench_dom"
need_binary "$BIN" bench_dom "$BUILD"
for n in $SIZES; do need_count N "$n"; done
need_count ITERATIONS "${ITERATIONS:-5}"
need_whole LEGENDRE "${LEGENDRE:-4}"
for tr in ${TILE_ROWS:-8}; do need_count TILE_ROWS "$tr"; done
for ov in ${OVERLAPS:-1 2 8}; do need_count OVERLAPS "$ov"; done
for q in ${QUADS:-S4 S8 S16 cube96}; do
  [[ "$q" == cube96 || "$q" =~ ^S[0-9]+$ ]] || { echo "$bench_script: QUADS: '$q' is not cube96 or S<order>" >&2; exit 1; }
done
echo "| zones | quadrature | directions | moments | ranks | tile rows | octant overlap | iterations | s/iteration | grind ns | sweep ns | moments ns | pipeline eff. | state B/cell | 2-rank eff. |"
echo "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"
for n in $SIZES; do
  for q in ${QUADS:-S4 S8 S16 cube96}; do
    for tr in ${TILE_ROWS:-8}; do
      for ov in ${OVERLAPS:-1 2 8}; do
        r1=$(mpiexec -n 1 --oversubscribe --bind-to none "$BIN" "$n" "$q" "${ITERATIONS:-5}" "${LEGENDRE:-4}" "$tr" "$ov")
        r2=$(mpiexec -n 2 --oversubscribe --bind-to none "$BIN" "$n" "$q" "${ITERATIONS:-5}" "${LEGENDRE:-4}" "$tr" "$ov")
        echo "$r1 |"
        # 2-rank efficiency from column 11 (fields split on '|'), the grind time: the same
        # ratio as the times per iteration, with 4 digits where s/iteration shows 1-3
        t1=$(echo "$r1" | awk -F'|' '{print $11}')
        t2=$(echo "$r2" | awk -F'|' '{print $11}')
        t2x2=$(awk -v b="$t2" 'BEGIN { print 2 * b }')
        eff=$(ratio "$t1" "$t2x2")  # exits on a row it cannot read
        echo "$r2 $eff |"
      done
    done
  done
done
