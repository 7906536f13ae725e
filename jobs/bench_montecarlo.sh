#!/usr/bin/env bash
# Monte Carlo throughput (issue 3 item 6): the default cloud, forward tracing only (no image,
# no HDF5, the fast `sweep` light pass), on 1 and 2 ranks. Each run logs its rates; this prints
# the median of REPS runs per rank count and the 2-rank speed-up of the tracing phase. Target:
# 10⁷ collisions/s per core and a 2-rank speed-up ≥ 1.8.
#   bash jobs/bench_montecarlo.sh [build-dir [photons [reps [reference-nimbus]]]]
#   (defaults: build, 4000000, 3)
# Rows "new" (the default kernel: lanes where the CPU has AVX-512), "flux" (the same binary
# with the diffuse flux tallied, model.montecarlo.flux = true) and "scalar" (the same binary
# with model.montecarlo.kernel = "scalar") run alternately, so that a shared machine's load hits
# them alike; with a fourth argument (a nimbus binary of another version) it runs in turn too
# (row "ref"). Then the kernels' floor: bench_montecarlo (jobs/bench/bench_montecarlo.cpp) runs
# both path kernels on a small periodic grid that stays in cache (needs -DNIMBUS_BUILD_BENCHMARKS=ON).
set -euo pipefail
cd "$(dirname "$0")/.."
source jobs/env.sh
source jobs/bench_args.sh
bin="${1:-build}/bin/nimbus"
photons="${2:-4000000}"
reps="${3:-3}"
ref="${4:-}"
need_binary "$bin" nimbus "${1:-build}"
need_count photons "$photons"
need_count reps "$reps"
if [[ -n "$ref" && ! -x "$ref" ]]; then echo "$bench_script: the reference nimbus '$ref' is not an executable" >&2; exit 1; fi
log=$(mktemp)
trap 'rm -f "$log"' EXIT

# One run: prints "trace_seconds paths/s/core collisions/s/core segments/collision"; a failed
# run stops the script with the end of nimbus's log.
run() {  # run BINARY RANKS [more nimbus arguments]
  local binary=$1 np=$2
  shift 2
  if ! mpiexec -n "$np" "$binary" run --set model.montecarlo.photons="$photons" --set output.image=false \
         --set output.hdf5=false --set light.method=sweep "$@" > "$log" 2>&1; then
    { echo "$bench_script: $binary on $np rank(s) failed:"; tail -5 "$log"; } >&2
    exit 1
  fi
  awk '
      /collisions in/ { for (i = 1; i <= NF; ++i) if ($i == "tracing") t = $(i + 1) }
      /paths\/s\/core/ { for (i = 1; i <= NF; ++i) { if ($i == "paths/s/core,") p = $(i - 1);
                          if ($i == "collisions/s/core") c = $(i - 1); if ($i == "tallied") s = $(i - 1) } }
      END { print t, p, c, s }' "$log"
}

echo "| version | ranks | photons | tracing s | paths/s per core | collisions/s per core | tallied segments per collision |"
echo "| --- | --- | --- | --- | --- | --- | --- |"
declare -A T P C S
versions=(new flux scalar)  # the same binary with model.montecarlo.flux = true, kernel = "scalar"
[[ -n "$ref" ]] && versions+=(ref)
for np in 1 2; do
  for ((r = 0; r < reps; ++r)); do
    for v in "${versions[@]}"; do
      b="$bin"; [[ "$v" == ref ]] && b="$ref"
      extra=(); [[ "$v" == scalar ]] && extra=(--set 'model.montecarlo.kernel="scalar"')
      [[ "$v" == flux ]] && extra=(--set model.montecarlo.flux=true)
      out=$(run "$b" "$np" "${extra[@]}")  # set -e: a failed run ends the script (run printed why)
      read -r t p c s <<<"$out"
      T[$v$np]+="$t "; P[$v$np]+="$p "; C[$v$np]+="$c "; S[$v$np]+="$s "
    done
  done
  for v in "${versions[@]}"; do
    med() { tr ' ' '\n' <<<"$1" | grep -v '^$' | median; }
    echo "| $v | $np | $photons | $(med "${T[$v$np]}") | $(med "${P[$v$np]}") | $(med "${C[$v$np]}") | $(med "${S[$v$np]}") |"
  done
done
for v in "${versions[@]}"; do
  t1=$(tr ' ' '\n' <<<"${T[${v}1]}" | grep -v '^$' | median)
  t2=$(tr ' ' '\n' <<<"${T[${v}2]}" | grep -v '^$' | median)
  speedup=$(ratio "$t1" "$t2")  # exits on times it cannot read
  echo "2-rank speed-up of the tracing phase ($v, medians of $reps): $speedup"
done
floor="${1:-build}/bin/bench_montecarlo"
if [[ -x "$floor" ]]; then
  echo
  echo "Kernel floor (cache-resident homogeneous grid):"
  "$floor"
fi
