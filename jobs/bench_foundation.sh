#!/usr/bin/env bash
# Foundation benchmark: light pass (sun + 8 sky terms, `sweep` and `exact`) and single-scattering render of the
# default cumulus at 128³ and 256³, 1920×1080, on 1 and 2 ranks; medians of 3 repeats.
#   bash jobs/bench_foundation.sh [build-dir] [sizes...]      (default: build 128 256)
set -euo pipefail
cd "$(dirname "$0")/.."
source jobs/env.sh
source jobs/bench_args.sh
build=build
if [[ $# -gt 0 && ! "$1" =~ ^[0-9]+$ ]]; then build=$1; shift; fi  # a build folder, as the other scripts take
sizes=("$@")
[ $# -eq 0 ] && sizes=(128 256)
need_binary "$build/bin/bench_foundation" bench_foundation "$build"
for n in "${sizes[@]}"; do need_count N "$n"; done
echo "| grid | image | ranks | light terms | light pass s (sweep) | light pass s (exact) | render s |"
echo "| --- | --- | --- | --- | --- | --- | --- |"
for n in "${sizes[@]}"; do
  for np in 1 2; do
    mpiexec -n "$np" "$build/bin/bench_foundation" "$n" 1920 1080 3
  done
done
