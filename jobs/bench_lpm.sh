#!/usr/bin/env bash
# LPM benchmark (issue 6 item 5): the default cumulus at N³, one band, the sun only, a fixed
# number of iterations (epsilon 0). Fattal 2009 reports 64³ with 5×5 maps and 3 iterations in
# 17 s and 9×9 in 135 s on one 2.7 GHz Pentium IV core; the target here is ≥ 30x faster on 2
# ranks (< 0.57 s and < 4.5 s) and a 2-rank speed-up ≥ 1.6. Then the cost against n and p,
# compared with the paper's O(n (n² + p²) m q): per ray step (ray x cell layer) the cost should
# stay constant as n and p grow (ns/ray-step column). Since the vacuum fast path (empty cells
# skip the exponential, README) the cost per ray step also depends on how much of the grid
# the cloud fills, not only on n and p.
#   bash jobs/bench_lpm.sh [build-dir [reference-bench_lpm]]        (default: build)
# With a second argument (a bench_lpm binary of another version, e.g. a copy of the previous
# build's bin/bench_lpm), the paper settings run both side by side, alternating, so that a
# shared machine's load hits both alike (rows labelled "new" / "ref").
# Needs a build with -DNIMBUS_BUILD_BENCHMARKS=ON and the lpm model (target bench_lpm).
set -euo pipefail
cd "$(dirname "$0")/.."
source jobs/env.sh
source jobs/bench_args.sh
bin="${1:-build}/bin/bench_lpm"
ref="${2:-}"
need_binary "$bin" bench_lpm "${1:-build}"
if [[ -n "$ref" && ! -x "$ref" ]]; then echo "$bench_script: the reference bench_lpm '$ref' is not an executable" >&2; exit 1; fi
header() {
  echo "| grid | maps | k | R | iterations | ranks | wall s | CPU s (max rank) | CPU s per map sweep | CPU ns per ray step |"
  echo "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"
}
echo "## Paper settings (64³, 3 iterations)"
header
for p in 5 9; do
  for np in 1 2; do
    if [[ -n "$ref" ]]; then
      echo "$(mpiexec -n "$np" "$bin" 64 "$p" 3 1 1 3) new"
      echo "$(mpiexec -n "$np" "$ref" 64 "$p" 3 1 1 3) ref"
    else
      mpiexec -n "$np" "$bin" 64 "$p" 3 1 1 3
    fi
  done
done
echo
echo "## Cost against n (p = 5) and p (n = 64), 2 ranks, 1 iteration"
header
for n in 32 48 64 96; do mpiexec -n 2 "$bin" "$n" 5 1 1 1 3; done
for p in 3 7 9 15; do mpiexec -n 2 "$bin" 64 "$p" 1 1 1 3; done
echo
echo "## Coarse bins and refinement (64³, p = 9, 2 ranks, 1 iteration)"
header
mpiexec -n 2 "$bin" 64 9 1 3 1 3
mpiexec -n 2 "$bin" 64 9 1 1 2 3
